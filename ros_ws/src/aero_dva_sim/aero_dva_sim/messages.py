"""Conversions between dva_msgs / ROS messages and numpy values for the simulator (the only module
of this package, with the *_node.py files, that touches message classes)."""
from __future__ import annotations

import math
from array import array

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rosgraph_msgs.msg import Clock

from aero_dva_sim.damper import DamperSnapshot
from dva_msgs.msg import (
    AccelerationBlock,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)

DIAGNOSTIC_LEVELS = {"ok": DiagnosticStatus.OK, "warn": DiagnosticStatus.WARN,
                     "error": DiagnosticStatus.ERROR, "stale": DiagnosticStatus.STALE}


def to_time(seconds: float) -> Time:
    """ROS time of ``seconds`` [s] (sim time since the start of the flight), rounded to 1 ns."""
    nanoseconds = int(round(seconds * 1e9))
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def to_seconds(stamp: Time) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def _doubles(values: np.ndarray) -> array:
    # array.array is the fast path of the generated setters (no per-element checks).
    out = array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def clock(seconds: float) -> Clock:
    return Clock(clock=to_time(seconds))


def acceleration_block(t0: float, sample_rate: float, first_index: int,
                       accelerations: np.ndarray) -> AccelerationBlock:
    """``accelerations`` (3, n): plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2]."""
    msg = AccelerationBlock(sample_rate=float(sample_rate), first_sample_index=int(first_index))
    msg.header.stamp = to_time(t0)
    msg.header.frame_id = "wing"
    msg.plunge, msg.pitch, msg.leading_edge = (_doubles(row) for row in accelerations)
    return msg


def displacement_block(t0: float, sample_rate: float, first_index: int,
                       displacements: np.ndarray) -> DisplacementBlock:
    """``displacements`` (4, n): plunge [m], pitch [rad], leading edge [m], DVA stroke [m]."""
    msg = DisplacementBlock(sample_rate=float(sample_rate), first_sample_index=int(first_index))
    msg.header.stamp = to_time(t0)
    msg.header.frame_id = "wing"
    msg.plunge, msg.pitch, msg.leading_edge, msg.absorber_stroke = (
        _doubles(row) for row in displacements)
    return msg


def force_block(t0: float, sample_rate: float, first_index: int, force: np.ndarray) -> ForceBlock:
    msg = ForceBlock(sample_rate=float(sample_rate), first_sample_index=int(first_index))
    msg.header.stamp = to_time(t0)
    msg.aileron_force = _doubles(force)
    return msg


def flight_condition(t: float, airspeed: float, density: float) -> FlightCondition:
    msg = FlightCondition(airspeed=float(airspeed), air_density=float(density))
    msg.header.stamp = to_time(t)
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
    msg.header.stamp = to_time(snapshot.time)
    return msg


def diagnostics(t: float, name: str, hardware_id: str,
                statuses: list[tuple[str, str, dict]]) -> DiagnosticArray:
    """A DiagnosticArray at sim time ``t``; ``statuses`` = [(level, message, values), ...]."""
    msg = DiagnosticArray()
    msg.header.stamp = to_time(t)
    for level, text, values in statuses:
        msg.status.append(DiagnosticStatus(
            level=DIAGNOSTIC_LEVELS[level], name=name, message=text, hardware_id=hardware_id,
            values=[KeyValue(key=k, value=_text(v)) for k, v in values.items()]))
    return msg


def _text(value) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.9g}"
    return str(value)
