"""Conversions between dva_msgs / ROS messages and numpy values for the simulator (the only module
of this package, with the *_node.py files, that touches message classes)."""
from __future__ import annotations

from array import array

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock

from aero_dva.flight.damper import DamperSnapshot
from dva_msgs.msg import (
    AccelerationBlock,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)
from dva_ros_common.conversions import (
    LEVELS,
    diagnostic_array,
    diagnostic_status,
    seconds_to_time,
)


def _doubles(values: np.ndarray) -> array:
    # array.array is the fast path of the generated setters (no per-element checks).
    out = array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def clock(seconds: float) -> Clock:
    return Clock(clock=seconds_to_time(seconds))


def acceleration_block(t0: float, sample_rate: float, first_index: int,
                       accelerations: np.ndarray) -> AccelerationBlock:
    """``accelerations`` (3, n): plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2]."""
    msg = AccelerationBlock(sample_rate=float(sample_rate), first_sample_index=int(first_index))
    msg.header.stamp = seconds_to_time(t0)
    msg.header.frame_id = "wing"
    msg.plunge, msg.pitch, msg.leading_edge = (_doubles(row) for row in accelerations)
    return msg


def displacement_block(t0: float, sample_rate: float, first_index: int,
                       displacements: np.ndarray) -> DisplacementBlock:
    """``displacements`` (4, n): plunge [m], pitch [rad], leading edge [m], DVA stroke [m]."""
    msg = DisplacementBlock(sample_rate=float(sample_rate), first_sample_index=int(first_index))
    msg.header.stamp = seconds_to_time(t0)
    msg.header.frame_id = "wing"
    msg.plunge, msg.pitch, msg.leading_edge, msg.absorber_stroke = (
        _doubles(row) for row in displacements)
    return msg


def force_block(t0: float, sample_rate: float, first_index: int, force: np.ndarray) -> ForceBlock:
    msg = ForceBlock(sample_rate=float(sample_rate), first_sample_index=int(first_index))
    msg.header.stamp = seconds_to_time(t0)
    msg.aileron_force = _doubles(force)
    return msg


def flight_condition(t: float, airspeed: float, density: float) -> FlightCondition:
    msg = FlightCondition(airspeed=float(airspeed), air_density=float(density))
    msg.header.stamp = seconds_to_time(t)
    return msg


def damper_state(snapshot: DamperSnapshot) -> DamperState:
    msg = DamperState(
        commanded_damping=float(snapshot.commanded_damping),
        applied_damping=float(snapshot.applied_damping),
        min_damping=float(snapshot.min_damping),
        max_damping=float(snapshot.max_damping),
        command_age=float(snapshot.command_age),
        status=int(snapshot.status),
        source=snapshot.source,
    )
    msg.header.stamp = seconds_to_time(snapshot.time)
    return msg


def diagnostics(t: float, name: str, hardware_id: str,
                statuses: list[tuple[str, str, dict]]) -> DiagnosticArray:
    """A DiagnosticArray at sim time ``t``; ``statuses`` = [(level, message, values), ...]."""
    return diagnostic_array(seconds_to_time(t), [
        diagnostic_status(LEVELS[level], name, text, values, hardware_id)
        for level, text, values in statuses])
