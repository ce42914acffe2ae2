"""The switching c2 law over ROS 2: the simulator runs it in its damper path every sample, the
switching_controller supervises it. Launch-free, real nodes over DDS on sim time, short flights.

- On a fast ramp through the flutter boundary the wing flown with the law diverges at a
  higher airspeed than with the best constant c2 (same seed).
- Each fault leaves the damper on a constant c2 and says so: an invalid gains file (in the
  simulator, and in the supervisor), a burst (the supervisor's peak limit) and stale commands
  (the supervisor falls silent: the damper's timeout ends the law).
"""
from __future__ import annotations

import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from aero_dva.data_files import data_file
from aero_dva_sim.simulator_node import Simulator
from dva_controller.controller_node import law_node
from dva_controller.switching_controller_node import SwitchingController
from dva_msgs.msg import (
    AccelerationBlock,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)
from dva_ros_common.node_tools import close_executor

FixedController = law_node("fixed")

pytestmark = pytest.mark.ros

SAFE_C2 = 624.7  # [N s/m] the best constant c2 of the chapter-6 wing
GAINS = str(data_file("switching_gains.json"))
# 1.10 -> 1.30 U_cr in 4 s: the best constant c2 flutters at 1.15 U_cr, the law about 0.05 later.
RAMP = "airspeed: {kind: ramp, start_ratio: 1.10, end_ratio: 1.30}"
HOLD = "airspeed: {kind: constant, value_ratio: 1.0}"


def fly(executor, spin, ros_context, tmp_path, controller: Node | None, airspeed: str,
        duration: float, gains: str = GAINS, stop=None):
    """Fly one scenario with ``controller``; returns the simulator, the damper states, the
    diagnostics texts and the displacement blocks. ``stop(states)`` true removes the
    controller (silence)."""
    from diagnostic_msgs.msg import DiagnosticArray

    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(f"name: s\nduration: {duration}\nblock_size: 50\n{airspeed}\n"
                        "excitation: {force_std: 1000.0, seed: 5}\n")
    sim = Simulator(context=ros_context, parameter_overrides=[
        Parameter("scenario", value=str(scenario)), Parameter("real_time_factor", value=0.0),
        Parameter("wait_for_subscribers", value=1), Parameter("damper_timeout", value=0.3),
        Parameter("damper_time_constant", value=0.01), Parameter("switching_gains", value=gains),
        # the flight waits for the supervisor's commands; once it is silent, 0.5 s (wall)
        Parameter("max_command_lag", value=0.2), Parameter("command_wait_timeout", value=0.5),
        Parameter("wait_for_command_publishers", value=1)])
    probe = Node("probe", context=ros_context)
    states, texts, blocks = [], [], []
    probe.create_subscription(DamperState, "dva/damper_state", states.append, 5000)
    probe.create_subscription(DisplacementBlock, "wing/displacement", blocks.append, 5000)
    probe.create_subscription(
        DiagnosticArray, "/diagnostics",
        lambda m: texts.extend(f"{s.name}: {s.message}" for s in m.status), 1000)
    for msg_type, topic in ((ForceBlock, "wing/excitation"), (FlightCondition, "flight/condition"),
                            (AccelerationBlock, "wing/acceleration")):
        probe.create_subscription(msg_type, topic, lambda _: None, 10)
    nodes = [probe, sim] if controller is None else [controller, probe, sim]
    for node in nodes:
        executor.add_node(node)
    if stop is not None:
        assert spin(executor, lambda: stop(states) or sim.finished.done(), timeout=60.0)
        executor.remove_node(controller)
        controller.destroy_node()  # alive, it would stay in the domain after the test
    assert spin(executor, sim.finished.done, timeout=120.0)
    spin(executor, lambda: len(states) >= sim.published["dva/damper_state"]
         and len(blocks) >= sim.published["wing/displacement"], timeout=5.0)
    spin(executor, lambda: any("flight" in t and ("completed" in t or "diverged" in t)
                               for t in texts), timeout=5.0)
    return sim, states, texts, blocks


