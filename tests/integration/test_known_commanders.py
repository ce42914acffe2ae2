"""Known commanders: the simulator knows the controller its flight was started with; commands
from another node or of another source are counted, reported on /diagnostics and, with
strict_commands, refused; stamps ahead of sim time are rejected; a run_flight with a second
commander fails and says so."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from builtin_interfaces.msg import Time
from rclpy.node import Node

from dva_msgs.msg import DamperCommand

from .test_simulator_node import Probe, _scenario, _simulator

pytestmark = pytest.mark.ros

CONTROLLER, INTRUDER = 700.0, 2400.0


def _command(damping: float, source: str, stamp_s: float = 0.0) -> DamperCommand:
    msg = DamperCommand(damping=damping, source=source)
    msg.header.stamp = Time(sec=int(stamp_s), nanosec=int((stamp_s % 1) * 1e9))
    return msg


@pytest.mark.parametrize("strict", [True, False])
def test_a_second_commander_is_counted_reported_and_refused_when_strict(
        executor, spin, ros_context, tmp_path, strict):
    probe = Probe(ros_context)
    probe.node.destroy_publisher(probe.commands)  # the controller's node is the one commander
    controller = Node("fixed_controller", context=ros_context)
    ours = controller.create_publisher(DamperCommand, "dva/damper_command", 10)
    sim = _simulator(ros_context, tmp_path,
                     _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}", duration=3.0),
                     damper_timeout=10.0, controller="fixed", strict_commands=strict,
                     real_time_factor=1.0)
    for node in (probe.node, controller, sim):
        executor.add_node(node)
    assert spin(executor, lambda: ours.get_subscription_count() > 0, timeout=20.0)
    ours.publish(_command(CONTROLLER, "fixed"))
    assert spin(executor, lambda: any(s.applied_damping == CONTROLLER for s in probe.states),
                20.0)
    # a source the controller does not send, from the controller's own node
    ours.publish(_command(1234.0, "switching"))
    # a second node on the topic, sending the controller's own source
    intruder = Node("intruder", context=ros_context)
    theirs = intruder.create_publisher(DamperCommand, "dva/damper_command", 10)
    executor.add_node(intruder)
    assert spin(executor, lambda: theirs.get_subscription_count() > 0, timeout=20.0)
    theirs.publish(_command(INTRUDER, "fixed"))
    assert spin(executor, lambda: sim.commanders.foreign_nodes and sim.finished.done() and any(
        "node '" in m for m in probe.messages()) and (not strict or any(
            "flight stopped" in m for m in probe.messages())), 60.0)

    applied = {s.applied_damping for s in probe.states}
    assert (INTRUDER in applied) is not strict  # the last command: it holds to the end
    assert not strict or 1234.0 not in applied
    assert sim.finished.result() == ("failed" if strict else "completed")
    values = sim.commanders.values()
    assert "switching (1)" in values["foreign_sources"]
    # its node's name may reach the simulator's graph after its first message
    assert "intruder" in values["foreign_nodes"] or "unnamed publisher" in \
        values["foreign_nodes"]
    errors = [m for m in probe.messages() if "unexpected commander" in m]
    assert any("node 'intruder'" in m or "node 'unnamed publisher'" in m for m in errors), \
        probe.messages()
    if strict:
        assert any("a second commander" in m and "flight stopped" in m
                   for m in probe.messages()), probe.messages()
    assert any("source 'switching'" in m for m in errors)
    assert all(("refused (strict_commands)" in m) is strict for m in errors)


def test_stamps_ahead_of_sim_time_and_long_sources_are_handled(executor, spin, ros_context,
                                                               tmp_path):
    probe = Probe(ros_context)
    sim = _simulator(ros_context, tmp_path,
                     _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}", duration=2.0),
                     damper_timeout=10.0, real_time_factor=1.0)
    executor.add_node(probe.node)
    executor.add_node(sim)
    assert spin(executor, lambda: probe.commands.get_subscription_count() > 0, timeout=20.0)
    probe.commands.publish(_command(800.0, "test"))
    assert spin(executor, lambda: any(s.applied_damping == 800.0 for s in probe.states), 20.0)
    probe.commands.publish(_command(1500.0, "test", stamp_s=1.0e9))  # 30 years ahead
    probe.commands.publish(_command(float("nan"), "\x1b[31m" + "x" * 10_000_000))
    assert spin(executor, lambda: sim.finished.done(), 60.0)
    assert 1500.0 not in {s.applied_damping for s in probe.states}
    assert sim.rejected.get("stamp_ahead_of_sim_time") == 1
    text = next(m for m in probe.messages() if "not_a_number" in m)
    assert "\x1b" not in text and "\\x1b[31m" in text and len(text) < 400


@pytest.mark.parametrize("source", ["intruder", "fixed"])
def test_run_flight_with_a_second_commander_fails_and_says_so(executor, spin, ros_context,
                                                              ros_domain, tmp_path, source):
    """The issue's flight: a second node commands valid values beside the controller, under
    another source or under the controller's own ("fixed"). run_flight is strict by default:
    its c2 never reaches the damper, and the flight exits 1 saying so in its last line and in
    its summary."""
    from aero_dva.bag.reader import bag_topics, read_messages

    scenario = _scenario(tmp_path, "{kind: constant, value_ratio: 0.8}", duration=3.0,
                         block=50)
    intruder = Node("intruder", context=ros_context)
    publisher = intruder.create_publisher(DamperCommand, "dva/damper_command", 10)
    intruder.create_timer(0.02, lambda: publisher.publish(_command(INTRUDER, source)))
    executor.add_node(intruder)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    bag = tmp_path / "bag"
    process = subprocess.Popen(
        [sys.executable, "-m", "aero_dva_sim.run_flight", "--scenario", scenario,
         "--controller", "fixed", "--real-time-factor", "1", "--domain-id", str(ros_domain),
         "--output", str(bag), "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    assert spin(executor, lambda: process.poll() is not None, timeout=300.0)
    out, err = process.communicate()
    # 3: strict stopped the flight (the simulator failed it); 1: it flew, refusing the
    # commands of another source, and does not count as controlled
    assert process.returncode in (1, 3), err
    last = err.strip().splitlines()[-1]
    # strict (run_flight's default): the flight stops at the second commander's first command,
    # or, if its node was not yet matched, its commands (another source) are refused and the
    # flight fails on them at the end
    assert "a second commander" in last or (
        "unexpected commander" in last and "refused" in last), last
    summary = json.loads(out) if out.strip() else {}
    if "commands_foreign" in summary:  # the flight flew: its summary says it
        assert summary["commands_foreign"] > 0 and summary["strict_commands"] is True
        assert "unexpected commander" in summary["control_problem"]
    else:  # stopped: the JSON carries the one line
        assert "commander" in json.dumps(summary) or not summary, summary
    # (none when the flight stopped before the recorder kept a state)
    applied = [m.message.applied_damping for m in read_messages(
        bag, ["/dva/damper_state"], allow_truncated=True)] \
        if "/dva/damper_state" in bag_topics(bag) else []
    assert INTRUDER not in applied and all(0.0 <= c2 <= 2500.0 for c2 in applied)
