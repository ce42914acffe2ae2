"""Which (U, rho, c2) dwells the training sweep records (Zhang (2006) sec. 7.2.1, made learnable).

The study trains its network on 0.8 .. 1.14 U_cr in 0.002 U_cr steps with 20 values of c2 per
airspeed, one 2 s window each, at one air density. Flown as one continuous sweep, an unstable
(U, c2) pair grows and spoils every later dwell, so the earlier sweep dropped 1.044 .. 1.14
U_cr, exactly where c2 matters; and one density cannot teach a network to tell density from
airspeed. The plan here:

- **airspeeds** ``ratios`` x U_cr (default the study's 0.8 .. 1.14 in 0.002 steps; U_cr of
  the bare wing at the base density), at **densities** ``factors`` x rho0 (default 0.9, 1.0,
  1.1);
- **c2 values** at each (U, rho): ``n_damping`` evenly spaced over the interval around the
  exact optimum c2*(U, rho) (:func:`aero_dva.control.optimal_damping.optimal_damping`) on which
  the wing decays at ``min_decay`` 1/s or faster, cut to c2* +- ``max_offset``; a condition
  with no such c2 is left out (and listed); where the interval is a single grid point, that
  one c2 is recorded;
- **each dwell starts from its stationary state** (drawn by the recording, see
  :mod:`dva_offline.training.recording`), so no dwell inherits a transient from the one before
  and the window is a sample of the stationary response the labels describe.

Pure numerics: the plan is data; :mod:`dva_offline.training.plan_io` reads and writes it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.flight.damper import DAMPER_RANGE, damping_problem
from aero_dva.flight.flight_limits import (
    MAX_FLIGHT_SAMPLES,
    MAX_FORCE_STD,
    MAX_WINDOW_SAMPLES,
    SAMPLE_RATE_RANGE,
)
from aero_dva.input_ranges import Range, check_number

__all__ = [
    "DEFAULT_FACTORS",
    "DEFAULT_RATIOS",
    "PlanSettings",
    "TrainingPlan",
    "make_training_plan",
    "ratio_grid",
    "stable_interval",
]

#: Airspeeds of the study's training experiment [U/U_cr]: 0.8 .. 1.14 in 0.002 steps.
DEFAULT_RATIOS = (0.8, 1.14, 0.002)
#: Densities [rho / rho0]: a constant 10 % offset either way around the base density.
DEFAULT_FACTORS = (0.9, 1.0, 1.1)
_C2_GRID = np.linspace(*DAMPER_RANGE, 126)  # [N s/m] the damper's range, 20 N s/m apart
#: The stated ranges of a plan's settings (besides the ratios, factors and window).
_RANGES = {"min_decay": Range(1e-6, 1e3, "1/s"),
           "max_offset": Range(1.0, DAMPER_RANGE[1], "N s/m"),
           "force_std": Range(1e-6, MAX_FORCE_STD, "N"),
           "seed": Range(0, 2**63 - 1)}


@dataclass(frozen=True)
class PlanSettings:
    """What a plan is made from (every field is stored with the plan).

    Attributes
    ----------
    ratios : tuple of float
        Airspeeds [U / U_cr].
    factors : tuple of float
        Densities [rho / rho0].
    n_damping : int
        c2 values per (U, rho) (the study: 20).
    min_decay : float
        [1/s] every recorded pair decays at least this fast (> 0): a stationary state exists
        and its correlation time is below 1 / min_decay.
    max_offset : float
        [N s/m] c2 stays within c2* +- this.
    damping_range : (float, float)
        [N s/m] the damper's range (inside :data:`~aero_dva.flight.damper.DAMPER_RANGE`).
    window : float
        [s] dwell = analysis window (no settling: each dwell starts stationary).
    sample_rate, force_std : float
        [Hz], [N] per sample: the simulator's.
    seed : int
        Excitation and initial-state seed of the recording.
    """

    ratios: tuple[float, ...]
    factors: tuple[float, ...] = DEFAULT_FACTORS
    n_damping: int = 20
    min_decay: float = 0.2
    max_offset: float = 300.0
    damping_range: tuple[float, float] = DAMPER_RANGE
    window: float = 2.0
    sample_rate: float = 1000.0
    force_std: float = 1000.0
    seed: int = 7

    def __post_init__(self):
        ratios = tuple(float(r) for r in self.ratios)
        factors = tuple(float(f) for f in self.factors)
        if not ratios or any(not (math.isfinite(r) and 0.05 <= r <= 3) for r in ratios):
            raise ValueError(f"ratios must be airspeeds U/U_cr in [0.05, 3], got "
                             f"{self.ratios}")
        if not factors or any(not (math.isfinite(f) and 0.3 <= f <= 2) for f in factors) \
                or len(set(factors)) != len(factors):
            raise ValueError(f"factors must be distinct density ratios in [0.3, 2], got "
                             f"{self.factors}")
        if isinstance(self.n_damping, bool) or not isinstance(self.n_damping, int) \
                or self.n_damping < 1:
            raise ValueError(f"n_damping must be an integer >= 1, got {self.n_damping!r}")
        for name in ("min_decay", "max_offset", "window", "sample_rate"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        for name, rng in _RANGES.items():
            check_number(getattr(self, name), name, rng)
        low, high = SAMPLE_RATE_RANGE
        if not low <= self.sample_rate <= high:
            raise ValueError(f"sample_rate must be in [{low:g}, {high:g}] Hz, got "
                             f"{self.sample_rate:g}")
        low, high = (float(v) for v in self.damping_range)
        if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
            raise ValueError(f"damping_range must be 0 <= low < high N s/m, got "
                             f"{self.damping_range}")
        problem = damping_problem((low, high), "damping_range")
        if problem is not None:
            raise ValueError(problem)
        n = self.window * self.sample_rate
        if n > MAX_WINDOW_SAMPLES:
            raise ValueError(f"window x sample_rate = {self.window:g} s x "
                             f"{self.sample_rate:g} Hz = {n:,.0f} samples, more than the "
                             f"{MAX_WINDOW_SAMPLES:,} a window may have")
        if abs(n - round(n)) > 1e-6 * n or round(n) < 2:
            raise ValueError(f"window * sample_rate must be a whole number >= 2 of samples, "
                             f"got {self.window} s * {self.sample_rate} Hz")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        object.__setattr__(self, "ratios", ratios)
        object.__setattr__(self, "factors", factors)
        object.__setattr__(self, "damping_range", (low, high))

    @property
    def window_samples(self) -> int:
        return int(round(self.window * self.sample_rate))


@dataclass(frozen=True)
class TrainingPlan:
    """The dwells to record, with the conditions' optimum and stable interval.

    Attributes
    ----------
    settings : PlanSettings
    critical_airspeed : float
        [m/s] U_cr of the bare wing at ``base_density`` (the ratios' reference).
    base_density : float
        [kg/m^3] rho0.
    optimal_damping : ndarray, shape (n_factors, n_ratios)
        [N s/m] c2*(U, rho); NaN where no c2 of the damper's range is stable.
    stable_low, stable_high : ndarray, shape (n_factors, n_ratios)
        [N s/m] the interval around c2* on which the wing decays at ``min_decay`` or faster
        (on a 20 N s/m grid, inside the damper's range); NaN where there is none.
    airspeed, density, damping : ndarray, shape (n_dwells,)
        [m/s], [kg/m^3], [N s/m] of each dwell, in recording order: density, then airspeed,
        then c2 ascending.
    condition : ndarray of int, shape (n_dwells,)
        Index ``i_factor * n_ratios + i_ratio`` of each dwell's (U, rho).
    """

    settings: PlanSettings
    critical_airspeed: float
    base_density: float
    optimal_damping: np.ndarray
    stable_low: np.ndarray
    stable_high: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    condition: np.ndarray

    @property
    def n_dwells(self) -> int:
        return int(self.airspeed.size)

    @property
    def duration(self) -> float:
        """[s] recorded flight time."""
        return self.n_dwells * self.settings.window

    @property
    def ratios(self) -> np.ndarray:
        return np.asarray(self.settings.ratios)

    @property
    def densities(self) -> np.ndarray:
        return self.base_density * np.asarray(self.settings.factors)

    @property
    def skipped(self) -> list[tuple[float, float]]:
        """(U/U_cr, rho/rho0) of the conditions left out (no c2 decays fast enough)."""
        missing = ~np.isfinite(self.stable_low)
        return [(self.settings.ratios[j], self.settings.factors[i])
                for i, j in zip(*np.nonzero(missing))]


def stable_interval(growth: np.ndarray, grid: np.ndarray, optimum: float,
                    min_decay: float) -> tuple[float, float]:
    """The run of ``grid`` around ``optimum`` on which ``growth <= -min_decay``.

    Parameters
    ----------
    growth : (n_c,) [1/s] largest real part at each c2 of ``grid`` (inf/NaN: unstable).
    grid : (n_c,) [N s/m] increasing.
    optimum : float
        [N s/m] the c2 the run must contain (its nearest grid point must decay).

    Returns
    -------
    (low, high) [N s/m], or (NaN, NaN) when the grid point nearest ``optimum`` does not decay
    fast enough.
    """
    ok = np.isfinite(growth) & (growth <= -min_decay)
    if not math.isfinite(optimum):
        return math.nan, math.nan
    k = int(np.argmin(np.abs(grid - optimum)))
    if not ok[k]:
        return math.nan, math.nan
    lo = k
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    hi = k
    while hi < grid.size - 1 and ok[hi + 1]:
        hi += 1
    return float(grid[lo]), float(grid[hi])


def make_training_plan(model, critical_airspeed: float, base_density: float,
                       settings: PlanSettings, progress=None) -> TrainingPlan:
    """Plan the dwells (see the module docstring).

    Parameters
    ----------
    model : AeroelasticModel
        The wing with its tunable Maxwell DVA.
    critical_airspeed : float
        [m/s] U_cr of the bare wing at ``base_density``.
    base_density : float
        [kg/m^3] rho0.
    settings : PlanSettings
    progress : callable, optional
        Called with the number of densities done.
    """
    if not (math.isfinite(critical_airspeed) and critical_airspeed > 0):
        raise ValueError(f"critical_airspeed must be > 0 m/s, got {critical_airspeed}")
    if not (math.isfinite(base_density) and base_density > 0):
        raise ValueError(f"base_density must be > 0 kg/m^3, got {base_density}")
    s = settings
    speeds = np.asarray(s.ratios) * critical_airspeed
    low, high = s.damping_range
    grid = np.unique(np.clip(np.append(_C2_GRID, [low, high]), low, high))
    n_f, n_u = len(s.factors), speeds.size
    best = np.full((n_f, n_u), np.nan)
    lows = np.full((n_f, n_u), np.nan)
    highs = np.full((n_f, n_u), np.nan)
    for i, factor in enumerate(s.factors):
        rho = factor * base_density
        opt = optimal_damping(model, speeds, grid, rho, force_std=s.force_std,
                              sample_rate=s.sample_rate)
        growth = stationary_rms(model, speeds[:, None], rho, grid[None, :],
                                force_std=s.force_std, sample_rate=s.sample_rate).growth_rate
        for j in range(n_u):
            c_opt = float(opt.optimal_damping[j])
            lo, hi = stable_interval(growth[j], grid, c_opt, s.min_decay)
            if math.isfinite(lo):
                best[i, j], lows[i, j], highs[i, j] = c_opt, lo, hi
        if progress is not None:
            progress(i + 1)
    rows = []
    for i, factor in enumerate(s.factors):
        for j in range(n_u):
            if not math.isfinite(lows[i, j]):
                continue
            a = max(lows[i, j], best[i, j] - s.max_offset)
            b = min(highs[i, j], best[i, j] + s.max_offset)
            # distinct values only: equal neighbours would merge into one dwell in the log
            values = np.unique(np.linspace(a, b, s.n_damping)) if s.n_damping > 1 \
                else [best[i, j]]
            rows += [(speeds[j], factor * base_density, float(c), i * n_u + j)
                     for c in values]
    if not rows:
        raise ValueError("no (U, rho) of the plan has a c2 that decays at "
                         f"{s.min_decay} 1/s or faster: nothing to record")
    if len(rows) * s.window_samples > MAX_FLIGHT_SAMPLES:
        raise ValueError(f"the plan's {len(rows):,} dwells x {s.window_samples:,} samples "
                         f"are more than the {MAX_FLIGHT_SAMPLES:,} samples a recording may "
                         "have (fewer airspeeds, densities or c2 values, or a shorter window)")
    table = np.array(rows)
    return TrainingPlan(settings=s, critical_airspeed=float(critical_airspeed),
                        base_density=float(base_density), optimal_damping=best,
                        stable_low=lows, stable_high=highs, airspeed=table[:, 0],
                        density=table[:, 1], damping=table[:, 2],
                        condition=table[:, 3].astype(int))


def ratio_grid(start: float, stop: float, step: float) -> tuple[float, ...]:
    """``start, start + step, .. <= stop`` rounded to 1e-9 (``"0.8:1.14:0.002"`` style)."""
    if not (math.isfinite(start) and math.isfinite(stop) and math.isfinite(step)) \
            or step <= 0 or stop < start:
        raise ValueError(f"need start <= stop and step > 0, got {start}, {stop}, {step}")
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    return tuple(round(start + k * step, 9) for k in range(n))
