"""What the damper flew with: blocks on the controller's, start-up and fallback c2, and when a
flight must not be reported as controlled."""
from __future__ import annotations

import dataclasses

from aero_dva.flight.applied_control import AppliedControl, control_problem
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, Scenario


def _runtime(**params) -> FlightRuntime:
    scenario = Scenario("c", 1.0, block_size=50, airspeed=AirspeedProfile("constant", (80.0,)),
                        seed=4)
    config = load_runtime_config(params)
    return FlightRuntime(dataclasses.replace(config, scenario=scenario))


def test_runtime_counts_blocks_by_the_source_of_their_c2():
    runtime = _runtime(damper_timeout=0.2)
    for _ in range(3):
        runtime.step()  # no command yet: start-up c2
    runtime.command(900.0, "test")
    for _ in range(7):
        runtime.step()
    applied = runtime.applied
    assert (applied.blocks, applied.startup) == (10, 3)
    # the command at t = 0.15 s is stale once older than 0.2 s: from the block at 0.4 s on
    assert applied.controlled == 5 and applied.fallback == 2
    assert applied.values() == {"blocks": 10, "blocks_controlled": 5, "blocks_startup": 3,
                                "blocks_fallback": 2}


def test_a_flight_without_a_controlled_block_is_refused():
    assert "never acted" in control_problem(100, 0, 0, 0.5)
    assert "never acted" in control_problem(100, 0, 100, 1.0)
    assert "no block" in control_problem(0, 0, 0, 0.5)


def test_the_fallback_share_is_bounded():
    assert control_problem(100, 98, 2, 0.02) is None
    problem = control_problem(100, 97, 3, 0.02)
    assert "3 of 100 blocks (3.0%)" in problem and "2.0%" in problem
    assert control_problem(100, 1, 0, 0.0) is None  # start-up blocks are not fallback


def test_counts_add_up():
    applied = AppliedControl()
    for source in ("initial", "initial", "airspeed_schedule", "fallback", "fixed"):
        applied.count(source)
    assert (applied.blocks, applied.startup, applied.fallback, applied.controlled) == (5, 2, 1, 2)
