"""The batch encoder against ROS 2 itself: rclpy serialization, and DDS in both directions.

The messages are built by :mod:`aero_dva_sim.messages`, i.e. exactly as the simulator node
publishes them. ROS 2 (Fast CDR) leaves alignment padding uninitialised, so its bytes are
compared with ours where they carry data: equal length, equal bytes wherever ours are not
padding zeros, and equal bytes after decoding and re-encoding with mcap-ros2-support (which pads
with zeros). Each side also decodes the other's bytes to the same message.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from mcap.records import Schema
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock

from aero_dva.bag import cdr_encoding as cdr
from aero_dva.bag.mcap_io import message_definition
from aero_dva.flight.damper import DamperSnapshot, DamperStatus
from aero_dva_sim import messages
from dva_msgs.msg import (
    AccelerationBlock,
    DamperCommand,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)
from dva_ros_common import conversions

RNG = np.random.default_rng(5)


def _snapshot(status=DamperStatus.SATURATED, source="rbf_network") -> DamperSnapshot:
    return DamperSnapshot(time=12.35, commanded_damping=3100.0, applied_damping=2500.0,
                          min_damping=0.0, max_damping=2500.0, command_age=0.02,
                          status=status, source=source, rejection=None)


def _level(value) -> int:
    return value[0] if isinstance(value, bytes) else int(value)  # ``byte`` fields: bytes


def _cases():
    """(ROS message as the node builds it, our bytes) pairs."""
    cases = []
    for n in (1, 2, 3, 5, 50):
        acc, disp, force = RNG.standard_normal((3, n)), RNG.standard_normal((4, n)), \
            RNG.standard_normal(n)
        for t0 in (0.0, 0.3, 6839.95, 1234.5678901):
            index = int(t0 * 1000)
            cases += [
                (messages.acceleration_block(t0, 1000.0, index, acc),
                 cdr.encode_acceleration_block(t0, 1000.0, index, acc)),
                (messages.displacement_block(t0, 1000.0, index, disp),
                 cdr.encode_displacement_block(t0, 1000.0, index, disp)),
                (messages.force_block(t0, 1000.0, index, force),
                 cdr.encode_force_block(t0, 1000.0, index, force)),
            ]
    for t in (0.0, 0.05, 29.123456789):
        cases += [
            (messages.clock(t), cdr.encode_clock(t)),
            (messages.flight_condition(t, 97.5, 1.225), cdr.encode_flight_condition(
                t, 97.5, 1.225)),
        ]
    for status in DamperStatus:
        for source in ("", "initial", "fallback", "rbf_network", "airspeed_schedule"):
            state = _snapshot(status, source)
            cases.append((messages.damper_state(state), cdr.encode_damper_state(state)))
    nan_state = DamperSnapshot(time=0.0, commanded_damping=math.nan, applied_damping=500.0,
                               min_damping=0.0, max_damping=2500.0, command_age=math.inf,
                               status=DamperStatus.NO_COMMAND, source="initial", rejection=None)
    cases.append((messages.damper_state(nan_state), cdr.encode_damper_state(nan_state)))
    command = DamperCommand(damping=812.5, source=DamperCommand.SOURCE_RBF_NETWORK)
    command.header.stamp = Time(sec=3, nanosec=5)
    cases.append((command, cdr.encode_damper_command(3.000000005, 812.5, "rbf_network")))
    values = {"sim_time_s": 29.0, "wall_time_s": 0.123456789123, "real_time_factor": math.inf,
              "published:wing/acceleration": 580, "nan": math.nan}
    for statuses in ([], [("error", "wing diverged at U = 117.32 m/s", values)],
                     [("ok", "flight completed", {}), ("warn", "stale", {"a": 1})]):
        ros = messages.diagnostics(29.0, "simulator: flight", "aero_dva_sim", statuses)
        ours = cdr.encode_diagnostic_array(29.0, [
            (_level(conversions.LEVELS[level]), "simulator: flight", text,
             "aero_dva_sim", [(k, conversions._text(v)) for k, v in vals.items()])
            for level, text, vals in statuses])
        cases.append((ros, ours))
    return cases


CASES = _cases()
TYPE_NAMES = {AccelerationBlock: cdr.ACCELERATION_BLOCK, DisplacementBlock: cdr.DISPLACEMENT_BLOCK,
              ForceBlock: cdr.FORCE_BLOCK, FlightCondition: cdr.FLIGHT_CONDITION,
              DamperState: cdr.DAMPER_STATE, DamperCommand: cdr.DAMPER_COMMAND,
              Clock: cdr.CLOCK, DiagnosticArray: cdr.DIAGNOSTIC_ARRAY}


def _normalised(type_name: str, data: bytes) -> bytes:
    """Decode with mcap-ros2-support and encode again: the same values, zero padding."""
    definition = message_definition(type_name)
    schema = Schema(id=1, name=type_name, encoding="ros2msg", data=definition.encode())
    decoded = DecoderFactory().decoder_for("cdr", schema)(data)
    return serialize_dynamic(type_name, definition)[type_name](_as_dict(decoded))


def _as_dict(value):
    if hasattr(value, "__slots__") and not isinstance(value, (str, bytes)):
        return {name: _as_dict(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, list):
        return [_as_dict(v) for v in value]
    return value


def _check_against_ros(msg, ours: bytes, theirs: bytes) -> None:
    type_name = TYPE_NAMES[type(msg)]
    assert len(ours) == len(theirs), type_name
    differ = [i for i, (a, b) in enumerate(zip(ours, theirs, strict=True)) if a != b]
    assert all(ours[i] == 0 for i in differ), f"{type_name}: data bytes differ at {differ}"
    assert len(differ) <= 7 * (1 + ours.count(b"\0" * 4)), type_name
    assert _normalised(type_name, theirs) == ours
    back = deserialize_message(ours, type(msg))
    assert _normalised(type_name, serialize_message(back)) == ours
    if "nan" not in repr(msg):  # NaN != NaN in message equality
        assert back == msg


@pytest.mark.parametrize("case", range(len(CASES)))
def test_bytes_equal_rclpy_serialization(case):
    msg, ours = CASES[case]
    _check_against_ros(msg, ours, serialize_message(msg))


def test_empty_sequences_decode_in_ros():
    """Fast CDR sizes empty float64 sequences with padding; our shorter bytes still decode."""
    msg = messages.acceleration_block(1.0, 1000.0, 0, np.zeros((3, 0)))
    ours = cdr.encode_acceleration_block(1.0, 1000.0, 0, np.zeros((3, 0)))
    assert deserialize_message(ours, AccelerationBlock) == msg
    assert _normalised(cdr.ACCELERATION_BLOCK, serialize_message(msg)[:len(ours)]) == ours


def test_dds_carries_our_bytes_and_delivers_the_nodes(executor, spin, ros_context):
    """Our bytes published raw arrive as the node's message; the node's message received raw
    (what the mcap_recorder records) equals our bytes up to padding."""
    t0, index = 12.3, 12300
    acc = RNG.standard_normal((3, 50))
    expected = messages.acceleration_block(t0, 1000.0, index, acc)
    ours = cdr.encode_acceleration_block(t0, 1000.0, index, acc)
    sender = Node("sender", context=ros_context)
    receiver = Node("receiver", context=ros_context)
    typed, raw = [], []
    receiver.create_subscription(AccelerationBlock, "ours", typed.append, 10)
    receiver.create_subscription(AccelerationBlock, "theirs", raw.append, 10, raw=True)
    ours_pub = sender.create_publisher(AccelerationBlock, "ours", 10)
    theirs_pub = sender.create_publisher(AccelerationBlock, "theirs", 10)
    executor.add_node(sender)
    executor.add_node(receiver)

    def arrived() -> bool:
        if not typed:
            ours_pub.publish(ours)
        if not raw:
            theirs_pub.publish(expected)
        return bool(typed and raw)

    assert spin(executor, arrived, timeout=15.0), "nothing arrived over DDS"
    assert typed[0] == expected
    _check_against_ros(expected, ours, bytes(raw[0]))
