"""``fixed_controller``: publishes a constant damper command c2 (the fixed-c2 baseline of ch. 7).

Parameters
----------
damping : float, default 1500.0
    c2 [N s/m] to command; finite and >= 0. Can be changed at run time (``ros2 param set``).
rate : float, default 10.0
    Publishing rate [Hz] (in ROS time, so sim time when ``use_sim_time`` is true).

Publishes ``dva/damper_command`` (dva_msgs/DamperCommand, source "fixed").
"""
from __future__ import annotations

import math
import sys

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from aero_dva.bag import channels as ch
from dva_msgs.msg import DamperCommand
from dva_ros_common.conversions import damper_command
from dva_ros_common.node_tools import bounded, run_node

NODE_NAME = "fixed_controller"
MAX_DAMPING = 1.0e6  # [N s/m] far above any damper of this size class; larger is a unit error


class FixedController(Node):
    """Publish a constant, validated c2 at a fixed rate."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.declare_parameter(
            "damping", 1500.0, bounded("c2 to command [N s/m]", 0.0, MAX_DAMPING)
        )
        self.declare_parameter("rate", 10.0, bounded("publishing rate [Hz]", 0.01, 1000.0))
        self._damping = self._checked_damping(self.get_parameter("damping").value)
        rate = float(self.get_parameter("rate").value)
        self._publisher = self.create_publisher(DamperCommand, ch.DAMPER_COMMAND.name, 10)
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
            elif param.name == "rate":
                return SetParametersResult(successful=False, reason="'rate' is read at start-up")
        return SetParametersResult(successful=True)

    def _publish(self) -> None:
        stamp = self.get_clock().now().to_msg()
        self._publisher.publish(damper_command(stamp, self._damping, DamperCommand.SOURCE_FIXED))


def main(args=None) -> int:
    return run_node(FixedController, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
