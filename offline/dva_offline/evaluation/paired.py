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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from aero_dva.flight.divergence import divergence_airspeed
from aero_dva.flight.peak_limit import peak_limit_airspeed
from aero_dva.flight.range_rms import SKIP, range_mean, range_rms
from aero_dva.flight.scenario import AirspeedProfile, Scenario

__all__ = ["CASE_NAMES", "HOLD", "REFERENCE_CONTROLLER", "ROW_STATS", "DensityCase",
           "FlightRecord",
           "PairedStat", "case_scenario", "default_cases", "flight_record", "hold_scenario",
           "law_pairs", "paired", "summarise"]

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
                  seed: int, ramp_to: float | None = None) -> Scenario:
    """``base`` (a ramp, airspeeds relative to U_cr at its base density) flown in ``case``
    with excitation ``seed``: airspeeds resolved in m/s with ``critical_airspeed`` first, so
    a density offset does not move the ramp. ``ramp_to`` [U/U_cr]: the ramp carried on at its
    own slope to that airspeed (the flight lasts longer by whole blocks; its first seconds are
    the base ramp's, with the same force)."""
    if base.airspeed.kind != "ramp":
        raise ValueError(f"the evaluation flies a ramp, got airspeed kind {base.airspeed.kind!r}")
    values = base.airspeed.values
    if base.airspeed.relative:
        values = tuple(v * critical_airspeed for v in values)
    duration = base.duration
    if ramp_to is not None and ramp_to * critical_airspeed > values[1] > values[0]:
        step = base.block_size / base.sample_rate
        longer = (ramp_to * critical_airspeed - values[0]) / (values[1] - values[0])
        duration = math.ceil(round(base.duration * longer / step, 9)) * step
        values = (values[0], values[0] + (values[1] - values[0]) * duration / base.duration)
    return replace(base, name=f"{base.name}_{case.name}_seed{seed}",
                   airspeed=AirspeedProfile("ramp", tuple(values), relative=False),
                   duration=duration,
                   density=base.density * case.factor, density_variation=case.variation,
                   density_frequency=case.frequency, seed=int(seed))


#: The flight at one airspeed that measures the RMS, switches and damper power there
#: (as the switching law's study measured them): U/U_cr, duration [s], transient left out [s].
HOLD = (1.1, 20.0, 2.0)


def hold_scenario(base: Scenario, case: DensityCase, critical_airspeed: float,
                  seed: int) -> Scenario:
    """``base`` held at :data:`HOLD`'s airspeed in ``case`` with excitation ``seed`` (its force
    the ramp's first seconds' of that seed)."""
    ratio, duration, _ = HOLD
    return replace(base, name=f"{base.name}_{case.name}_hold_seed{seed}",
                   airspeed=AirspeedProfile("constant", (ratio * critical_airspeed,),
                                            relative=False),
                   duration=duration, density=base.density * case.factor,
                   density_variation=case.variation, density_frequency=case.frequency,
                   seed=int(seed))


@dataclass(frozen=True)
class FlightRecord:
    """The numbers of one evaluation flight: its ramp and its hold at :data:`HOLD`."""

    controller: str
    case: str
    seed: int
    diverged: bool
    divergence_ratio: float  # U_div / U_cr (NaN: reached the end of the ramp)
    rms: float  # [m] leading-edge RMS over the RMS range
    mean_damping: float  # [N s/m] mean applied c2 over the RMS range
    median_peak_activation: float  # RBF only, else NaN
    practical_ratio: float = math.nan  # U/U_cr of the first |leading edge| over the peak limit
    rms_hold: float = math.nan  # [m] leading-edge RMS of the hold (NaN: it fluttered)
    switches_per_second: float = math.nan  # the damper's target changes per second (hold)
    damper_power: float = math.nan  # [W] mean power the damper dissipates (hold)

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in self.__dict__.items()}


