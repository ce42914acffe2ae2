"""The simulator node: blocks and clock, damper safety (rejection, stale fallback), divergence."""
from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from aero_dva_sim.simulator_node import Simulator
from dva_msgs.msg import (
    AccelerationBlock,
    DamperCommand,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)

pytestmark = pytest.mark.ros


def _scenario(tmp_path, airspeed: str, duration: float = 1.0, block: int = 20) -> str:
    path = tmp_path / "scenario.yaml"
    path.write_text(f"name: test\nduration: {duration}\nblock_size: {block}\n"
                    f"airspeed: {airspeed}\nexcitation: {{force_std: 1000.0, seed: 3}}\n")
    return str(path)


class Probe:
    """Collects what the simulator publishes."""

    def __init__(self, context):
        self.node = Node("probe", context=context)
        self.blocks, self.displacements, self.states, self.clock, self.diagnostics = \
            [], [], [], [], []
        sub = self.node.create_subscription
        sub(AccelerationBlock, "wing/acceleration", self.blocks.append, 1000)
        sub(DisplacementBlock, "wing/displacement", self.displacements.append, 1000)
        sub(DamperState, "dva/damper_state", self.states.append, 1000)
        # The simulator waits for a subscriber on every data topic before it starts.
        sub(ForceBlock, "wing/excitation", lambda _: None, 1000)
        sub(FlightCondition, "flight/condition", lambda _: None, 1000)
        sub(Clock, "/clock", self.clock.append, 1000)
        sub(DiagnosticArray, "/diagnostics", self.diagnostics.append, 1000)
        self.commands = self.node.create_publisher(DamperCommand, "dva/damper_command", 10)

    def messages(self, level: bytes | None = None) -> list[str]:
        return [s.message for d in self.diagnostics for s in d.status
                if level is None or s.level == level]


def _simulator(context, tmp_path, scenario, **params):
    overrides = [Parameter("scenario", value=scenario), Parameter("real_time_factor", value=0.0),
                 Parameter("wait_for_subscribers", value=1)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return Simulator(context=context, parameter_overrides=overrides)


def test_blocks_clock_and_counts(executor, spin, ros_context, tmp_path):
    probe = Probe(ros_context)
    scenario = _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}")
    sim = _simulator(ros_context, tmp_path, scenario)
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=60.0)
    assert sim.finished.result() == "completed"
    spin(executor, lambda: len(probe.blocks) >= 50 and len(probe.clock) >= 50
         and probe.diagnostics, timeout=5.0)

    assert len(probe.blocks) == 50  # 1 s of 20-sample blocks (the scenario's block size)
    assert [b.first_sample_index for b in probe.blocks] == list(range(0, 1000, 20))
    assert all(b.sample_rate == 1000.0 and len(b.plunge) == 20 for b in probe.blocks)
    le = np.concatenate([b.leading_edge for b in probe.blocks])
    assert np.all(np.isfinite(le)) and np.std(le) > 0
    stamps = [c.clock.sec + 1e-9 * c.clock.nanosec for c in probe.clock]
    assert stamps == sorted(stamps) and stamps[-1] == pytest.approx(1.0)
    assert "flight completed" in probe.messages()
    assert sim.published["wing/acceleration"] == 50


@pytest.mark.parametrize("stepping", ["numpy", "compiled"])
def test_each_stepping_flies_the_runtime_s_flight_and_reports_its_time(
        executor, spin, ros_context, tmp_path, stepping):
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    probe = Probe(ros_context)
    scenario = _scenario(tmp_path, "{kind: ramp, start_ratio: 0.8, end_ratio: 0.9}")
    sim = _simulator(ros_context, tmp_path, scenario, stepping=stepping)
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=60.0)
    spin(executor, lambda: len(probe.displacements) >= 50, timeout=5.0)
    runtime = FlightRuntime(load_runtime_config({"scenario": scenario}),
                            compiled=stepping == "compiled")
    flown = np.concatenate([runtime.step().displacements for _ in range(50)], axis=1)
    got = np.array([np.concatenate([getattr(m, name) for m in probe.displacements])
                    for name in ("plunge", "pitch", "leading_edge", "absorber_stroke")])
    np.testing.assert_array_equal(got, flown)  # the runtime's own route, bit for bit
    report = sim._summary()
    assert report["stepping_wall_s"] > 0 and report["publishing_wall_s"] > 0
    assert report["stepping_wall_s"] + report["publishing_wall_s"] <= report["wall_time_s"]
    assert 0 < report["stepping_cpu_s"] <= report["process_cpu_s"]
    assert 0 < report["publishing_cpu_s"] <= report["process_cpu_s"]


