"""The start of a lockstep flight: the simulator holds sim time until the graph is complete and
the first command has arrived, then flies block by block behind the controller; it fails, with
its reason on /diagnostics, when either never happens."""
from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter

from aero_dva_sim.simulator_node import Simulator
from dva_msgs.msg import AccelerationBlock, DamperCommand, FlightCondition

FIRST_ANSWER_DELAY = 0.5  # [s wall] the probe's silence before its first command
ERROR = b"\x02"


def _scenario(tmp_path, duration: float = 0.5) -> str:
    path = tmp_path / "scenario.yaml"
    path.write_text(f"name: test\nduration: {duration}\nblock_size: 50\n"
                    "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                    "excitation: {force_std: 1000.0, seed: 3}\n")
    return str(path)


class Controller:
    """Answers every flight condition with c2 = 10 U, the first one only after a pause; logs
    blocks and answers in the order they happen."""

    def __init__(self, context, answer: bool = True):
        self.node = Node("probe_controller", context=context)
        self.events: list[tuple[str, float]] = []  # (block, first sample) or (command, stamp)
        self.diagnostics: list = []
        self._answer = answer
        self._first_seen: float | None = None
        self._pending: list[FlightCondition] = []
        self.node.create_subscription(AccelerationBlock, "wing/acceleration", self._on_block, 100)
        self.node.create_subscription(FlightCondition, "flight/condition", self._on_condition,
                                      100)
        for topic in ("wing/displacement", "wing/excitation", "dva/damper_state"):
            self.node.create_subscription(_type(topic), topic, lambda _: None, 100)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append,
                                      100)
        self.commands = self.node.create_publisher(DamperCommand, "dva/damper_command", 10)
        self.node.create_timer(0.01, self._release)

    def _on_block(self, msg) -> None:
        self.events.append(("block", msg.first_sample_index))

    def _on_condition(self, msg) -> None:
        if self._answer:
            self._pending.append(msg)
            self._first_seen = self._first_seen or time.monotonic()
            self._release()

    def _release(self) -> None:
        if self._first_seen is None or time.monotonic() - self._first_seen < FIRST_ANSWER_DELAY:
            return
        for msg in self._pending:
            command = DamperCommand(damping=10.0 * msg.airspeed, source="probe")
            command.header.stamp = msg.header.stamp
            self.commands.publish(command)
            self.events.append(("command", msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9))
        self._pending.clear()

    def errors(self) -> list[str]:
        return [s.message for d in self.diagnostics for s in d.status if s.level == ERROR]


def _type(topic: str):
    from dva_msgs.msg import DamperState, DisplacementBlock, ForceBlock

    return {"wing/displacement": DisplacementBlock, "wing/excitation": ForceBlock,
            "dva/damper_state": DamperState}[topic]


def _simulator(context, scenario, **params):
    overrides = [Parameter("scenario", value=scenario), Parameter("real_time_factor", value=0.0),
                 Parameter("wait_for_subscribers", value=1),
                 Parameter("max_command_lag", value=0.05)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return Simulator(context=context, parameter_overrides=overrides)


def test_flight_holds_for_the_first_command_then_follows_the_controller(
        executor, spin, ros_context, tmp_path):
    controller = Controller(ros_context)
    sim = _simulator(ros_context, _scenario(tmp_path), wait_for_topics=["flight/condition:1"],
                     wait_for_command_publishers=1)
    executor.add_node(controller.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=60.0)
    assert sim.finished.result() == "completed" and sim.exit_code == 0
    spin(executor, lambda: len([e for e in controller.events if e[0] == "block"]) == 10,
         timeout=10.0)
    blocks = [t for kind, t in controller.events if kind == "block"]
    assert blocks == [50 * i for i in range(10)]  # sample indices
    # Lockstep from the first block on: the block after t is flown only once the command
    # answering the block at t was sent, though the first answer came 0.5 s of wall time late.
    # (A block's condition goes out as soon as the block before is stepped, so its answer may
    # come before the data of the block before: never before that block is flown.)
    at = {(kind, round(t, 6)): i for i, (kind, t) in enumerate(controller.events)}
    for k in range(9):
        assert at[("command", round(0.05 * k, 6))] < at[("block", 50 * (k + 1))], \
            controller.events
    applied = sim.runtime.applied
    assert (applied.blocks, applied.startup, applied.controlled, applied.fallback) == (10, 1, 9, 0)
    assert sim.commands_received == 9  # the answer to the last block comes after the flight


def test_flight_fails_when_the_controller_never_acts(executor, spin, ros_context, tmp_path):
    controller = Controller(ros_context, answer=False)
    sim = _simulator(ros_context, _scenario(tmp_path), first_command_timeout=0.5)
    executor.add_node(controller.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=60.0)
    assert sim.finished.result() == "failed" and sim.exit_code == 3  # could not fly: failed
    assert spin(executor, controller.errors, timeout=10.0)
    assert "the controller never acted" in controller.errors()[0]
    assert [kind for kind, _ in controller.events] == ["block"]  # held after the first block
    assert sim.runtime.applied.controlled == 0


def test_flight_fails_when_the_graph_stays_incomplete(executor, spin, ros_context, tmp_path):
    controller = Controller(ros_context)
    # two subscribers on flight/condition are awaited; only the probe is there
    sim = _simulator(ros_context, _scenario(tmp_path), wait_for_topics=["flight/condition:2"],
                     wait_timeout=0.5, wait_timeout_fails=True)
    executor.add_node(controller.node)
    executor.add_node(sim)
    assert spin(executor, sim.finished.done, timeout=60.0)
    assert sim.finished.result() == "failed" and sim.exit_code == 3  # could not fly: failed
    assert spin(executor, controller.errors, timeout=10.0)
    error = controller.errors()[0]
    assert "not complete" in error and "2 subscribers on flight/condition (1)" in error
    assert controller.events == [] and sim.runtime.applied.blocks == 0
