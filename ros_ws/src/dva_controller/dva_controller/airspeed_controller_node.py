"""``airspeed_controller``: c2 from the measured airspeed, ``c2 = a0 + a1 U`` (seed eq. 7.1).

One ``dva/damper_command`` (source "airspeed_schedule") per accepted ``flight/condition``
message, at most one per ``min_period`` of ROS time. The command is clamped to the damper's
range ``[damping_min, damping_max]`` (and, with a schedule file, to the file's range as well).
An airspeed that is NaN, infinite, negative or above ``max_airspeed`` is ignored and reported
on ``/diagnostics``; it never becomes a command.

Parameters
----------
a0 : float, default -2150.0
    [N s/m] intercept of eq. 7.1 (used when ``schedule_file`` is empty). The defaults are the
    example of :mod:`aero_dva.control.schedule_io`, not a fit to any wing: fit one offline.
a1 : float, default 31.5
    [N s^2/m^2] slope of eq. 7.1 (used when ``schedule_file`` is empty).
schedule_file : str, default ""
    JSON schedule (:func:`aero_dva.control.schedule_io.load_schedule`); when set, its a0, a1 and
    ranges replace the parameters above.
extrapolate : bool, default true
    Continue the line outside the schedule file's fitted airspeed range (the seed's use);
    false holds the end values. Without a file the line is used at every accepted airspeed.
damping_min, damping_max : float, default 0.0, 2500.0
    [N s/m] range of the damper (the simulator's default range).
min_period : float, default 0.0
    [s] least ROS time between two commands (0: one command per flight condition).
max_airspeed : float, default 400.0
    [m/s] larger airspeeds are treated as sensor or unit errors and ignored.
stale_timeout : float, default 1.0
    [s] ROS time without a flight condition after which the periodic status turns WARN.
diagnostic_period : float, default 1.0
    [s] ROS time between periodic status reports on ``/diagnostics``.

Subscribes ``flight/condition`` (dva_msgs/FlightCondition); publishes ``dva/damper_command``
(dva_msgs/DamperCommand) and ``/diagnostics``. A command carries the stamp of the flight
condition it was computed from (the DamperCommand convention), so whoever applies it can tell
the sample-to-command latency.
"""
from __future__ import annotations

import math
import sys

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.schedule_io import load_schedule
from dva_msgs.msg import DamperCommand, FlightCondition
from dva_ros_common import conversions
from dva_ros_common.node_tools import InputHealth, Status, bounded, refuse_changes, run_node

NODE_NAME = "airspeed_controller"
MAX_DAMPING = 1.0e6  # [N s/m] far above any damper of this size class; larger is a unit error
_READ_AT_START = (
    "a0",
    "a1",
    "schedule_file",
    "extrapolate",
    "damping_min",
    "damping_max",
    "min_period",
    "max_airspeed",
    "stale_timeout",
    "diagnostic_period",
)


def damping_range(low: float, high: float) -> tuple[float, float]:
    """Validate the ``damping_min``/``damping_max`` pair."""
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 <= low < high):
        raise ValueError(
            f"parameters 'damping_min' and 'damping_max' must satisfy 0 <= min < max, "
            f"got {low}, {high} N s/m"
        )
    return low, high


