"""Flights of one scenario stepped together: each seed as its own FlightRuntime flies it."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from aero_dva.flight.damper import DamperConfig, DamperModel
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.hidden_plant import PlantOptions
from aero_dva.flight.scenario import AirspeedProfile, Scenario
from aero_dva.flight.seed_batch import IdealDampers, SeedBatchRuntime, batch_problem

CONFIG = load_runtime_config({})
RTOL = 1e-9  # rounding only (products over several flights sum in another order)


def _config(seed=0, duration=1.0, block_size=50):
    scenario = Scenario("t", duration, block_size=block_size,
                        airspeed=AirspeedProfile("ramp", (90.0, 100.0)), density=1.2,
                        density_variation=0.1, density_frequency=2.0, seed=seed)
    return replace(CONFIG, scenario=scenario)


def _commands(block_number: int, seeds) -> np.ndarray:
    """Each flight its own c2, some blocks none (NaN) for some flights."""
    c2 = 400.0 + 50.0 * np.arange(len(seeds)) + 3.0 * block_number
    c2[(block_number + np.arange(len(seeds))) % 3 == 0] = math.nan
    return c2


@pytest.mark.parametrize("block_size", [50, 37])  # 37: hold periods cut by the blocks
def test_each_seed_of_a_batch_is_the_flight_runtime_of_that_seed(block_size):
    seeds = (4, 7, 9)
    batch = SeedBatchRuntime(_config(block_size=block_size), seeds, 100.0)
    singles = [FlightRuntime(_config(seed=s, block_size=block_size), 100.0) for s in seeds]
    k = 0
    while not batch.done:
        block = batch.step()
        c2 = _commands(k, seeds)
        for row, (single, f) in enumerate(zip(singles, block.flights.tolist())):
            expected = single.step()
            assert expected.first_index == block.first_index
            np.testing.assert_array_equal(expected.force, block.force[row])
            np.testing.assert_array_equal(expected.damping, np.full(
                expected.damping.size, block.damping[row]))
            for name in ("displacements", "accelerations"):
                ref = getattr(expected, name)
                np.testing.assert_allclose(getattr(block, name)[row], ref, rtol=RTOL,
                                           atol=RTOL * np.abs(ref).max())
            if not math.isnan(c2[f]):
                single.command(float(c2[f]), "rbf")
        batch.command(c2[block.flights], "rbf")
        k += 1
    assert all(s.done for s in singles) and k == -(-1000 // block_size)


def test_one_command_for_all_flights_is_broadcast():
    batch = SeedBatchRuntime(_config(), (1, 2), 100.0)
    batch.step()
    batch.command(700.0, "fixed")
    assert np.all(batch.step().damping == 700.0)


def test_what_cannot_fly_as_a_batch_is_refused_by_name():
    plant = replace(_config().scenario, plant=PlantOptions(actuator_lag=0.01))
    assert "hidden plant" in batch_problem(replace(CONFIG, scenario=plant))
    with pytest.raises(ValueError, match="hidden plant"):
        SeedBatchRuntime(replace(CONFIG, scenario=plant), (1,), 100.0)
    assert "without absorber" in batch_problem(replace(_config(), absorber=None))
    assert batch_problem(_config()) is None
    with pytest.raises(ValueError, match="seeds"):
        SeedBatchRuntime(_config(), (), 100.0)


def test_ideal_dampers_follow_the_damper_model_rules():
    config = DamperConfig(min_damping=100.0, max_damping=2000.0, fallback_damping=600.0,
                          initial_damping=300.0, stale_timeout=0.5)
    rng = np.random.default_rng(1)
    flights = 4
    models = [DamperModel(config) for _ in range(flights)]
    ideal = IdealDampers(config, flights)
    which = np.arange(flights)
    choices = [50.0, 700.0, 2500.0, 1e6, -1.0, math.inf, math.nan, 1500.0]
    for k in range(200):
        t = 0.05 * k
        np.testing.assert_array_equal(ideal.values(which, t),
                                      [m.update(t) for m in models])
        # sparse commands, so some go stale; bad ones are rejected (the target stays)
        values = np.where(rng.random(flights) < 0.15, rng.choice(choices, flights), math.nan)
        ideal.command(which, values, t)
        for m, v in zip(models, values.tolist()):
            if not math.isnan(v):
                m.command(v, t)
    with pytest.raises(ValueError, match="lag"):
        IdealDampers(DamperConfig(0.0, 2500.0, 600.0, time_constant=0.1), 1)