def flight_record(controller: str, case: str, seed: int, outcome, critical_airspeed: float,
                  rms_range: tuple[float, float], skip: float = SKIP, *,
                  peak_limit: float = math.inf, hold=None) -> FlightRecord:
    """Summarise a :class:`~dva_offline.evaluation.closed_loop.FlightOutcome` (the ramp) and,
    when given, ``hold`` (the same controller held at :data:`HOLD`'s airspeed).

    ``rms_range`` [m/s]: airspeeds over which the RMS is taken (samples after ``skip``
    seconds). A flight that ends inside the range has no RMS (NaN). ``peak_limit`` [m]: the
    practical boundary is the airspeed of the first sample beyond it. The hold's RMS, switches
    and damper power leave out its first seconds; a hold that the simulator stopped, or whose
    last 2 s have ten times the RMS of the 2 s after the transient, fluttered: no RMS (NaN).
    """
    rate = outcome.sample_rate
    u, le = outcome.airspeed, outcome.leading_edge
    div = divergence_airspeed(u, le, rate) if u.size >= 3 * rate else math.nan
    rms = range_rms(u, le, rate, rms_range, skip)
    c2 = range_mean(u, outcome.damping, rate, rms_range, skip)
    act = float(np.median(outcome.peak_activation)) if outcome.peak_activation.size \
        else math.nan
    practical = peak_limit_airspeed(u, le, peak_limit) if math.isfinite(peak_limit) \
        else math.nan
    held = _hold_numbers(hold) if hold is not None else (math.nan,) * 3
    return FlightRecord(controller=controller, case=case, seed=int(seed),
                        diverged=bool(outcome.diverged),
                        divergence_ratio=div / critical_airspeed, rms=rms,
                        mean_damping=c2, median_peak_activation=act,
                        practical_ratio=practical / critical_airspeed, rms_hold=held[0],
                        switches_per_second=held[1], damper_power=held[2])


def _hold_numbers(hold) -> tuple[float, float, float]:
    """(leading-edge RMS [m], target changes per second, mean damper power [W]) of a hold
    after its transient (module docstring of :func:`flight_record`)."""
    rate = hold.sample_rate
    skip = int(HOLD[2] * rate)
    le = hold.leading_edge
    window = int(2.0 * rate)
    whole = hold.samples >= int(HOLD[1] * rate)
    after = le[skip:skip + window]
    last = le[-window:]
    grew = not whole or hold.diverged or _rms(last) > 10.0 * _rms(after)
    rms = math.nan if grew else _rms(le[skip:])
    target = (hold.damping if hold.target is None else hold.target)[skip:]
    switches = np.count_nonzero(target[1:] != target[:-1]) * rate / max(1, target.size - 1)
    power = np.empty(0) if hold.damper_power is None else hold.damper_power[skip:]
    power = power[np.isfinite(power)]
    return rms, float(switches), math.fsum(power) / power.size if power.size else math.nan


def _rms(x) -> float:
    return math.sqrt(math.fsum(np.asarray(x, dtype=float) ** 2) / len(x)) if len(x) else math.nan


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


def _mean(values) -> float:
    x = np.asarray(values, dtype=float)
    return float(np.mean(x[np.isfinite(x)])) if np.isfinite(x).any() else math.nan


