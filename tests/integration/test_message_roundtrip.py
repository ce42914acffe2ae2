"""Custom dva_msgs messages cross DDS between two nodes intact (launch-free, own context)."""
from __future__ import annotations

import math

import pytest
from rclpy.node import Node

from dva_msgs.msg import AccelerationBlock, DamperState, ScaledSpectrum

pytestmark = pytest.mark.ros


def _roundtrip(executor, spin, ros_context, msg_type, topic, msg):
    sender = Node("sender", context=ros_context)
    receiver = Node("receiver", context=ros_context)
    received = []
    receiver.create_subscription(msg_type, topic, received.append, 10)
    publisher = sender.create_publisher(msg_type, topic, 10)
    executor.add_node(sender)
    executor.add_node(receiver)

    # Publish until discovery has matched the endpoints and one message arrived.
    def arrived() -> bool:
        if not received:
            publisher.publish(msg)
        return bool(received)

    assert spin(executor, arrived, timeout=15.0), f"no {msg_type.__name__} arrived on {topic}"
    return received[0]


def test_acceleration_block_roundtrip(executor, spin, ros_context):
    msg = AccelerationBlock()
    msg.header.frame_id = "wing"
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345_000_000
    msg.sample_rate = 1000.0
    msg.first_sample_index = 2**40 + 7  # beyond 32 bits: the field must be 64-bit
    msg.plunge = [0.1 * i for i in range(20)]
    msg.pitch = [-0.01 * i for i in range(20)]
    msg.leading_edge = [math.pi] * 20

    got = _roundtrip(executor, spin, ros_context, AccelerationBlock, "wing/acceleration", msg)

    assert got.header.frame_id == "wing"
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == (12, 345_000_000)
    assert got.sample_rate == 1000.0
    assert got.first_sample_index == 2**40 + 7
    assert list(got.plunge) == list(msg.plunge)
    assert list(got.pitch) == list(msg.pitch)
    assert list(got.leading_edge) == list(msg.leading_edge)


def test_spectrum_and_damper_state_roundtrip(executor, spin, ros_context):
    spectrum = ScaledSpectrum()
    spectrum.frequencies = [float(f) for f in range(5, 21)]
    spectrum.channel_names = ["plunge", "pitch"]
    spectrum.magnitudes = [1.0 / 16] * 32
    spectrum.window_function = ScaledSpectrum.WINDOW_RECTANGULAR
    spectrum.scaling = ScaledSpectrum.SCALING_BAND_SUM
    spectrum.window_duration = 2.0
    got = _roundtrip(executor, spin, ros_context, ScaledSpectrum, "dva/spectrum", spectrum)
    assert list(got.channel_names) == ["plunge", "pitch"]
    assert len(got.magnitudes) == 32 and got.scaling == "band_sum"

    state = DamperState(status=DamperState.STATUS_FALLBACK_STALE, applied_damping=800.0,
                        command_age=math.inf, commanded_damping=math.nan, source="fallback")
    got = _roundtrip(executor, spin, ros_context, DamperState, "dva/damper_state", state)
    assert got.status == DamperState.STATUS_FALLBACK_STALE == 2
    assert got.applied_damping == 800.0 and math.isinf(got.command_age)
    assert math.isnan(got.commanded_damping)
