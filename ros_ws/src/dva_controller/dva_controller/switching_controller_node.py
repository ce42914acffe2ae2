"""A per-sample law's supervisor (``switching_controller``, ``clipped_optimal_controller``).

A per-sample law (the switching c2 law, the clipped-optimal law) needs its loop at the damper's
sample rate (1 kHz), far faster than the graph's 50 ms blocks, so it runs inside the
simulator's damper path; this node only supervises it. Each command period it arms the law (a
command from the law's source, e.g. ``"switching"``, carrying the safe constant c2 the damper
holds if the law cannot run) or holds the safe c2 itself (its fallback source, e.g.
``"switching_fallback"``): on an invalid gains file (checked through
aero_dva.control.switching_io by the law's own loader, and made for the wing), or for
``rearm_after`` seconds after a burst (a leading-edge displacement beyond ``peak_limit``). Each
fallback is logged and published on /diagnostics with its reason. If this node falls silent,
the damper's stale-command timeout applies its fallback c2 and ends the law. The simulator
needs the same gains file (its parameter named by the law's table entry, e.g.
``switching_gains``).

One executable per per-sample law of the controller table (its entry's ``node``); the entry
gives its parameters (units, defaults, ranges), which the node declares and ``--help``
prints.
"""
from __future__ import annotations

import sys

from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva.control.controllers import controller
from aero_dva.control.switching_supervisor import SwitchingSupervisor
from dva_controller.switching_controller_spec import (  # noqa: F401  (SPEC: its users')
    ENTRY,
    SPEC,
    main,
    node_spec,
)
from dva_msgs.msg import DamperCommand, DamperState, DisplacementBlock
from dva_ros_common import conversions
from dva_ros_common.held_publisher import HeldPublisher
from dva_ros_common.node_params import declare_parameters


def gains_problem(entry, path: str, wing: str) -> str | None:
    """Why the gains file (empty: the law's package file) cannot be used for ``wing`` by the
    law of ``entry`` (its loader checks the design), or None."""
    from aero_dva.control.switching_io import gains_problem as problem
    from aero_dva.data_files import data_file

    default = next(o.default_file for o in entry.options if o.default_file)
    return problem(path or str(data_file(default)), wing or None,
                   lambda p: entry.make_law({"gains_file": str(p)}))


class Supervisor(Node):
    """Arm the damper's per-sample law ``name``, or hold the safe c2 and say why."""

    def __init__(self, name: str = ENTRY.name, **kwargs) -> None:
        self.entry = entry = controller(name)
        self.spec = node_spec(entry)
        super().__init__(self.spec.name, **kwargs)
        values = declare_parameters(self, self.spec)
        self.supervisor = SwitchingSupervisor(
            float(values["safe_damping"]), float(values["peak_limit"]),
            float(values["rearm_after"]),
            gains_problem(entry, values["gains_file"], values["wing"]),
            entry.source, entry.sources[0])
        self.reason: str | None = None  # why the law is not armed now (None: armed)
        self.fallbacks: list[str] = []  # every reason said, in order
        self.damper_mode: int | None = None  # the damper's mode in its last state
        self._publisher = HeldPublisher(
            self, DamperCommand, ch.DAMPER_COMMAND.name, values["hold_until_subscribers"])
        self._diag = self.create_publisher(conversions.message_class(ch.DIAGNOSTICS.type_name),
                                           ch.DIAGNOSTICS.name, 10)
        self.create_subscription(DisplacementBlock, ch.DISPLACEMENT.name, self._on_block, 50)
        self.create_subscription(DamperState, ch.DAMPER_STATE.name, self._on_state, 50)
        self.create_timer(1.0 / float(values["rate"]), self._publish)
        self._said(self.supervisor.command(0.0).reason, 0.0)
        self.get_logger().info(
            f"supervising the {entry.label}: safe c2 {self.supervisor.safe_damping:g} N s/m, "
            f"peak limit {self.supervisor.peak_limit:g} m")

    def _on_block(self, msg: DisplacementBlock) -> None:
        t0 = conversions.time_to_seconds(msg.header.stamp)
        if self.supervisor.observe(t0, msg.sample_rate, msg.leading_edge) is not None:
            self._publish()  # a burst disarms the law at once, not at the next period

    def _on_state(self, msg: DamperState) -> None:
        if msg.mode != self.damper_mode and msg.mode == DamperState.MODE_SWITCHING_REFUSED:
            self._diagnose(conversions.time_to_seconds(msg.header.stamp), "warn",
                           f"the damper refused the {self.entry.label} (see the simulator's "
                           f"diagnostics): it holds c2 = {msg.applied_damping:g} N s/m")
        self.damper_mode = msg.mode

    def _publish(self) -> None:
        now = self.get_clock().now()
        t = now.nanoseconds * 1e-9
        command = self.supervisor.command(t)
        self._said(command.reason, t)
        self._publisher.publish(conversions.damper_command(now.to_msg(), command.damping,
                                                           command.source))

    def _said(self, reason: str | None, t: float) -> None:
        """Log and publish each change of the reason the law is not armed."""
        if reason == self.reason:
            return
        if reason is None:
            self._diagnose(t, "ok", f"{self.entry.label} armed")
        else:
            said = (f"{reason} ({self.supervisor.last_burst})" if reason.startswith("burst")
                    else reason)
            self.fallbacks.append(said)
            self._diagnose(t, "warn", f"{self.entry.label} not armed: {said}; holding c2 = "
                           f"{self.supervisor.safe_damping:g} N s/m")
        self.reason = reason

    def _diagnose(self, t: float, level: str, text: str) -> None:
        # One call site per severity: rclpy refuses a severity change at the same call site.
        if level == "warn":
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)
        self._diag.publish(conversions.diagnostics(
            t, f"{self.spec.name}: law", self.spec.package, [(level, text, {
                "safe_damping": self.supervisor.safe_damping,
                "bursts": self.supervisor.bursts})]))


class SwitchingController(Supervisor):
    """The switching law's supervisor (``switching_controller``)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(ENTRY.name, **kwargs)


if __name__ == "__main__":
    sys.exit(main())