def test_bad_commands_are_rejected_never_applied(executor, spin, ros_context, tmp_path):
    probe = Probe(ros_context)
    sim = _simulator(ros_context, tmp_path,
                     _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}", duration=2.0),
                     damper_timeout=10.0)
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, lambda: probe.commands.get_subscription_count() > 0, timeout=20.0)
    probe.commands.publish(DamperCommand(damping=700.0, source="test"))
    assert spin(executor, lambda: any(s.applied_damping == 700.0 for s in probe.states), 20.0)
    for bad in (math.nan, -5.0, math.inf, 1e9):
        probe.commands.publish(DamperCommand(damping=bad, source="bad"))
    assert spin(executor, lambda: len(probe.messages()) >= 4 and sim.finished.done(), 60.0)

    rejected = [m for m in probe.messages() if m.startswith("rejected damper command")]
    assert len(rejected) == 4, probe.messages()
    later = probe.states[-1]
    assert later.applied_damping == 700.0  # never replaced by a bad value
    assert any(s.status == DamperState.STATUS_REJECTED for s in probe.states)


def test_silent_controller_gets_the_fallback(executor, spin, ros_context, tmp_path):
    probe = Probe(ros_context)
    sim = _simulator(ros_context, tmp_path,
                     _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}", duration=1.0),
                     damper_timeout=0.2, damper_fallback=900.0, damper_initial=300.0)
    executor.add_node(probe.node)
    executor.add_node(sim)
    # One command at the start (before the flight starts), then the controller falls silent.
    assert spin(executor, lambda: probe.commands.get_subscription_count() > 0, timeout=20.0)
    probe.commands.publish(DamperCommand(damping=500.0, source="test"))
    assert spin(executor, sim.finished.done, timeout=60.0)
    spin(executor, lambda: len(probe.states) >= 50 and len(probe.messages()) >= 2, timeout=5.0)
    applied = [s.applied_damping for s in probe.states]
    assert 500.0 in applied and applied[-1] == 900.0
    stale = [s for s in probe.states if s.status == DamperState.STATUS_FALLBACK_STALE]
    assert stale and all(s.applied_damping == 900.0 for s in stale)
    accepted = next(s for s in probe.states if s.applied_damping == 500.0)
    first = stale[0].header.stamp.sec + 1e-9 * stale[0].header.stamp.nanosec
    since = accepted.header.stamp.sec + 1e-9 * accepted.header.stamp.nanosec
    assert 0.2 <= first - since + 0.02 <= 0.25  # stale 0.2 s after the command, per block
    assert any("fallback" in m for m in probe.messages())


def test_divergence_is_reported_not_crashed(executor, spin, ros_context, tmp_path):
    probe = Probe(ros_context)
    sim = _simulator(ros_context, tmp_path,
                     _scenario(tmp_path, "{kind: constant, value_ratio: 1.3}", duration=30.0),
                     absorber="none")
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=120.0)
    assert sim.finished.result() == "diverged"
    spin(executor, lambda: any("diverged" in m for m in probe.messages()), timeout=5.0)
    assert any("diverged" in m for m in probe.messages())
    assert len(probe.blocks) < 1500  # stopped long before the 30 s flight ended
    le = np.concatenate([b.leading_edge for b in probe.blocks])
    assert np.all(np.isfinite(le))