def supervisor(ros_context, **params):
    overrides = [Parameter("use_sim_time", value=True), Parameter("rate", value=20.0)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return SwitchingController(context=ros_context, parameter_overrides=overrides)


def diverged_at(sim, texts) -> float:
    """U/U_cr where the simulator stopped the flight (after its divergence)."""
    text = next(t for t in texts if "flight stopped at U = " in t)
    return float(text.split("U/U_cr = ")[1].split(",")[0])


def test_switching_diverges_later_than_the_best_constant_c2(executor, spin, ros_context,
                                                            tmp_path):
    # The burst detector is set out of the way: this compares the laws, not the supervisor.
    law = supervisor(ros_context, peak_limit=10.0)
    sim, states, texts, _ = fly(executor, spin, ros_context, tmp_path, law, RAMP, 4.0)
    assert sim.finished.result() == "diverged"
    switched_at = diverged_at(sim, texts)
    armed = [s for s in states if s.mode == DamperState.MODE_SWITCHING]
    assert len(armed) > 0.9 * len(states)
    rates = sorted(s.switching_rate for s in armed)
    assert rates[len(rates) // 2] > 5.0  # the law switches within the blocks
    assert any("switching law armed in the damper path" in t for t in texts)
    close_executor(executor)  # the second flight has its own executor and nodes

    second = SingleThreadedExecutor(context=ros_context)
    fixed = FixedController(context=ros_context, parameter_overrides=[
        Parameter("use_sim_time", value=True), Parameter("damping", value=SAFE_C2),
        Parameter("rate", value=20.0)])
    try:
        sim, states, texts, _ = fly(second, spin, ros_context, tmp_path, fixed, RAMP, 4.0)
    finally:
        close_executor(second, fixed)
    assert sim.finished.result() == "diverged"
    assert all(s.mode == DamperState.MODE_CONSTANT for s in states)
    assert switched_at > diverged_at(sim, texts) + 0.01


def test_the_graph_flight_is_the_in_process_flight(executor, spin, ros_context, tmp_path):
    # The first block flies before any command (on the start-up c2); from the second on the
    # flight holds for the first command, and every command arms the law with the same safe
    # c2: the graph flies what the runtime flies in process with a "switching" command before
    # each later block.
    import numpy as np

    from aero_dva.control.switching_io import with_switching
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    law = supervisor(ros_context, peak_limit=10.0)
    sim, states, _, blocks = fly(executor, spin, ros_context, tmp_path, law, RAMP, 1.0)
    assert sim.finished.result() == "completed"
    assert states[0].mode == DamperState.MODE_CONSTANT
    assert all(s.mode == DamperState.MODE_SWITCHING for s in states[1:])
    graph = np.concatenate([np.array(b.leading_edge) for b in blocks])
    config = load_runtime_config({"scenario": str(tmp_path / "scenario.yaml"),
                                  "damper_time_constant": 0.01, "damper_timeout": 0.3})
    runtime = FlightRuntime(with_switching(config, GAINS))
    local = []
    while not runtime.done:
        if local:
            runtime.command(SAFE_C2, "switching")
        local.append(runtime.step().displacements[2])
    local = np.concatenate(local)
    assert graph.size == local.size == 1000
    np.testing.assert_allclose(graph, local, rtol=1e-9, atol=1e-12 * np.abs(local).max())


def test_invalid_gains_in_the_simulator_hold_the_safe_c2_and_say_so(executor, spin,
                                                                    ros_context, tmp_path):
    bad = tmp_path / "gains.json"
    bad.write_text('{"format": "dva_switching_gains", "version": 1, "gain": [1, 2]}')
    law = supervisor(ros_context)
    sim, states, texts, _ = fly(executor, spin, ros_context, tmp_path, law, HOLD, 0.5,
                             gains=str(bad))
    assert sim.finished.result() == "completed"
    assert states[-1].mode == DamperState.MODE_SWITCHING_REFUSED
    assert states[-1].applied_damping == pytest.approx(SAFE_C2, rel=1e-6)
    assert any("switching law refused: invalid switching gains" in t for t in texts)
    assert spin(executor, lambda: law.damper_mode == DamperState.MODE_SWITCHING_REFUSED, 5.0)


def test_invalid_gains_in_the_supervisor_never_arm(executor, spin, ros_context, tmp_path):
    bad = tmp_path / "gains.json"
    bad.write_text("not json")
    law = supervisor(ros_context, gains_file=str(bad))
    assert law.reason.startswith("invalid switching gains")
    sim, states, texts, _ = fly(executor, spin, ros_context, tmp_path, law, HOLD, 0.5)
    assert all(s.mode == DamperState.MODE_CONSTANT for s in states)
    assert states[-1].source == "switching_fallback"
    assert states[-1].applied_damping == pytest.approx(SAFE_C2, rel=1e-6)
    assert law.fallbacks[0].startswith("invalid switching gains")  # said at start-up


def test_a_burst_disarms_the_law_and_says_so(executor, spin, ros_context, tmp_path):
    # The default peak limit (13 mm): on the ramp the law bursts near its practical boundary.
    law = supervisor(ros_context, rearm_after=100.0)
    sim, states, texts, _ = fly(executor, spin, ros_context, tmp_path, law, RAMP, 4.0)
    assert law.fallbacks and law.fallbacks[0].startswith("burst detector")
    modes = [s.mode for s in states]
    first_fallback = next(i for i, s in enumerate(states) if s.source == "switching_fallback")
    assert modes[first_fallback - 1] == DamperState.MODE_SWITCHING  # armed until the burst
    assert all(m == DamperState.MODE_CONSTANT for m in modes[first_fallback + 1:])
    assert any("switching law not armed: burst detector" in t for t in texts)
    assert any("switching law disarmed" in t for t in texts)


def test_stale_commands_end_the_law_on_the_fallback_c2(executor, spin, ros_context, tmp_path):
    law = supervisor(ros_context)
    sim, states, texts, _ = fly(
        executor, spin, ros_context, tmp_path, law, HOLD, 2.0,
        stop=lambda s: sum(x.mode == DamperState.MODE_SWITCHING for x in s) >= 3)
    assert sim.finished.result() == "completed"
    assert any(s.mode == DamperState.MODE_SWITCHING for s in states)
    assert states[-1].status == DamperState.STATUS_FALLBACK_STALE
    assert states[-1].mode == DamperState.MODE_CONSTANT
    assert any("no damper command within" in t and "switching law is disarmed" in t
               for t in texts)


def test_run_flight_refuses_an_unreadable_gains_file_at_once(tmp_path, capsys):
    from aero_dva_sim.run_flight import main as run_flight_main

    bad = tmp_path / "gains.json"
    bad.write_text('{"format": "something else"}')
    assert run_flight_main(["--controller", "switching", "--gains", str(bad), "--output",
                            str(tmp_path / "bag")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "switching gains" in err[0] and "something else" in err[0]
    assert not (tmp_path / "bag").exists()  # no graph was started
