"""Seeds flown together give the flights (and the records) of one flight at a time."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.oracle import OptimalDampingTable
from aero_dva.control.rbf_network import InputScaling, RBFNetwork, spectrum_input_names
from aero_dva.flight.flight_runtime import load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, Scenario
from aero_dva.wing.model import AeroelasticModel
from dva_offline.evaluation.closed_loop import fly
from dva_offline.evaluation.closed_loop_batch import fly_batch
from dva_offline.evaluation.flights import (
    BATCH_SEEDS,
    EvaluationSetup,
    fly_paired,
    seed_batches,
)
from dva_offline.evaluation.paired import default_cases

from .controls import (
    evaluation_laws,
    fixed_control,
    oracle_control,
    rbf_control,
    schedule_control,
)

CONFIG = load_runtime_config({})
MODEL = AeroelasticModel(CONFIG.wing, CONFIG.absorber, CONFIG.aero)
SCHEDULE = AirspeedSchedule(-1060.0, 14.6, (110.0, 115.0), (0.0, 2500.0))

# The batch sums some products over several flights in another order than one flight does:
# the same flight to rounding (measured: 1e-13 relative at most over a 30 s flight). 1e-9 is
# the records' agreement across processes (test_paired.RECORD_RTOL) and far below what another
# seed, controller or case changes (1e-3 and more).
RTOL = 1e-9


def _network() -> RBFNetwork:
    """Five neurons that see the spectra, so every flight gets its own c2."""
    names, units = spectrum_input_names()
    rng = np.random.default_rng(0)
    centres = np.c_[rng.uniform(0.0, 0.15, (5, 32)), rng.uniform(1.2, 1.8, (5, 1))]
    return RBFNetwork(centres=centres, output_weights=np.array([-80.0, 50, 30, -20, 60]),
                      output_bias=600.0, spread=1.0,
                      scaling=InputScaling(np.zeros(33), np.r_[np.full(32, 0.3), 400.0]),
                      input_names=names, input_units=units)


def _config(duration=3.0, airspeed=("ramp", (88.0, 96.0)), mu=0.1):
    scenario = Scenario("t", duration, block_size=50, airspeed=AirspeedProfile(*airspeed),
                        density=1.2, density_variation=mu, density_frequency=1.0, seed=0)
    return replace(CONFIG, scenario=scenario)


def _one_at_a_time(config, make, seeds):
    return [fly(replace(config, scenario=replace(config.scenario, seed=s)), make())
            for s in seeds]


def _assert_same_flights(got, expected):
    assert len(got) == len(expected)
    for g, e in zip(got, expected, strict=True):
        assert (g.samples, g.diverged) == (e.samples, e.diverged)
        for name in ("airspeed", "density", "damping", "leading_edge", "peak_activation"):
            a, b = getattr(g, name), getattr(e, name)
            assert a.shape == b.shape, name
            scale = np.abs(b).max() if b.size else 0.0
            np.testing.assert_allclose(a, b, rtol=RTOL, atol=RTOL * scale, err_msg=name)


TABLE = OptimalDampingTable.build(MODEL, np.arange(86.0, 99.0, 1.0), np.array([1.05, 1.2, 1.35]))


@pytest.mark.parametrize("make", [
    lambda: fixed_control(624.7),
    lambda: schedule_control(SCHEDULE),
    lambda: oracle_control(TABLE),
    lambda: rbf_control(_network()),
], ids=["fixed", "schedule", "oracle", "rbf"])
def test_a_seed_batch_flies_each_seed_as_one_flight_does(make):
    config = _config()
    seeds = (1, 2, 5)
    got = fly_batch(config, make, seeds)
    _assert_same_flights(got, _one_at_a_time(config, make, seeds))
    # the seeds are different flights (their forces differ)
    assert not np.allclose(got[0].leading_edge, got[1].leading_edge)
    if make().entry.name == "rbf":  # each flight its own c2 from its spectra
        assert got[0].peak_activation.size == 11
        assert not np.array_equal(got[0].damping[-100:], got[1].damping[-100:])


def test_diverging_flights_stop_at_their_own_block_and_the_others_go_on():
    config = _config(duration=2.0, airspeed=("constant", (130.0,)), mu=0.0)
    seeds = (1, 2, 3)
    got = fly_batch(config, lambda: fixed_control(600.0), seeds)
    expected = _one_at_a_time(config, lambda: fixed_control(600.0), seeds)
    _assert_same_flights(got, expected)
    assert all(g.diverged for g in got) and len({g.samples for g in got}) == 2


def test_scenarios_the_batch_cannot_fly_go_one_at_a_time():
    # a stepped sweep operates the damper itself: flown by fly() per seed, same flights
    scenario = replace(_config().scenario, airspeed=AirspeedProfile("steps", (88.0, 90.0)),
                       duration=1.0, dwell=0.25, sweep_damping=(500.0, 700.0))
    config = replace(CONFIG, scenario=scenario)
    got = fly_batch(config, lambda: fixed_control(600.0), (1, 2))
    for g, e in zip(got, _one_at_a_time(config, lambda: fixed_control(600.0), (1, 2))):
        np.testing.assert_array_equal(g.leading_edge, e.leading_edge)


def test_seed_batches_keep_every_worker_busy():
    seeds = list(range(1, 31))
    assert seed_batches(seeds, 6, 1) == [tuple(seeds)]
    two = seed_batches(seeds, 1, 2)
    assert len(two) == 4 and sum(two, ()) == tuple(seeds)
    assert seed_batches([4], 6, 8) == [(4,)]
    many = seed_batches(list(range(100)), 6, 1)  # memory: at most BATCH_SEEDS per batch
    assert max(map(len, many)) <= BATCH_SEEDS and sum(many, ()) == tuple(range(100))


def test_batched_records_equal_the_one_flight_records():
    """Every controller on a ramp through flutter with a varying density, two seeds: the
    records `dva evaluate` writes are the same on both routes (an 8 s ramp to keep it cheap;
    the 30 s default in bench/bench_evaluate_batch.py)."""
    ramp = Scenario("ramp", 8.0, block_size=50, airspeed=AirspeedProfile(
        "ramp", (0.95, 1.25), relative=True), density=1.2, seed=0)
    setup = EvaluationSetup(config=replace(CONFIG, scenario=ramp), model=MODEL,
                            critical_airspeed=100.0, laws=evaluation_laws(
                                624.7, SCHEDULE, _network(), OptimalDampingTable.build(
                                    MODEL, np.arange(93.0, 128.0, 5.0), np.array([1.0, 1.4]))),
                            rms_range=(96.0, 105.0))
    case = default_cases(8.48)["1Hz"]
    controllers = ("fixed", "schedule", "rbf", "oracle")
    batched, kept = fly_paired(setup, [case], [3, 4], controllers, keep_seed=3)
    single, kept_single = fly_paired(setup, [case], [3, 4], controllers, keep_seed=3,
                                     batch=False)
    assert [(r.controller, r.seed) for r in batched] == \
        [(c, s) for s in (3, 4) for c in controllers]
    for b, s in zip(batched, single, strict=True):
        for key, value in s.to_dict().items():
            other = b.to_dict()[key]
            if isinstance(value, float):
                assert other == pytest.approx(value, rel=RTOL), (key, b, s)
            else:
                assert other == value, (key, b, s)
    assert set(kept) == set(kept_single) == {(c, "1Hz", 3) for c in controllers}
    # the ramp reaches flutter and the RMS range is flown: both are compared
    assert all(r.diverged and np.isfinite(r.divergence_ratio) and np.isfinite(r.rms)
               for r in batched)
    assert all(np.isfinite(r.median_peak_activation) == (r.controller == "rbf")
               for r in batched)

