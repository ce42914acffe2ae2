"""Flight scenarios: what the simulator flies (airspeed, density, excitation, c2 sweep).

A scenario is plain data (frozen dataclasses) with vectorised profile functions of time, so the
simulator node, the batch path and the tests evaluate the very same profiles. Airspeeds may be
given as ratios of a reference critical airspeed (the study's U/Ucr); :func:`resolve_airspeeds`
turns them into m/s once that airspeed is known.

Profiles
--------
- airspeed ``constant``: U(t) = U0.
- airspeed ``ramp``: U rises linearly from ``start`` to ``end`` over the flight (the study's
  ch. 6-7: 0.8 -> 1.2 Ucr in 30 s).
- airspeed ``steps``: a stepped sweep; each airspeed is held for ``len(sweep_damping)`` dwells of
  ``dwell`` seconds, one per c2 value (the study's sec. 7.2.1 training experiment).
- density: rho(t) = rho0 (1 + mu sin(2 pi f t)) (Zhang (2006) eq. 7.2, with f = 1 Hz there).
- excitation: zero-mean white Gaussian aileron force with standard deviation ``force_std``
  (1 kN in the study), drawn per sample from ``numpy.random.default_rng(seed)``; optionally
  scaled by ``force_levels`` taken in turn for ``level_dwell`` seconds each (a flight test at
  several excitation levels, which shows amplitude-dependent behaviour).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from aero_dva.flight.flight_limits import (
    DENSITY_RANGE,
    MAX_BLOCK_SIZE,
    MAX_FLIGHT_SAMPLES,
    MAX_FORCE_STD,
    SAMPLE_RATE_RANGE,
)
from aero_dva.flight.hidden_plant import PlantOptions
from aero_dva.input_ranges import MAX_AIRSPEED

AIRSPEED_KINDS = ("constant", "ramp", "steps")


class ScenarioError(ValueError):
    """A scenario is malformed or physically meaningless; the message names the field."""


@dataclass(frozen=True)
class AirspeedProfile:
    """Airspeed versus time. Values are [m/s] unless ``relative`` (then ratios of U_ref).

    Attributes
    ----------
    kind : {"constant", "ramp", "steps"}
    values : tuple of float
        constant: (U0,); ramp: (start, end); steps: (U_1, ..., U_n).
    relative : bool
        True when ``values`` are ratios U/U_ref still to be resolved.
    """

    kind: str
    values: tuple[float, ...]
    relative: bool = False


@dataclass(frozen=True)
class Scenario:
    """A complete flight: timing, airspeed, density, excitation and (for sweeps) c2 values.

    Attributes
    ----------
    name : str
    duration : float
        Flight length [s]; for ``steps`` the sweep length (:func:`sweep_duration`).
    sample_rate : float
        Simulation and sensor sampling rate [Hz].
    block_size : int
        Samples per published block.
    airspeed : AirspeedProfile
    density : float
        rho0 [kg/m^3].
    density_variation : float
        mu of eq. 7.2, in [0, 1).
    density_frequency : float
        f [Hz] of the density variation (omega = 2 pi f).
    force_std : float
        Standard deviation of the aileron force [N].
    seed : int
        Seed of the excitation (and of any other randomness of the run).
    dwell : float
        Seconds each (U, c2) pair of a sweep is held [s].
    sweep_damping : tuple of float
        c2 values [N s/m] applied in turn at each sweep airspeed (empty unless ``steps``).
    force_levels : tuple of float
        Multipliers of ``force_std`` applied in turn, each for ``level_dwell`` [s] (empty:
        one level).
    level_dwell : float
        [s] how long each of ``force_levels`` is held.
    plant : PlantOptions or None
        Hidden plant effects (:mod:`aero_dva.flight.hidden_plant`); None flies the nominal model.
    """

    name: str
    duration: float
    sample_rate: float = 1000.0
    block_size: int = 20
    airspeed: AirspeedProfile = field(default_factory=lambda: AirspeedProfile("constant", (80.0,)))
    density: float = 1.2
    density_variation: float = 0.0
    density_frequency: float = 1.0
    force_std: float = 1000.0
    seed: int = 0
    dwell: float = 2.0
    sweep_damping: tuple[float, ...] = ()
    force_levels: tuple[float, ...] = ()
    level_dwell: float = 1.0
    plant: PlantOptions | None = None

    def __post_init__(self) -> None:
        validate(self)

    @property
    def n_samples(self) -> int:
        """Number of samples of the flight."""
        return int(round(self.duration * self.sample_rate))


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ScenarioError(f"{name} must be a positive finite number, got {value!r}")


def validate(s: Scenario) -> None:
    """Raise :class:`ScenarioError` naming the first bad field of ``s``."""
    _positive("duration", s.duration)
    _positive("sample_rate", s.sample_rate)
    low, high = SAMPLE_RATE_RANGE
    if not low <= s.sample_rate <= high:
        raise ScenarioError(f"sample_rate must be in [{low:g}, {high:g}] Hz, got "
                            f"{s.sample_rate:g}")
    if isinstance(s.block_size, bool) or not isinstance(s.block_size, int) \
            or not 1 <= s.block_size <= MAX_BLOCK_SIZE:
        raise ScenarioError(f"block_size must be an integer in [1, {MAX_BLOCK_SIZE}], got "
                            f"{s.block_size!r}")
    samples = s.duration * s.sample_rate
    if samples > MAX_FLIGHT_SAMPLES:
        raise ScenarioError(f"duration x sample_rate = {s.duration:g} s x {s.sample_rate:g} Hz "
                            f"= {samples:,.0f} samples, more than the {MAX_FLIGHT_SAMPLES:,} a "
                            "flight may have")
    if round(samples) < s.block_size:
        raise ScenarioError(f"duration {s.duration:g} s is shorter than one block "
                            f"({s.block_size} samples at {s.sample_rate:g} Hz)")
    if s.airspeed.kind not in AIRSPEED_KINDS:
        raise ScenarioError(
            f"airspeed.kind must be one of {AIRSPEED_KINDS}, got {s.airspeed.kind!r}"
        )
    needed = {"constant": 1, "ramp": 2}.get(s.airspeed.kind)
    values = s.airspeed.values
    if needed is not None and len(values) != needed:
        raise ScenarioError(
            f"airspeed {s.airspeed.kind} takes {needed} value(s), got {len(values)}"
        )
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        raise ScenarioError(f"airspeed values must be finite and >= 0, got {values}")
    unit = "U/U_ref" if s.airspeed.relative else "m/s"
    limit = 5.0 if s.airspeed.relative else MAX_AIRSPEED
    if max(values) > limit:
        raise ScenarioError(f"airspeed {max(values)} {unit} is absurd for this model (> {limit})")
    _positive("density", s.density)
    low, high = DENSITY_RANGE
    if not low <= s.density <= high:
        raise ScenarioError(f"density must be in [{low:g}, {high:g}] kg/m^3 (air), got "
                            f"{s.density:g}")
    if not 0.0 <= s.density_variation < 1.0:
        raise ScenarioError(f"density_variation (mu) must be in [0, 1), got {s.density_variation}")
    _positive("density_frequency", s.density_frequency)
    if not 1e-6 <= s.density_frequency <= s.sample_rate / 2:
        raise ScenarioError(f"density_frequency must be in [1e-06, {s.sample_rate / 2:g}] Hz "
                            f"(half the sample rate), got {s.density_frequency:g}")
    if not (isinstance(s.force_std, (int, float)) and 1e-6 <= s.force_std <= MAX_FORCE_STD):
        raise ScenarioError(f"force_std must be in [1e-06, {MAX_FORCE_STD:g}] N (a flight "
                            f"needs its excitation), got {s.force_std!r}")
    if isinstance(s.seed, bool) or not isinstance(s.seed, int) or not 0 <= s.seed < 2**63:
        raise ScenarioError(f"seed must be an integer in [0, 2**63), got {s.seed!r}")
    if s.airspeed.kind == "steps":
        _positive("dwell", s.dwell)
        if s.dwell * s.sample_rate < 1:
            raise ScenarioError(f"dwell {s.dwell:g} s is shorter than one sample")
        if not s.sweep_damping:
            raise ScenarioError("a 'steps' sweep needs sweep_damping (the c2 values to apply)")
        if not all(math.isfinite(c) and c >= 0 for c in s.sweep_damping):
            raise ScenarioError(f"sweep_damping must be finite and >= 0 N s/m: {s.sweep_damping}")
        expected = sweep_duration(len(values), len(s.sweep_damping), s.dwell)
        if not math.isclose(s.duration, expected, rel_tol=1e-9):
            raise ScenarioError(
                f"duration {s.duration} s does not match the sweep: {len(values)} airspeeds x "
                f"{len(s.sweep_damping)} c2 values x {s.dwell} s = {expected} s"
            )
    elif s.sweep_damping:
        raise ScenarioError("sweep_damping is only meaningful with airspeed kind 'steps'")
    if s.force_levels:
        _positive("level_dwell", s.level_dwell)
        if s.level_dwell * s.sample_rate < 1:
            raise ScenarioError(f"level_dwell {s.level_dwell:g} s is shorter than one sample")
        if not all(isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= 100
                   for v in s.force_levels):
            raise ScenarioError(f"force levels must be in (0, 100], got {s.force_levels}")
    if s.plant is not None:
        if not isinstance(s.plant, PlantOptions):
            raise ScenarioError(
                f"plant must be PlantOptions or None, got {type(s.plant).__name__}")
        try:
            s.plant.check_duration(s.duration)
        except ValueError as exc:
            raise ScenarioError(str(exc)) from None


def sweep_duration(n_airspeeds: int, n_damping: int, dwell: float) -> float:
    """Length [s] of a stepped sweep holding every (U, c2) pair for ``dwell`` seconds."""
    return n_airspeeds * n_damping * dwell


def resolve_airspeeds(s: Scenario, reference_airspeed: float) -> Scenario:
    """Return ``s`` with relative airspeeds multiplied by ``reference_airspeed`` [m/s]."""
    if not s.airspeed.relative:
        return s
    _positive("reference_airspeed", reference_airspeed)
    values = tuple(v * reference_airspeed for v in s.airspeed.values)
    return replace(s, airspeed=AirspeedProfile(s.airspeed.kind, values, relative=False))


def _require_resolved(s: Scenario) -> None:
    if s.airspeed.relative:
        raise ScenarioError("airspeeds are relative (U/U_ref): call resolve_airspeeds first")


def sample_times(s: Scenario, start: int = 0, count: int | None = None) -> np.ndarray:
    """Times [s] of samples ``start .. start+count-1`` (all samples by default), shape (count,)."""
    count = s.n_samples - start if count is None else count
    return (start + np.arange(count)) / s.sample_rate


def airspeed_at(s: Scenario, t: np.ndarray) -> np.ndarray:
    """Airspeed [m/s] at times ``t`` [s] (any shape); held at the end value after the flight."""
    _require_resolved(s)
    t = np.asarray(t, dtype=float)
    values = np.asarray(s.airspeed.values, dtype=float)
    if s.airspeed.kind == "constant":
        return np.full_like(t, values[0])
    if s.airspeed.kind == "ramp":
        fraction = np.clip(t / s.duration, 0.0, 1.0)
        return values[0] + (values[1] - values[0]) * fraction
    step = np.clip((t // (s.dwell * len(s.sweep_damping))).astype(int), 0, len(values) - 1)
    return values[step]


def sweep_damping_at(s: Scenario, t: np.ndarray) -> np.ndarray:
    """c2 [N s/m] the sweep applies at times ``t`` (``steps`` scenarios only)."""
    if s.airspeed.kind != "steps":
        raise ScenarioError("sweep_damping_at needs a 'steps' scenario")
    t = np.asarray(t, dtype=float)
    dwell_index = np.clip((t // s.dwell).astype(int), 0, None)
    return np.asarray(s.sweep_damping, dtype=float)[dwell_index % len(s.sweep_damping)]


def density_at(s: Scenario, t: np.ndarray) -> np.ndarray:
    """Air density [kg/m^3] at times ``t`` [s]: rho0 (1 + mu sin(2 pi f t)), eq. 7.2."""
    t = np.asarray(t, dtype=float)
    return s.density * (1.0 + s.density_variation * np.sin(2.0 * np.pi * s.density_frequency * t))


def force_scale_at(s: Scenario, t: np.ndarray) -> np.ndarray:
    """Multiplier of ``force_std`` at times ``t`` [s] (1 without ``force_levels``)."""
    t = np.asarray(t, dtype=float)
    if not s.force_levels:
        return np.ones_like(t)
    index = np.clip((t // s.level_dwell).astype(int), 0, None) % len(s.force_levels)
    return np.asarray(s.force_levels, dtype=float)[index]


def excitation(s: Scenario, rng: np.random.Generator | None = None) -> np.ndarray:
    """The whole flight's aileron force [N], shape (n_samples,), from ``default_rng(s.seed)``."""
    rng = np.random.default_rng(s.seed) if rng is None else rng
    force = s.force_std * rng.standard_normal(s.n_samples)
    if s.force_levels:
        force *= force_scale_at(s, sample_times(s))
    return force
