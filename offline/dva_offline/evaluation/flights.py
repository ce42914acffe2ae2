"""The paired evaluation's flights and stability boundaries (``dva evaluate``).

:func:`fly_paired` flies every (case, seed, controller) of :mod:`dva_offline.evaluation.paired`:
by default the seeds of a case in batches, each controller's flights of a batch together
(:func:`fly_seeds`, :func:`.closed_loop_batch.fly_batch`); with ``batch=False`` one flight at
a time (:func:`fly_seed`, :func:`.closed_loop.fly`, the reference route). Both give the same
records up to rounding. :func:`stability_boundaries` gives, per case, where the
linear wing stops being stable under each analysable control law: the frozen-density
eigenvalue boundary (at the case's density, or at the worst density of its cycle) and, for a
varying density, the Floquet boundary of the periodic system
(:mod:`aero_dva.control.periodic_stability`). A law that reads more than time and the flight
condition (the RBF network's spectra) has no such boundary; its flights are the measurement.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from aero_dva.control import controllers as table
from aero_dva.control.oracle import OptimalDampingTable
from aero_dva.control.periodic_stability import floquet_boundary, frozen_boundary
from dva_offline.evaluation.closed_loop import LawControl, PerSampleControl, fly
from dva_offline.evaluation.closed_loop_batch import fly_batch
from dva_offline.evaluation.paired import (
    DensityCase,
    FlightRecord,
    case_scenario,
    flight_record,
    hold_scenario,
)

__all__ = ["BATCH_MEMORY", "BATCH_SEEDS", "PEAK_FACTOR", "EvaluationSetup", "batch_seeds",
           "flight_memory_problem", "case_table", "fly_paired", "fly_seed", "fly_seeds",
           "oracle_table", "peak_limit", "refused", "seed_batches", "stability_boundaries"]


@dataclass(frozen=True)
class EvaluationSetup:
    """What the flights share.

    Attributes
    ----------
    config : RuntimeConfig
        The base flight (scenario = the ramp, relative to U_cr; wing, absorber, damper).
    model : AeroelasticModel
        The wing with its Maxwell DVA.
    critical_airspeed : float
        [m/s] U_cr of the bare wing at the base density.
    laws : mapping
        Controller name -> its law as made from the evaluation's inputs (each flight flies a
        copy, so a law's state is its flight's own); a per-sample law's gains.
    rms_range : (float, float)
        [m/s] airspeeds of the RMS.
    ramp_to : float or None
        [U/U_cr] the ramp carried on at its slope to this airspeed (None: as the scenario).
    peak_limits : mapping
        Case name -> [m] the leading-edge displacement beyond which a flight has reached its
        practical boundary (:func:`peak_limit`).
    safe_damping : float
        [N s/m] the constant c2 of a per-sample law's commands (the best fixed c2).
    hold : bool
        Fly each controller's hold at :data:`~dva_offline.evaluation.paired.HOLD` too.
    """

    config: object
    model: object
    critical_airspeed: float
    laws: Mapping[str, object] = field(default_factory=dict)
    rms_range: tuple[float, float] = (80.0, 105.0)
    ramp_to: float | None = None
    peak_limits: Mapping[str, float] = field(default_factory=dict)
    safe_damping: float = math.nan
    hold: bool = True

    def controller(self, name: str) -> LawControl | PerSampleControl:
        if name not in self.laws:
            raise ValueError(f"no law for controller {name!r} in this evaluation")
        entry = table.controller(name)
        if entry.runs == table.SAMPLE:
            return PerSampleControl(entry, self.laws[name], self.safe_damping)
        return LawControl(entry, copy.deepcopy(self.laws[name]),
                          self.config.scenario.sample_rate)

    def scenario(self, case: DensityCase, seed: int):
        """The ramp of ``case`` and ``seed``."""
        return case_scenario(self.config.scenario, case, self.critical_airspeed, seed,
                             self.ramp_to)

    def record(self, name: str, case: DensityCase, seed: int, outcome, hold) -> FlightRecord:
        return flight_record(name, case.name, seed, outcome, self.critical_airspeed,
                             self.rms_range, peak_limit=self.peak_limits.get(case.name,
                                                                             math.inf),
                             hold=hold)


#: A per-sample law cannot fly a density that varies in time: it multiplies the held
#: conditions, each with its own table of c2 levels, all kept for the whole flight.
VARYING_DENSITY = ("a density varying in time multiplies the held conditions, each with its "
                   "own table of the law's c2 levels")


def refused(controller: str, case: DensityCase) -> str | None:
    """Why ``controller`` does not fly ``case`` in the evaluation, or None."""
    if table.controller(controller).runs == table.SAMPLE and case.variation != 0.0:
        return VARYING_DENSITY
    return None


#: The practical boundary's peak limit: this many times the best fixed c2's stationary
#: leading-edge RMS at the start of the ramp (the switching law's study took 20x the fixed
#: damper's RMS over its first seconds, 13 mm on the chapter-6 wing; this is the same number
#: from the model, known before any flight).
PEAK_FACTOR = 20.0


def peak_limit(model, airspeed: float, density: float, damping: float) -> float:
    """[m] :data:`PEAK_FACTOR` x the stationary leading-edge RMS at ``airspeed`` [m/s],
    ``density`` and the constant c2 ``damping`` (1 kN white force at 1 kHz)."""
    from aero_dva.control.stationary_rms import stationary_rms

    rms = stationary_rms(model, airspeed, density, damping).output("leading_edge")
    return PEAK_FACTOR * float(rms)


def oracle_table(model, critical_airspeed: float, base_density: float,
                 cases: Sequence[DensityCase], ramp: tuple[float, float]
                 ) -> OptimalDampingTable:
    """c2*(U, rho) over the ramp's airspeeds and every case's densities (1 m/s x 0.04 rho0
    grid, bilinear between: c2* changes by about 10 N s/m per grid step)."""
    low = min(ramp) * critical_airspeed - 2.0
    high = max(ramp) * critical_airspeed + 2.0
    rho = [base_density * c.factor * (1 + s * c.variation) for c in cases for s in (-1, 1)]
    r_lo, r_hi = min(rho) - 0.02 * base_density, max(rho) + 0.02 * base_density
    n_rho = max(3, int(math.ceil((r_hi - r_lo) / (0.04 * base_density))) + 1)
    return OptimalDampingTable.build(model, np.arange(math.floor(low), high + 1.0, 1.0),
                                     np.linspace(r_lo, r_hi, n_rho))


def fly_seed(setup: EvaluationSetup, controllers: Sequence[str], keep_seed: int | None,
             job: tuple[DensityCase, int]) -> tuple[list[FlightRecord], dict]:
    """One job of the evaluation: every controller on one (case, seed), the same force realisation
    for all (paired), its ramp and its hold; the outcomes too when the seed is ``keep_seed``
    (for plots). A controller that cannot fly the case (:func:`refused`) flies nothing."""
    case, seed = job
    config = replace(setup.config, scenario=setup.scenario(case, seed))
    held = replace(setup.config, scenario=hold_scenario(setup.config.scenario, case,
                                                         setup.critical_airspeed, seed))
    records, kept = [], {}
    for name in controllers:
        if refused(name, case):
            continue
        outcome = fly(config, setup.controller(name), setup.critical_airspeed)
        hold = fly(held, setup.controller(name), setup.critical_airspeed) if setup.hold \
            else None
        records.append(setup.record(name, case, seed, outcome, hold))
        if seed == keep_seed:
            kept[(name, case.name, seed)] = outcome
    return records, kept


def fly_seeds(setup: EvaluationSetup, controllers: Sequence[str], keep_seed: int | None,
              job: tuple[DensityCase, tuple[int, ...]]
              ) -> tuple[dict[int, list[FlightRecord]], dict]:
    """One batched job: every controller on a batch of seeds of one case, each controller's
    flights of the batch flown together (:func:`.closed_loop_batch.fly_batch`; a per-sample
    law one at a time), ramps and holds. Returns the records per seed (in controller order, as
    :func:`fly_seed`) and the outcomes of ``keep_seed`` when it is in the batch."""
    case, seeds = job
    config = replace(setup.config, scenario=setup.scenario(case, seeds[0]))
    held = replace(setup.config, scenario=hold_scenario(setup.config.scenario, case,
                                                         setup.critical_airspeed, seeds[0]))
    records: dict[int, list[FlightRecord]] = {s: [] for s in seeds}
    kept = {}
    for name in controllers:
        if refused(name, case):
            continue
        make = partial(setup.controller, name)
        outcomes = fly_batch(config, make, seeds, setup.critical_airspeed)
        holds = fly_batch(held, make, seeds, setup.critical_airspeed) if setup.hold \
            else [None] * len(seeds)
        for seed, outcome, hold in zip(seeds, outcomes, holds, strict=True):
            records[seed].append(setup.record(name, case, seed, outcome, hold))
            if seed == keep_seed:
                kept[(name, case.name, seed)] = outcome
    return records, kept


BATCH_SEEDS = 32
"""Most seeds in one batch: its flights' traces are held whole (about 2 MB per flight of the
default ramp), and from a few tens of flights on the per-block cost is already shared."""
#: [bytes] what a flight of the evaluation holds per sample (its traces; measured 78 B for the
#: fixed controller's batch route, the RBF network's windows add more: docs/reliability.md).
FLIGHT_BYTES_PER_SAMPLE = 160
#: [bytes] most the flights of one batch (one job of one process) may hold.
BATCH_MEMORY = 2**30


def batch_seeds(samples: int) -> int:
    """Most seeds per batch for flights of ``samples`` samples: :data:`BATCH_SEEDS`, fewer when
    their traces would pass :data:`BATCH_MEMORY`."""
    return max(1, min(BATCH_SEEDS, BATCH_MEMORY // max(1, samples * FLIGHT_BYTES_PER_SAMPLE)))


def flight_memory_problem(samples: int) -> str | None:
    """Why one evaluation flight of ``samples`` samples may not be flown (it would hold more
    than :data:`BATCH_MEMORY`), or None."""
    need = samples * FLIGHT_BYTES_PER_SAMPLE
    if need <= BATCH_MEMORY:
        return None
    return (f"a flight of {samples:,} samples would hold about {need / 2**20:,.0f} MiB of "
            f"traces, more than the {BATCH_MEMORY // 2**20:,} MiB an evaluation flight may "
            f"take (at most {BATCH_MEMORY // FLIGHT_BYTES_PER_SAMPLE:,} samples: duration x "
            "sample rate)")


def seed_batches(seeds: Sequence[int], cases: int, workers: int,
                 samples: int = 0) -> list[tuple[int, ...]]:
    """The seeds of a case cut into batches: as few as keep ``workers`` busy (at least two jobs
    per worker over all ``cases``) and hold at most :func:`batch_seeds` seeds each for flights
    of ``samples`` samples, as large as possible otherwise (the per-block cost of a batch is
    paid once for all its flights)."""
    seeds = tuple(seeds)
    parts = 1 if workers <= 1 else max(1, min(len(seeds), -(-2 * workers // max(cases, 1))))
    parts = max(parts, -(-len(seeds) // batch_seeds(samples)))
    size = -(-len(seeds) // parts)
    return [seeds[i:i + size] for i in range(0, len(seeds), size)]


def fly_paired(setup: EvaluationSetup, cases: Sequence[DensityCase], seeds: Sequence[int],
              controllers: Sequence[str], progress: Callable[[str], None] | None = None,
              keep_seed: int | None = None, *, workers: int = 1, ray_address: str | None = None,
              done: Mapping[tuple[str, int], list[FlightRecord]] | None = None,
              finished: Callable[[tuple[str, int], list[FlightRecord]], None] | None = None,
              batch: bool = True) -> tuple[list[FlightRecord], dict]:
    """Fly everything; returns the records (in case, seed, controller order, whatever the
    route) and the outcomes of ``keep_seed`` (for plots).

    The jobs are run by :func:`.campaign.run_jobs`: in order, on ``workers`` forked
    processes, or on Ray (``ray_address``). With ``batch`` (the default) a job is a batch of
    seeds of one case (:func:`seed_batches`, :func:`fly_seeds`); without, one (case, seed)
    (:func:`fly_seed`, the one-flight reference route). ``done`` maps a (case name, seed)
    already flown (a resumed evaluation) to its records: that seed is not flown again unless
    its outcomes are wanted for plots. ``finished(key, records)`` is called in this process
    for each (case name, seed) as its job completes (to save it).
    """
    from dva_offline.evaluation.campaign import check_workers, run_jobs

    check_workers(workers)
    done = dict(done or {})
    results: dict[tuple[str, int], list[FlightRecord]] = dict(done)
    kept: dict = {}
    todo = {case.name: [s for s in seeds if s == keep_seed or (case.name, s) not in done]
            for case in cases}
    if batch:
        jobs = [(case, part) for case in cases if todo[case.name]
                for part in seed_batches(todo[case.name], len(cases), workers,
                                         setup.config.scenario.n_samples)]
        # The jobs whose outcomes come back (large) first, so they are not the last to finish.
        jobs.sort(key=lambda job: keep_seed not in job[1])
        work = partial(fly_seeds, setup, tuple(controllers), keep_seed)
    else:
        jobs = [(case, seed) for case in cases for seed in todo[case.name]]
        jobs.sort(key=lambda job: job[1] != keep_seed)
        work = partial(fly_seed, setup, tuple(controllers), keep_seed)
    for job, (records, outcomes) in run_jobs(jobs, work, workers=workers,
                                             ray_address=ray_address, processes=True):
        by_seed = records if batch else {job[1]: records}
        for seed, rows in by_seed.items():
            _finish((job[0].name, seed), rows, results, finished, progress)
        kept.update(outcomes)
    ordered = [r for case in cases for seed in seeds for r in results[(case.name, seed)]]
    return ordered, kept


def _finish(key, records, results, finished, progress) -> None:
    results[key] = records
    if finished is not None:
        finished(key, records)
    if progress is not None:
        for r in records:
            progress(f"{key[0]} seed {key[1]} {r.controller}")


def _laws(setup: EvaluationSetup, controllers: Sequence[str]) -> dict:
    """c2 as a function of the flight condition (a number, or ``c2(U, rho)``) of each flown
    law that has one (``condition_law``)."""
    return {name: setup.laws[name].condition_law() for name in controllers
            if name in setup.laws and hasattr(setup.laws[name], "condition_law")}


def stability_boundaries(setup: EvaluationSetup, cases: Sequence[DensityCase],
                         controllers: Sequence[str]) -> dict[str, dict[str, dict]]:
    """Per case and control law: ``{"frozen": U/U_cr, "floquet": U/U_cr or None}``.

    ``frozen``: the eigenvalue boundary at the case's density, or for a varying density the
    lowest one over the cycle's extremes; ``floquet``: the periodic system's (varying density
    only).
    """
    u_cr = setup.critical_airspeed
    rho0 = setup.config.scenario.density
    span = (0.7 * u_cr, 1.6 * u_cr)
    out: dict[str, dict[str, dict]] = {}
    for case in cases:
        rows = {}
        base = rho0 * case.factor
        for name, law in _laws(setup, controllers).items():
            extremes = (base,) if case.variation == 0 else \
                (base * (1 - case.variation), base * (1 + case.variation))
            frozen = min(frozen_boundary(setup.model, r, law, span) for r in extremes)
            floquet = None
            if case.variation > 0:
                floquet = floquet_boundary(setup.model, base, case.variation, case.frequency,
                                           law, span) / u_cr
            rows[name] = {"frozen": frozen / u_cr if math.isfinite(frozen) else None,
                          "floquet": floquet if floquet is None or math.isfinite(floquet)
                          else None}
        out[case.name] = rows
    return out


def case_table(cases: Mapping[str, DensityCase]) -> list[dict]:
    """The cases as JSON rows."""
    return [{"case": c.name, "density_factor": c.factor, "variation": c.variation,
             "frequency_hz": c.frequency, "description": c.description}
            for c in cases.values()]
