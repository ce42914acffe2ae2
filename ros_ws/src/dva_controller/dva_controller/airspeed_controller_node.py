"""``airspeed_controller``: c2 from the measured airspeed, ``c2 = a0 + a1 U`` (study eq. 7.1).

One ``dva/damper_command`` (source "airspeed_schedule") per accepted ``flight/condition``
message, at most one per ``min_period`` of ROS time. The command is clamped to the damper's
range ``[damping_min, damping_max]`` (and, with a schedule file, to the file's range as well).
An airspeed that is NaN, infinite, negative or above ``max_airspeed`` is ignored and reported
on ``/diagnostics``; it never becomes a command.

Its parameters (units, defaults, ranges) are the table ``SPEC`` below, which the node declares
them from and ``airspeed_controller --help`` prints. The default a0, a1 are the example of
:mod:`aero_dva.control.schedule_io`, not a fit to any wing: fit one offline
(``dva control schedule``) and pass it as ``schedule_file``.

Subscribes ``flight/condition`` (dva_msgs/FlightCondition); publishes ``dva/damper_command``
(dva_msgs/DamperCommand) and ``/diagnostics``. A command carries the stamp of the flight
condition it was computed from (the DamperCommand convention), so whoever applies it can tell
the sample-to-command latency.
"""
from __future__ import annotations

import math
import sys

from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.command_laws import ScheduleLaw
from aero_dva.control.schedule_io import load_schedule
from dva_controller.shared_params import DAMPER_RANGE, damping_range
from dva_msgs.msg import DamperCommand, FlightCondition
from dva_ros_common import conversions
from dva_ros_common.held_publisher import HOLD_PARAM, HeldPublisher
from dva_ros_common.node_params import NodeSpec, Param, declare_parameters
from dva_ros_common.node_tools import INPUT_HEALTH_PARAMS, InputHealth, Status, run_node

SPEC = NodeSpec(
    name="airspeed_controller",
    package="dva_controller",
    summary="Command c2 from the measured airspeed with the linear schedule c2 = a0 + a1 U "
            "(eq. 7.1 of Zhang (2006)): one command per accepted flight condition, clamped to "
            "the damper's range. NaN, infinite, negative or too large airspeeds are ignored "
            "and reported on /diagnostics.",
    params=(
        Param("a0", -2150.0, "eq. 7.1 intercept (used when schedule_file is empty)", "N s/m",
              -1.0e6, 1.0e6),
        Param("a1", 31.5, "eq. 7.1 slope (used when schedule_file is empty)", "N s^2/m^2",
              -1.0e5, 1.0e5),
        Param("schedule_file", "", "JSON airspeed schedule (dva control schedule); when set, "
              "its a0, a1 and ranges replace the parameters", default_text="'' (use a0, a1)"),
        Param("extrapolate", True, "continue the schedule file's line outside its fitted "
              "airspeeds (false: hold the end values)"),
        *DAMPER_RANGE,
        Param("min_period", 0.0, "least ROS time between two commands (0: one per flight "
              "condition)", "s", 0.0, 3600.0),
        Param("max_airspeed", 400.0, "larger airspeeds are treated as sensor or unit errors "
              "and ignored", "m/s", 1.0, 1.0e4),
        *INPUT_HEALTH_PARAMS,
        HOLD_PARAM,
    ),
    topics="""
subscribes flight/condition (dva_msgs/FlightCondition)
publishes dva/damper_command (dva_msgs/DamperCommand, source "airspeed_schedule"), /diagnostics
""",
)


class AirspeedController(Node):
    """Command c2 from the airspeed with the linear schedule of eq. 7.1."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        low, high = damping_range(float(values["damping_min"]), float(values["damping_max"]))
        self.max_airspeed = float(values["max_airspeed"])
        self.extrapolate = bool(values["extrapolate"])
        path = str(values["schedule_file"])
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
                a0=float(values["a0"]),
                a1=float(values["a1"]),
                airspeed_range=(0.0, self.max_airspeed),
                damping_range=(low, high),
            )
            origin = "parameters a0, a1"
        self.damping_range = (low, high)
        self.law = ScheduleLaw(self.schedule, self.damping_range, self.extrapolate,
                               self.max_airspeed, round(float(values["min_period"]) * 1e9))

        self.counts = dict.fromkeys(("conditions", "rejected", "commands", "rate_limited"), 0)
        self.last_command = math.nan
        self._health = InputHealth(
            self, "airspeed schedule", ch.FLIGHT_CONDITION.name, self.counts, self._status
        )

        self._command_pub = HeldPublisher(
            self, DamperCommand, ch.DAMPER_COMMAND.name, values["hold_until_subscribers"])
        self.create_subscription(FlightCondition, ch.FLIGHT_CONDITION.name, self._on_condition, 10)
        self.get_logger().info(
            f"c2 = {self.schedule.a0:g} + {self.schedule.a1:g} U N s/m ({origin}), "
            f"clamped to [{low:g}, {high:g}] N s/m"
        )

    def command_for(self, airspeed: float) -> float:
        """[N s/m] the clamped eq. 7.1 command at a valid airspeed [m/s]."""
        return self.law.command_for(airspeed)

    def _on_condition(self, msg: FlightCondition) -> None:
        self.counts["conditions"] += 1
        self._health.mark_input()
        condition = conversions.flight_condition_values(msg)
        result = self.law.step(condition.stamp_ns, condition.airspeed)
        if result.kind == "rejected":
            self.counts["rejected"] += 1
            self._health.report(conversions.WARN, "rejected_airspeed",
                                f"flight condition ignored: {result.reason}",
                                airspeed=condition.airspeed, stamp_ns=condition.stamp_ns)
            return
        if result.kind == "rate_limited":
            self.counts["rate_limited"] += 1
            return
        self._command_pub.publish(
            conversions.damper_command(conversions.ns_to_time(condition.stamp_ns), result.damping,
                                    DamperCommand.SOURCE_AIRSPEED_SCHEDULE))
        self.last_command = result.damping
        self.counts["commands"] += 1

    def _status(self) -> Status:
        text = f"last command {self.last_command:.6g} N s/m"
        return conversions.OK, text, {"last_command": self.last_command}


def main(args=None) -> int:
    return run_node(AirspeedController, SPEC, args)


if __name__ == "__main__":
    sys.exit(main())