def summarise(records: Sequence[FlightRecord], controllers: Sequence[str],
              cases: Sequence[str], refused: Mapping[tuple[str, str], str] | None = None
              ) -> list[dict]:
    """Per (controller, case): mean divergence ratio, mean RMS ratio to the best fixed c2 on
    the same seed, and the paired differences with their 95 % intervals.

    ``divergence_difference`` = U_div/U_cr minus that of the best fixed c2 (same seed),
    ``practical_difference`` the same for the practical boundary, ``rms_change`` = RMS / RMS
    of the best fixed c2 - 1 (negative: less vibration), ``rms_hold_change`` the same for the
    hold's RMS, ``divergence_to_oracle`` = U_div/U_cr minus the oracle's,
    ``divergence_to_schedule`` and ``rms_to_schedule`` the same against the airspeed schedule
    (the study's key comparison; when those are flown); each over the seeds on which both
    flights have the value. A (controller, case) in ``refused`` gets a row with no flights and
    ``not_flown``, the reason.
    """
    table = {(r.controller, r.case, r.seed): r for r in records}
    refused = dict(refused or {})
    rows = []
    for case in cases:
        for controller in controllers:
            own = [r for (c, k, _), r in table.items() if c == controller and k == case]
            if not own:
                if (controller, case) in refused:
                    rows.append(_refused_row(controller, case, refused[(controller, case)]))
                continue
            ref = {r.seed: table.get((REFERENCE_CONTROLLER, case, r.seed)) for r in own}
            oracle = {r.seed: table.get(("oracle", case, r.seed)) for r in own}
            schedule = {r.seed: table.get(("schedule", case, r.seed)) for r in own}
            pairs = [(r, ref[r.seed]) for r in own if ref[r.seed] is not None]
            div = [r.divergence_ratio for r in own]
            ddiff = [r.divergence_ratio - f.divergence_ratio for r, f in pairs]
            ratio = [r.rms / f.rms for r, f in pairs]
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
                "mean_practical_ratio": _mean([r.practical_ratio for r in own]),
                "reached_limit": sum(math.isfinite(r.practical_ratio) for r in own),
                "mean_rms_hold": _mean([r.rms_hold for r in own]),
                "hold_fluttered": sum(not math.isfinite(r.rms_hold) for r in own),
                "switches_per_second": _mean([r.switches_per_second for r in own]),
                "damper_power": _mean([r.damper_power for r in own]),
                "not_flown": None,
                "divergence_difference": paired(ddiff),
                "practical_difference": paired(
                    [r.practical_ratio - f.practical_ratio for r, f in pairs]),
                "rms_change": paired(np.asarray(ratio) - 1.0),
                "rms_hold_change": paired([r.rms_hold / f.rms_hold - 1.0 for r, f in pairs]),
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


#: The paired statistics of a row (:class:`PairedStat`).
ROW_STATS = ("divergence_difference", "practical_difference", "rms_change", "rms_hold_change",
             "divergence_to_oracle", "divergence_to_schedule", "rms_to_schedule")


def _refused_row(controller: str, case: str, reason: str) -> dict:
    empty = PairedStat(0, math.nan, math.nan, math.nan)
    row = {"controller": controller, "case": case, "flights": 0, "diverged": 0,
           "reached_limit": 0, "hold_fluttered": 0, "not_flown": reason}
    for key in ("mean_divergence_ratio", "mean_rms_ratio", "mean_rms", "mean_c2",
                "median_peak_activation", "mean_practical_ratio", "mean_rms_hold",
                "switches_per_second", "damper_power"):
        row[key] = math.nan
    row.update({k: empty for k in ROW_STATS})
    return row


def law_pairs(records: Sequence[FlightRecord], laws: Sequence[str],
              cases: Sequence[str]) -> list[dict]:
    """Each of ``laws`` after the first against the first, per case, on the same seeds: the
    paired differences of the bounded and practical boundaries [U_cr] and the RMS ratios - 1
    over the RMS range and at the hold (the per-sample laws against each other)."""
    table = {(r.controller, r.case, r.seed): r for r in records}
    out = []
    for case in cases:
        for law in laws[1:]:
            pairs = [(r, table[(laws[0], case, seed)]) for (c, k, seed), r in table.items()
                     if c == law and k == case and (laws[0], case, seed) in table]
            if not pairs:
                continue
            out.append({
                "law": law, "against": laws[0], "case": case, "flights": len(pairs),
                "divergence": paired([a.divergence_ratio - b.divergence_ratio
                                      for a, b in pairs]).to_dict(),
                "practical": paired([a.practical_ratio - b.practical_ratio
                                     for a, b in pairs]).to_dict(),
                "rms": paired([a.rms / b.rms - 1.0 for a, b in pairs]).to_dict(),
                "rms_hold": paired([a.rms_hold / b.rms_hold - 1.0 for a, b in pairs]).to_dict(),
            })
    return out
