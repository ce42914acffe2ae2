"""The batch recorder against ROS 2 itself: rclpy serialization, and DDS in both directions.

Blocks are recorded through :class:`~aero_dva.bag.batch_recorder.BatchRecorder` and read back
raw; the same blocks are built as ROS messages by ``dva_ros_common.conversions``, i.e. exactly
as the simulator node publishes them. ROS 2 (Fast CDR) leaves alignment padding
uninitialised, so its bytes are compared with ours where they carry data: equal length, equal
bytes wherever ours are not padding zeros, and equal bytes after decoding and re-encoding with
rosbags (which pads with zeros). Each side also decodes the other's bytes to the same message.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message

from aero_dva.bag import channels as ch
from aero_dva.bag.batch_cdr import cdr_layout, sample_fields
from aero_dva.bag.batch_recorder import BatchRecorder
from aero_dva.bag.reader import read_messages
from aero_dva.bag.schemas import typestore
from aero_dva.flight.damper import DamperSnapshot, DamperStatus
from aero_dva.flight.samples import FlightSamples
from dva_msgs.msg import AccelerationBlock
from dva_ros_common import conversions

pytestmark = pytest.mark.ros

RATE = 1000.0
STORE = typestore()


def _flight():
    """Blocks of several lengths and start times, snapshots of every status and source."""
    rng = np.random.default_rng(5)
    blocks, states = [], []
    index = 0
    sources = ["", "initial", "fallback", "rbf_network", "airspeed_schedule"]
    for k, n in enumerate([1, 2, 3, 5, 50, 50, 7, 50]):
        for shift in (0, 1234567):  # [samples]: late blocks' stamps, 1234.567 s on
            block = FlightSamples(
                first_index=index + shift, sample_rate=RATE, force=rng.standard_normal(n),
                airspeed=np.full(n, 97.5 + k), density=np.full(n, 1.225),
                damping=np.full(n, 300.0), displacements=rng.standard_normal((4, n)),
                accelerations=rng.standard_normal((3, n)), diverged=False)
            blocks.append(block)
            t0 = block.t0
            status = list(DamperStatus)[len(states) % len(DamperStatus)]
            states.append(DamperSnapshot(
                time=t0 + 0.02, commanded_damping=math.nan if k == 0 else 3100.0,
                applied_damping=2500.0, min_damping=0.0, max_damping=2500.0,
                command_age=math.inf if k == 0 else 0.02, status=status,
                source=sources[len(states) % len(sources)], rejection=None))
            index += n
    return blocks, states


DIAGNOSTICS = [
    [("error", "wing diverged at U = 117.32 m/s",
      {"sim_time_s": 29.0, "wall_time_s": 0.123456789123, "real_time_factor": math.inf,
       "published:wing/acceleration": 580, "nan": math.nan})],
    [("ok", "flight completed", {}), ("warn", "stale", {"a": 1})],
]


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    """(ROS message as the node builds it, our bytes) pairs."""
    blocks, states = _flight()
    bag = tmp_path_factory.mktemp("ros") / "bag"
    with BatchRecorder(bag, RATE) as recorder:
        recorder.write_blocks(blocks, states)
        for k, statuses in enumerate(DIAGNOSTICS):
            recorder.write_diagnostics(29.0 + k, statuses)
    ours: dict[str, list[bytes]] = {}
    for record in read_messages(bag, decode=False, log_time_order=False):
        ours.setdefault(record.topic, []).append(record.message)
    expected = {name: [] for name in ours}
    for block, state in zip(blocks, states, strict=True):
        t0, i0 = block.t0, block.first_index
        expected[ch.CLOCK.absolute()].append(conversions.clock(block.t_end))
        expected[ch.ACCELERATION.absolute()].append(
            conversions.acceleration_block(t0, RATE, i0, block.accelerations))
        expected[ch.DISPLACEMENT.absolute()].append(
            conversions.displacement_block(t0, RATE, i0, block.displacements))
        expected[ch.EXCITATION.absolute()].append(
            conversions.force_block(t0, RATE, i0, block.force))
        expected[ch.FLIGHT_CONDITION.absolute()].append(
            conversions.flight_condition(t0, block.airspeed[0], block.density[0]))
        expected[ch.DAMPER_STATE.absolute()].append(conversions.damper_state(state))
    for k, statuses in enumerate(DIAGNOSTICS):
        expected[ch.DIAGNOSTICS.absolute()].append(conversions.diagnostics(
            29.0 + k, ch.FLIGHT_DIAGNOSTIC_NAME, ch.SIMULATOR_HARDWARE_ID, statuses))
    assert {t: len(v) for t, v in ours.items()} == {t: len(v) for t, v in expected.items()}
    return [(msg, data, topic) for topic in ours
            for msg, data in zip(expected[topic], ours[topic], strict=True)]


def _type_name(msg) -> str:
    module = type(msg).__module__.split(".")[0]
    return f"{module}/msg/{type(msg).__name__}"


def _normalised(type_name: str, data: bytes) -> bytes:
    """Decode with rosbags and encode again: the same values, zero padding."""
    return bytes(STORE.serialize_cdr(STORE.deserialize_cdr(data, type_name), type_name))


def _check_against_ros(msg, ours: bytes, theirs: bytes) -> None:
    type_name = _type_name(msg)
    assert len(ours) == len(theirs), type_name
    differ = [i for i, (a, b) in enumerate(zip(ours, theirs, strict=True)) if a != b]
    assert all(ours[i] == 0 for i in differ), f"{type_name}: data bytes differ at {differ}"
    assert len(differ) <= 7 * (1 + ours.count(b"\0" * 4)), type_name
    assert _normalised(type_name, theirs) == ours
    back = deserialize_message(ours, type(msg))
    assert _normalised(type_name, serialize_message(back)) == ours
    if "nan" not in repr(msg):  # NaN != NaN in message equality
        assert back == msg


def test_every_recorded_message_equals_rclpy_serialization(cases):
    assert len(cases) == 6 * 16 + 2
    for msg, ours, topic in cases:
        try:
            _check_against_ros(msg, ours, serialize_message(msg))
        except AssertionError as exc:
            raise AssertionError(f"{topic}: {exc}") from None


def test_empty_sequences_decode_in_ros():
    """Fast CDR sizes empty float64 sequences with padding; our shorter bytes still decode."""
    msg = conversions.acceleration_block(1.0, RATE, 0, np.zeros((3, 0)))
    fields = sample_fields(ch.ACCELERATION.type_name)
    row = cdr_layout(ch.ACCELERATION.type_name, dict.fromkeys(fields, 0),
                     {"header.frame_id": ch.WING_FRAME}).batch(1)
    row["header.stamp.sec"], row["sample_rate"] = 1, RATE
    ours = row.tobytes()
    assert deserialize_message(ours, AccelerationBlock) == msg
    assert _normalised(ch.ACCELERATION.type_name, serialize_message(msg)[:len(ours)]) == ours


def test_dds_carries_our_bytes_and_delivers_the_nodes(cases, executor, spin, ros_context):
    """Our bytes published raw arrive as the node's message; the node's message received raw
    (what the mcap_recorder records) equals our bytes up to padding."""
    expected, ours, _ = next(c for c in cases if isinstance(c[0], AccelerationBlock)
                             and len(c[0].plunge) == 50)
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
