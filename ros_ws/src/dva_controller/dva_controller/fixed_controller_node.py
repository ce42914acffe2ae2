"""``fixed_controller``: publishes a constant damper command c2 (the fixed-c2 baseline of ch. 7).

Its parameters (units, defaults, ranges) are the table ``SPEC`` below, which the node declares
them from and ``fixed_controller --help`` prints.
"""
from __future__ import annotations

import math
import sys

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from aero_dva.bag import channels as ch
from dva_controller.shared_params import MAX_DAMPING
from dva_msgs.msg import DamperCommand
from dva_ros_common.conversions import damper_command
from dva_ros_common.held_publisher import HOLD_PARAM, HeldPublisher
from dva_ros_common.node_params import NodeSpec, Param, declare_parameters
from dva_ros_common.node_tools import run_node

SPEC = NodeSpec(
    name="fixed_controller",
    package="dva_controller",
    summary="Publish a constant damper command c2: the fixed-c2 baseline of chapter 7 of "
            "Zhang (2006).",
    params=(
        Param("damping", 1500.0, "c2 to command", "N s/m", 0.0, MAX_DAMPING, dynamic=True),
        Param("rate", 10.0, "publishing rate, in ROS time (sim time with use_sim_time)", "Hz",
              0.01, 1000.0),
        HOLD_PARAM,
    ),
    topics="publishes dva/damper_command (dva_msgs/DamperCommand, source \"fixed\")",
)


class FixedController(Node):
    """Publish a constant, validated c2 at a fixed rate."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        self._damping = self._checked_damping(values["damping"])
        rate = float(values["rate"])
        self._publisher = HeldPublisher(
            self, DamperCommand, ch.DAMPER_COMMAND.name, values["hold_until_subscribers"])
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.create_timer(1.0 / rate, self._publish)
        self.get_logger().info(f"commanding c2 = {self._damping:g} N s/m at {rate:g} Hz")

    @staticmethod
    def _checked_damping(value) -> float:
        value = float(value)
        if not math.isfinite(value) or not 0.0 <= value <= MAX_DAMPING:
            raise ValueError(
                f"parameter 'damping' must be in [0, {MAX_DAMPING:g}] N s/m, got {value}"
            )
        return value

    def _on_set_parameters(self, params) -> SetParametersResult:
        for param in params:
            if param.name == "damping":
                try:
                    self._damping = self._checked_damping(param.value)
                except (TypeError, ValueError) as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _publish(self) -> None:
        stamp = self.get_clock().now().to_msg()
        self._publisher.publish(damper_command(stamp, self._damping, DamperCommand.SOURCE_FIXED))


def main(args=None) -> int:
    return run_node(FixedController, SPEC, args)


if __name__ == "__main__":
    sys.exit(main())
