"""The flight runtime: the ROS-free stepping of a scenario behind the simulator node."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from aero_dva.flight.damper import DamperStatus
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, Scenario


def _runtime(scenario: Scenario, **params) -> FlightRuntime:
    config = load_runtime_config(params)
    return FlightRuntime(dataclasses.replace(config, scenario=scenario))


def _fly(runtime: FlightRuntime) -> list:
    blocks = []
    while not runtime.done:
        blocks.append(runtime.step())
        if blocks[-1].diverged:
            break
    return blocks


def test_same_seed_same_flight_and_blocks_tile_the_flight():
    scenario = Scenario("c", 1.0, block_size=30, airspeed=AirspeedProfile("constant", (80.0,)),
                        seed=4)
    a, b = _fly(_runtime(scenario)), _fly(_runtime(scenario))
    assert [x.first_index for x in a] == list(range(0, 1000, 30))
    assert a[-1].force.size == 1000 - 33 * 30  # the last block is shorter
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.displacements, y.displacements)
    assert all(x.t_end == y.t0 for x, y in zip(a, a[1:]))


def test_sweep_drives_the_damper_and_reports_it():
    scenario = Scenario("s", 8.0, block_size=50, airspeed=AirspeedProfile("steps", (80.0, 90.0)),
                        dwell=2.0, sweep_damping=(300.0, 900.0))
    runtime = _runtime(scenario)
    seen = []
    while not runtime.done:
        block = runtime.step()
        snapshot = runtime.damper_snapshot()
        seen.append((block.damping[0], snapshot.applied_damping, snapshot.source))
    assert all(model == reported for model, reported, _ in seen)
    assert {c for c, _, _ in seen} == {300.0, 900.0}
    assert all(source == "sweep" for _, _, source in seen)
    assert runtime.command(50.0, "controller") is None  # a sweep ignores controllers


def test_sweep_outside_the_damper_range_is_refused(tmp_path):
    path = tmp_path / "sweep.yaml"
    path.write_text("duration: auto\nairspeed: {kind: steps, values: [80.0]}\n"
                    "sweep: {dwell: 2.0, damping: [100.0, 9000.0]}\n")
    with pytest.raises(ValueError, match=r"9000 N s/m lies outside the damper.s range"):
        load_runtime_config({"scenario": str(path)})


def test_bare_wing_diverges_above_its_flutter_speed_not_below():
    below = Scenario("b", 5.0, airspeed=AirspeedProfile("constant", (0.95,), relative=True))
    above = Scenario("a", 30.0, airspeed=AirspeedProfile("constant", (1.15,), relative=True))
    assert not _fly(_runtime(below, absorber="none"))[-1].diverged
    blocks = _fly(_runtime(above, absorber="none"))
    assert blocks[-1].diverged and blocks[-1].t0 < 30.0
    assert all(np.all(np.isfinite(b.displacements)) for b in blocks)


def test_commands_pass_through_the_damper_model():
    scenario = Scenario("c", 1.0, airspeed=AirspeedProfile("constant", (80.0,)))
    runtime = _runtime(scenario, damper_timeout=0.3)
    runtime.step()
    assert runtime.command(float("nan"), "x").accepted is False
    assert runtime.command(700.0, "x").accepted is True
    assert runtime.step().damping[0] == 700.0
    while not runtime.done:
        runtime.step()
    assert runtime.damper_snapshot().status == DamperStatus.FALLBACK_STALE


def test_the_flown_damper_is_the_state_each_block_was_flown_with():
    # A new command before every block, and one that goes stale inside a block: the state
    # at a block's end is not the next block's (a command comes between), so what the bag
    # records (flown_damper) must be each block's own start, stamped t0.
    scenario = Scenario("c", 1.0, block_size=50, airspeed=AirspeedProfile("constant", (80.0,)))
    runtime = _runtime(scenario, damper_timeout=0.03)
    seen = []
    while not runtime.done:
        k = len(seen)
        if k < 10 or k % 4 == 0:  # then one block in four commanded
            runtime.command(400.0 + 10.0 * k, "x")
        block = runtime.step()
        seen.append((block, runtime.flown_damper, runtime.damper_snapshot()))
    for block, flown, _ in seen:
        assert flown.time == block.t0 and flown.applied_damping == block.damping[0]
    sources = [flown.source for _, flown, _ in seen]
    assert sources[:10] == ["x"] * 10 and sources[10:13] == ["fallback", "fallback", "x"]
    # the state at the end differs from the block's: every block (a command is 0.05 s old,
    # stale after 0.03 s)
    assert all(end.status == DamperStatus.FALLBACK_STALE for _, _, end in seen)
    assert runtime.applied.fallback == sources.count("fallback") == 8


def test_the_next_condition_is_the_one_the_block_is_flown_with():
    """The simulator publishes a block's condition before flying it: it must be the block's
    first sample to the bit (a ramp with a density wave and a short last block), and asking
    for it changes nothing of the flight."""
    scenario = Scenario("c", 1.03, block_size=50, airspeed=AirspeedProfile("ramp", (80.0, 95.0)),
                        density_variation=0.2, density_frequency=3.0, seed=2)
    plain, asked = _runtime(scenario), _runtime(scenario)
    while not plain.done:
        t0, airspeed, density = asked.next_condition()
        assert asked.next_condition() == (t0, airspeed, density)  # asked twice: the same
        a, b = plain.step(), asked.step()
        assert (t0, airspeed, density) == (b.t0, b.airspeed[0], b.density[0])
        for name in ("airspeed", "density", "force", "displacements", "accelerations"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert b.force.size == 30  # the last block, shorter
    with pytest.raises(ValueError, match="over"):
        asked.next_condition()