def test_paced_flight_keeps_its_real_time_factor(executor, spin, ros_context, tmp_path):
    # 1 s of flight at 4x real time takes at least 0.25 s of wall time, however the ticks come
    # (how much more depends on the machine's load, so it is not tested).
    probe = Probe(ros_context)
    scenario = _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}")
    sim = _simulator(ros_context, tmp_path, scenario, real_time_factor=4.0)
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=60.0)
    assert spin(executor, lambda: "flight completed" in probe.messages(), timeout=5.0)
    # The report can overtake the last blocks on their way to the probe: wait for them.
    assert spin(executor, lambda: len(probe.blocks) >= 50, timeout=5.0), len(probe.blocks)
    final = next(s for d in probe.diagnostics for s in d.status
                 if s.message == "flight completed")
    values = {kv.key: float(kv.value) for kv in final.values
              if kv.key in ("sim_time_s", "real_time_factor")}
    assert values["sim_time_s"] == pytest.approx(1.0)
    assert values["real_time_factor"] <= 4.0 * 1.05  # never faster than asked
    assert len(probe.blocks) == 50


def test_a_flight_ahead_of_its_controller_is_said_once_and_loudly(executor, spin, ros_context,
                                                                  tmp_path):
    """Without max_command_lag the flight runs free: a command for an input it flew past more
    than a block ago is said once (log and /diagnostics, WARN), however many follow."""
    probe = Probe(ros_context)
    sim = _simulator(ros_context, tmp_path,
                     _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}", duration=5.0),
                     real_time_factor=2.0, max_command_lag=0.0)
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, lambda: len(probe.blocks) >= 10, timeout=60.0)  # 0.2 s flown
    for _ in range(3):
        probe.commands.publish(DamperCommand(damping=600.0, source="test"))  # stamped t = 0
    assert spin(executor, lambda: sim.commands_received >= 3, timeout=30.0)
    assert spin(executor, lambda: any("FLYING AHEAD" in m for m in probe.messages()), 10.0)
    ahead = [m for m in probe.messages(level=DiagnosticStatus.WARN) if "FLYING AHEAD" in m]
    assert len(ahead) == 1 and sim.flew_ahead
    assert "a command for t = 0.000 s arrived at t = " in ahead[0]
    assert "max_command_lag 0 s, so the flight runs free" in ahead[0]


@pytest.mark.parametrize("word", ["its_report", "another_report", "none"])
def test_the_ended_flight_exits_on_its_recorders_word(executor, spin, ros_context, tmp_path,
                                                      monkeypatch, word):
    """With a recorder in the graph (a publisher on dva/recorded), the ended flight exits once
    the recorder says, stamped with the end-of-flight report's stamp, that it holds the flight;
    a word for another report, or none, is waited for until ACK_TIMEOUT (then said)."""
    from aero_dva.bag import channels as ch
    from aero_dva_sim import simulator_node
    from dva_ros_common.conversions import diagnostics

    # The word must end it: the wait would otherwise outlast the spin below.
    monkeypatch.setattr(simulator_node, "ACK_TIMEOUT", 600.0 if word == "its_report" else 1.0)
    probe = Probe(ros_context)
    recorder = Node("recorder", context=ros_context)
    said = recorder.create_publisher(DiagnosticArray, ch.RECORDED.name, 10)

    def answer(report: DiagnosticArray) -> None:
        if word == "none" or not any(s.name == ch.FLIGHT_DIAGNOSTIC_NAME for s in report.status):
            return
        stamp = report.header.stamp if word == "its_report" else 123.0
        said.publish(diagnostics(stamp, ch.RECORDED_NAME, "/recorder", [("ok", "held", {})]))

    recorder.create_subscription(DiagnosticArray, "/diagnostics", answer, 10)
    sim = _simulator(ros_context, tmp_path, _scenario(tmp_path, "{kind: constant, "
                                                      "value_ratio: 0.8}"))
    executor.add_node(probe.node)
    executor.add_node(recorder)
    # matched before the flight (started by adding the simulator) can end
    assert spin(executor, lambda: sim._recorded_sub.get_publisher_count() == 1, timeout=60.0)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=120.0)
    assert sim.finished.result() == "completed"
    assert sim._lingering["heard"] == ({"/recorder"} if word == "its_report" else set())
