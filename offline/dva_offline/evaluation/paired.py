"""The chapter-7 evaluation as paired flights: controllers x density cases x seeds, in one process.

Every flight is the study's ramp (0.8 -> 1.2 U_cr in 30 s, 1 kN white aileron force) flown by
:func:`.closed_loop.fly`; U_cr is the bare wing's at the base density, and the ramp
is given in m/s so that every case flies the same airspeeds. A seed fixes the force
realisation, so the controllers of one (case, seed) meet the same gusts: their differences are
paired, and a paired t-interval over the seeds says whether a difference is more than chance.

Density cases (eq. 7.2, rho = rho0 (1 + mu sin 2 pi f t)); which can adaptation exploit:

============  =======================================================================
``rho0``      constant base density (the study's fig. 7.5, 7.13)
``x0.9``      constant rho0 x 0.9: an offset an airspeed schedule cannot see
``x1.1``      constant rho0 x 1.1
``slow``      mu = 0.1 with a 20 s period: the density changes slower than the wing
``1Hz``       mu = 0.1 at 1 Hz: the study's (fig. 7.6-7.7, 7.15-7.16)
``2f``        mu = 0.1 near twice the flutter frequency: parametric pumping
============  =======================================================================

Per flight: the divergence airspeed (:func:`aero_dva.flight.divergence.divergence_airspeed`,
the project's one detector) over U_cr, and the leading-edge RMS between ``rms_range`` (default
0.8 .. 1.05 U_cr, after the first 2 s in which the spectrum controller has no window yet;
:mod:`aero_dva.flight.range_rms`), the study's objective where the optimal c2 moves with the
airspeed, both compared with the best fixed c2 flown on the same seed.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from aero_dva.flight.divergence import divergence_airspeed
from aero_dva.flight.range_rms import SKIP, range_mean, range_rms
from aero_dva.flight.scenario import AirspeedProfile, Scenario

__all__ = ["CASE_NAMES", "REFERENCE_CONTROLLER", "DensityCase", "FlightRecord",
           "PairedStat", "case_scenario", "default_cases", "flight_record", "paired",
           "summarise"]

CASE_NAMES = ("rho0", "x0.9", "x1.1", "slow", "1Hz", "2f")
REFERENCE_CONTROLLER = "fixed"  # every ratio is to the best fixed c2 on the same seed


@dataclass(frozen=True)
class DensityCase:
    """rho(t) = factor rho0 (1 + mu sin(2 pi f t))."""

    name: str
    factor: float
    variation: float
    frequency: float
    description: str


def default_cases(flutter_frequency: float) -> dict[str, DensityCase]:
    """The six cases; ``flutter_frequency`` [Hz] places ``2f`` (at twice it, 0.1 Hz steps)."""
    twice = round(2.0 * flutter_frequency, 1)
    return {c.name: c for c in (
        DensityCase("rho0", 1.0, 0.0, 1.0, "constant rho0"),
        DensityCase("x0.9", 0.9, 0.0, 1.0, "constant 0.9 rho0"),
        DensityCase("x1.1", 1.1, 0.0, 1.0, "constant 1.1 rho0"),
        DensityCase("slow", 1.0, 0.1, 0.05, "mu 0.1, period 20 s"),
        DensityCase("1Hz", 1.0, 0.1, 1.0, "mu 0.1 at 1 Hz (the study's)"),
        DensityCase("2f", 1.0, 0.1, twice, f"mu 0.1 at {twice:g} Hz (2 x flutter)"),
    )}


def case_scenario(base: Scenario, case: DensityCase, critical_airspeed: float,
                  seed: int) -> Scenario:
    """``base`` (a ramp, airspeeds relative to U_cr at its base density) flown in ``case``
    with excitation ``seed``: airspeeds resolved in m/s with ``critical_airspeed`` first, so
    a density offset does not move the ramp."""
    if base.airspeed.kind != "ramp":
        raise ValueError(f"the evaluation flies a ramp, got airspeed kind {base.airspeed.kind!r}")
    values = base.airspeed.values
    if base.airspeed.relative:
        values = tuple(v * critical_airspeed for v in values)
    return replace(base, name=f"{base.name}_{case.name}_seed{seed}",
                   airspeed=AirspeedProfile("ramp", tuple(values), relative=False),
                   density=base.density * case.factor, density_variation=case.variation,
                   density_frequency=case.frequency, seed=int(seed))


@dataclass(frozen=True)
class FlightRecord:
    """The numbers of one evaluation flight."""

    controller: str
    case: str
    seed: int
    diverged: bool
    divergence_ratio: float  # U_div / U_cr (NaN: reached the end of the ramp)
    rms: float  # [m] leading-edge RMS over the RMS range
    mean_damping: float  # [N s/m] mean applied c2 over the RMS range
    median_peak_activation: float  # RBF only, else NaN

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in self.__dict__.items()}


def flight_record(controller: str, case: str, seed: int, outcome, critical_airspeed: float,
                  rms_range: tuple[float, float], skip: float = SKIP) -> FlightRecord:
    """Summarise a :class:`~dva_offline.evaluation.closed_loop.FlightOutcome`.

    ``rms_range`` [m/s]: airspeeds over which the RMS is taken (samples after ``skip``
    seconds). A flight that ends inside the range has no RMS (NaN).
    """
    rate = outcome.sample_rate
    u, le = outcome.airspeed, outcome.leading_edge
    div = divergence_airspeed(u, le, rate) if u.size >= 3 * rate else math.nan
    rms = range_rms(u, le, rate, rms_range, skip)
    c2 = range_mean(u, outcome.damping, rate, rms_range, skip)
    act = float(np.median(outcome.peak_activation)) if outcome.peak_activation.size \
        else math.nan
    return FlightRecord(controller=controller, case=case, seed=int(seed),
                        diverged=bool(outcome.diverged),
                        divergence_ratio=div / critical_airspeed, rms=rms,
                        mean_damping=c2, median_peak_activation=act)


@dataclass(frozen=True)
class PairedStat:
    """Mean of paired values and the 95 % t-interval of the mean (over seeds)."""

    n: int
    mean: float
    low: float
    high: float

    @property
    def excludes_zero(self) -> bool:
        return self.n >= 2 and (self.low > 0 or self.high < 0)

    def to_dict(self) -> dict:
        def clean(v):
            return v if math.isfinite(v) else None

        return {"n": self.n, "mean": clean(self.mean),
                "ci95": [clean(self.low), clean(self.high)]}


def paired(values: Sequence[float]) -> PairedStat:
    """:class:`PairedStat` of the finite ``values`` (one per seed)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return PairedStat(0, math.nan, math.nan, math.nan)
    mean = float(x.mean())
    if x.size < 2:
        return PairedStat(1, mean, math.nan, math.nan)
    half = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return PairedStat(int(x.size), mean, mean - half, mean + half)


