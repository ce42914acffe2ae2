"""``controller``: the node that hosts any block-rate law of the controller table, by name.

    ros2 run dva_controller controller NAME [--ros-args -p PARAM:=VALUE ...]
    ros2 run dva_controller rbf_controller [--ros-args ...]    (an alias: the law of that node)

The law, its parameters, what it reads and the source of its commands are its entry in
:mod:`aero_dva.control.controllers` (the project's own, or a package's registered through the
entry-point group ``aero_dva.controllers``); the project's block-rate laws keep their
executables (``fixed_controller``, ``airspeed_controller``, ``rbf_controller``) as aliases of
this one. The node declares the law's parameters, then its own (input health, the hold gate);
``--help`` prints them. It builds the law (a bad parameter or file stops it with a one-line
error, exit code 2), subscribes to what the law reads (``flight/condition``, ``dva/spectrum``)
or ticks its timer at the law's ``rate`` (ROS time: sim time with use_sim_time), and publishes
each command the law gives on ``dva/damper_command`` with the entry's source and the stamp of the
input it answers (the DamperCommand convention; a tick's is the node's time). An input the law
rejects gives no command: it is counted and reported on ``/diagnostics``.
"""
from __future__ import annotations

import dataclasses
import math
import sys
from functools import partial

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva.control import controllers as table
from aero_dva.control.controllers import (
    BLOCK,
    CONDITION,
    SPECTRUM,
    TICK,
    Condition,
    LawStep,
)
from dva_controller.controller_spec import main, node_spec
from dva_msgs.msg import DamperCommand, FlightCondition, ScaledSpectrum
from dva_ros_common import conversions
from dva_ros_common.held_publisher import HeldPublisher
from dva_ros_common.node_params import DATA_DEPTH, declare_parameters
from dva_ros_common.node_tools import InputHealth, Status


def _condition(msg: FlightCondition) -> tuple[int, Condition]:
    values = conversions.flight_condition_values(msg)
    return values.stamp_ns, Condition(values.airspeed, values.air_density)


def _spectrum(msg: ScaledSpectrum):
    spectrum = conversions.spectrum_input(msg)  # ValueError: malformed
    return spectrum.stamp_ns, spectrum


@dataclasses.dataclass(frozen=True)
class TopicInput:
    """How the node reads one kind of input: the message, what it counts and how it reports a
    rejected one, and how a message becomes the law's value."""

    message: type
    counted: str
    event: str
    what: str
    read: object


TOPIC_INPUTS = {  # the kinds of controller_spec.TOPIC_KINDS
    CONDITION: TopicInput(FlightCondition, "conditions", "rejected_airspeed", "flight condition",
                          _condition),
    SPECTRUM: TopicInput(ScaledSpectrum, "spectra", "rejected_spectrum", "spectrum", _spectrum),
}
LEVELS = {"ok": conversions.OK, "warn": conversions.WARN, "error": conversions.ERROR}


class ControllerNode(Node):
    """Run ``law``'s entry of the controller table (module docstring)."""

    def __init__(self, law: str, **kwargs) -> None:
        self.entry = table.controller(law)
        if self.entry.runs != BLOCK:
            raise ValueError(f"controller {law!r} runs {self.entry.runs}-wise, not in a "
                             "controller node")
        spec = node_spec(self.entry)
        super().__init__(spec.name, **kwargs)
        values = declare_parameters(self, spec)
        self.law = self.entry.make_law({p.name: values[p.name] for p in self.entry.params})
        topics = [k for k in self.entry.inputs if k in TOPIC_INPUTS]
        self.counts = {TOPIC_INPUTS[k].counted: 0 for k in topics}
        self.counts.update(rejected=0, commands=0)
        self.counts.update(dict.fromkeys(getattr(self.law, "counters", ()), 0))
        self.last_command = math.nan
        self._publisher = HeldPublisher(self, DamperCommand, ch.DAMPER_COMMAND.name,
                                        values["hold_until_subscribers"])
        self._health = None
        if topics:
            self._health = InputHealth(self, self.entry.label.lower(),
                                       ch.LAW_INPUTS[topics[0]].name, self.counts, self._status)
        for kind in topics:
            # DATA_DEPTH: a starved node loses none of its inputs (KEEP_LAST overwrites)
            self.create_subscription(TOPIC_INPUTS[kind].message, ch.LAW_INPUTS[kind].name,
                                     partial(self._on_message, kind), DATA_DEPTH)
        if TICK in self.entry.inputs:
            self.create_timer(1.0 / float(values["rate"]), self._on_tick)
        if any(p.dynamic for p in self.entry.params):
            self.add_on_set_parameters_callback(self._on_set_parameters)
        describe = getattr(self.law, "describe", None)
        if describe is not None:
            self.get_logger().info(describe())

    def taken(self) -> int:
        """Inputs read from topics so far."""
        return sum(self.counts[TOPIC_INPUTS[k].counted] for k in self.entry.inputs
                   if k in TOPIC_INPUTS)

    def _on_message(self, kind: str, msg) -> None:
        source = TOPIC_INPUTS[kind]
        self.counts[source.counted] += 1
        self._health.mark_input()
        try:
            stamp_ns, value = source.read(msg)
        except ValueError as exc:
            step, stamp_ns = LawStep("rejected", reason=str(exc)), 0
        else:
            step = self.law.answer(kind, stamp_ns, value)
        self._take(step, stamp_ns, source)

    def _on_tick(self) -> None:
        now = self.get_clock().now().nanoseconds
        self._take(self.law.answer(TICK, now, None), now, None)

    def _take(self, step: LawStep, stamp_ns: int, source: TopicInput | None) -> None:
        for name in step.counted:
            self.counts[name] = self.counts.get(name, 0) + 1
        if step.kind == "rejected":
            self.counts["rejected"] += 1
            if self._health is not None:
                self._health.report(conversions.WARN, source.event,
                                    f"{source.what} ignored: {step.reason}", **step.values)
            else:
                self.get_logger().warning(f"no command: {step.reason}")
            return
        if step.kind != "command":
            if step.kind:
                self.counts[step.kind] = self.counts.get(step.kind, 0) + 1
            return
        self._publisher.publish(conversions.damper_command(
            conversions.ns_to_time(stamp_ns), step.damping, self.entry.source))
        self.last_command = step.damping
        self.counts["commands"] += 1

    def _on_set_parameters(self, params) -> SetParametersResult:
        for p in params:
            if any(row.name == p.name and row.dynamic for row in self.entry.params):
                try:
                    self.law.set(p.name, p.value)
                except (TypeError, ValueError) as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _status(self) -> Status:
        status = getattr(self.law, "status", None)
        if status is not None:
            level, text, values = status(self.last_command)
            return LEVELS[level], text, values
        return (conversions.OK, f"last command {self.last_command:.6g} N s/m",
                {"last_command": self.last_command})


def law_node(name: str) -> type:
    """A :class:`ControllerNode` class bound to the law ``name`` (built as rclpy builds nodes,
    ``law_node("rbf")(context=..., parameter_overrides=...)``), with its ``SPEC``."""
    entry = table.controller(name)

    def __init__(self, **kwargs):
        ControllerNode.__init__(self, name, **kwargs)

    return type(f"{entry.name.title()}Controller", (ControllerNode,),
                {"__init__": __init__, "SPEC": node_spec(entry)})


if __name__ == "__main__":
    sys.exit(main())