class AirspeedController(Node):
    """Command c2 from the airspeed with the linear schedule of eq. 7.1."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.declare_parameter("a0", -2150.0, bounded("eq. 7.1 intercept [N s/m]", -1e6, 1e6))
        self.declare_parameter("a1", 31.5, bounded("eq. 7.1 slope [N s^2/m^2]", -1e5, 1e5))
        self.declare_parameter(
            "schedule_file",
            "",
            ParameterDescriptor(description="JSON airspeed schedule; replaces a0/a1 when set"),
        )
        self.declare_parameter(
            "extrapolate",
            True,
            ParameterDescriptor(description="extend the schedule file's line beyond its range"),
        )
        self.declare_parameter(
            "damping_min", 0.0, bounded("damper range, lower end [N s/m]", 0.0, MAX_DAMPING)
        )
        self.declare_parameter(
            "damping_max", 2500.0, bounded("damper range, upper end [N s/m]", 0.0, MAX_DAMPING)
        )
        self.declare_parameter(
            "min_period", 0.0, bounded("least ROS time between commands [s]", 0.0, 3600.0)
        )
        self.declare_parameter(
            "max_airspeed", 400.0, bounded("larger airspeeds are rejected [m/s]", 1.0, 1.0e4)
        )
        low, high = damping_range(
            float(self.get_parameter("damping_min").value),
            float(self.get_parameter("damping_max").value),
        )
        self.max_airspeed = float(self.get_parameter("max_airspeed").value)
        self.extrapolate = bool(self.get_parameter("extrapolate").value)
        path = str(self.get_parameter("schedule_file").value)
        if path:
            self.schedule = load_schedule(path)  # ScheduleFileError (a ValueError) names the file
            file_low, file_high = self.schedule.damping_range
            low, high = max(low, file_low), min(high, file_high)
            if low > high:
                raise ValueError(
                    f"airspeed schedule {path!r}: its damping range {self.schedule.damping_range} "
                    "N s/m does not overlap the damper range of 'damping_min'/'damping_max'"
                )
            origin = f"schedule file {path}"
        else:
            self.schedule = AirspeedSchedule(
                a0=float(self.get_parameter("a0").value),
                a1=float(self.get_parameter("a1").value),
                airspeed_range=(0.0, self.max_airspeed),
                damping_range=(low, high),
            )
            origin = "parameters a0, a1"
        self.damping_range = (low, high)
        self._min_period_ns = round(float(self.get_parameter("min_period").value) * 1e9)

        self.counts = dict.fromkeys(("conditions", "rejected", "commands", "rate_limited"), 0)
        self.last_command = math.nan
        self._last_command_ns: int | None = None
        self._health = InputHealth(
            self, "airspeed schedule", ch.FLIGHT_CONDITION.name, self.counts, self._status
        )

        self._command_pub = self.create_publisher(DamperCommand, ch.DAMPER_COMMAND.name, 10)
        self.create_subscription(FlightCondition, ch.FLIGHT_CONDITION.name, self._on_condition, 10)
        refuse_changes(self, _READ_AT_START)
        self.get_logger().info(
            f"c2 = {self.schedule.a0:g} + {self.schedule.a1:g} U N s/m ({origin}), "
            f"clamped to [{low:g}, {high:g}] N s/m"
        )

    def command_for(self, airspeed: float) -> float:
        """[N s/m] the clamped eq. 7.1 command at a valid airspeed [m/s]."""
        c2 = self.schedule.evaluate(airspeed, extrapolate=self.extrapolate)
        return min(max(c2, self.damping_range[0]), self.damping_range[1])

    def _on_condition(self, msg: FlightCondition) -> None:
        self.counts["conditions"] += 1
        self._health.mark_input()
        condition = conversions.flight_condition_values(msg)
        u = condition.airspeed
        if not (math.isfinite(u) and 0.0 <= u <= self.max_airspeed):
            self.counts["rejected"] += 1
            self._health.report(
                conversions.WARN,
                "rejected_airspeed",
                f"flight condition ignored: airspeed {u} m/s is not in [0, "
                f"{self.max_airspeed:g}] m/s",
                airspeed=u,
                stamp_ns=condition.stamp_ns,
            )
            return
        stamp_ns = condition.stamp_ns
        last = self._last_command_ns
        if last is not None and 0 <= stamp_ns - last < self._min_period_ns:
            self.counts["rate_limited"] += 1
            return
        c2 = self.command_for(u)
        self._command_pub.publish(
            conversions.damper_command(
                conversions.ns_to_time(stamp_ns), c2, DamperCommand.SOURCE_AIRSPEED_SCHEDULE
            )
        )
        self._last_command_ns = stamp_ns
        self.last_command = c2
        self.counts["commands"] += 1

    def _status(self) -> Status:
        text = f"last command {self.last_command:.6g} N s/m"
        return conversions.OK, text, {"last_command": self.last_command}


def main(args=None) -> int:
    return run_node(AirspeedController, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