def _median(values) -> float:
    x = np.asarray(values, dtype=float)
    return float(np.median(x[np.isfinite(x)])) if np.isfinite(x).any() else math.nan


def summarise(records: Sequence[FlightRecord], controllers: Sequence[str],
              cases: Sequence[str]) -> list[dict]:
    """Per (controller, case): mean divergence ratio, mean RMS ratio to the best fixed c2 on
    the same seed, and the paired differences with their 95 % intervals.

    ``divergence_difference`` = U_div/U_cr minus that of the best fixed c2 (same seed),
    ``rms_change`` = RMS / RMS of the best fixed c2 - 1 (negative: less vibration),
    ``divergence_to_oracle`` = U_div/U_cr minus the oracle's, ``divergence_to_schedule`` and
    ``rms_to_schedule`` the same against the airspeed schedule (the study's key comparison;
    when those are flown); each over the seeds on which both flights have the value.
    """
    table = {(r.controller, r.case, r.seed): r for r in records}
    rows = []
    for case in cases:
        for controller in controllers:
            own = [r for (c, k, _), r in table.items() if c == controller and k == case]
            if not own:
                continue
            ref = {r.seed: table.get((REFERENCE_CONTROLLER, case, r.seed)) for r in own}
            oracle = {r.seed: table.get(("oracle", case, r.seed)) for r in own}
            schedule = {r.seed: table.get(("schedule", case, r.seed)) for r in own}
            div = [r.divergence_ratio for r in own]
            ddiff = [r.divergence_ratio - ref[r.seed].divergence_ratio
                     for r in own if ref[r.seed] is not None]
            ratio = [r.rms / ref[r.seed].rms for r in own if ref[r.seed] is not None]
            finite_div = [d for d in div if math.isfinite(d)]
            rows.append({
                "controller": controller, "case": case, "flights": len(own),
                "diverged": sum(math.isfinite(d) for d in div),
                "mean_divergence_ratio": float(np.mean(finite_div)) if finite_div
                else math.nan,
                "mean_rms_ratio": float(np.nanmean(ratio)) if np.isfinite(ratio).any()
                else math.nan,
                "mean_rms": float(np.nanmean([r.rms for r in own])),
                "mean_c2": float(np.nanmean([r.mean_damping for r in own])),
                "median_peak_activation": _median(
                    [r.median_peak_activation for r in own]),
                "divergence_difference": paired(ddiff),
                "rms_change": paired(np.asarray(ratio) - 1.0),
                "divergence_to_oracle": paired(
                    [r.divergence_ratio - oracle[r.seed].divergence_ratio
                     for r in own if oracle[r.seed] is not None]),
                "divergence_to_schedule": paired(
                    [r.divergence_ratio - schedule[r.seed].divergence_ratio
                     for r in own if schedule[r.seed] is not None]),
                "rms_to_schedule": paired(
                    [r.rms / schedule[r.seed].rms - 1.0
                     for r in own if schedule[r.seed] is not None]),
            })
    return rows
