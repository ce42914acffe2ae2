"""dva_ros_common.conversions: message <-> numpy conversions (needs the built dva_msgs, no DDS)."""
from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("dva_msgs.msg", reason="needs the built workspace (source scripts/env.sh)")

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402

from aero_dva.control.spectrum import scaled_spectrum  # noqa: E402
from dva_msgs.msg import ScaledSpectrum  # noqa: E402
from dva_ros_common import conversions  # noqa: E402


def test_time_roundtrip_in_integer_nanoseconds():
    ns = 12_345_678_901_234_567
    stamp = conversions.ns_to_time(ns)
    assert (stamp.sec, stamp.nanosec) == (12_345_678, 901_234_567)
    assert conversions.time_to_ns(stamp) == ns
    with pytest.raises(ValueError):
        conversions.ns_to_time(-1)


def test_acceleration_samples_channels_and_sample_times():
    msg = conversions.acceleration_block(conversions.ns_to_time(5_000_000_000), 1000.0, 700,
                                         [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]])
    block = conversions.acceleration_samples(msg, ("pitch", "plunge"))
    np.testing.assert_array_equal(block.samples, [[4.0, 5.0, 6.0], [1.0, 2.0, 3.0]])
    assert (block.first_sample_index, block.sample_rate, block.frame_id) == (700, 1000.0, "wing")
    assert block.sample_time_ns(702) == 5_002_000_000
    msg.pitch = [1.0]
    with pytest.raises(ValueError, match="differ in length"):
        conversions.acceleration_samples(msg, ("plunge",))
    with pytest.raises(ValueError, match="unknown"):
        conversions.acceleration_samples(msg, ("yaw",))


def test_scaled_spectrum_message_roundtrip_is_channel_major():
    t = np.arange(2000) / 1000.0
    x = np.vstack([np.sin(2 * np.pi * 12 * t), np.sin(2 * np.pi * 7 * t)])
    spectrum = scaled_spectrum(x, 1000.0)
    msg = conversions.scaled_spectrum_message(conversions.ns_to_time(1), "wing",
                                              ["plunge", "pitch"], spectrum, 0.1, 750.0)
    assert msg.scaling == ScaledSpectrum.SCALING_BAND_SUM and msg.window_duration == 2.0
    assert msg.magnitudes[12 - 5] == pytest.approx(1.0)
    assert msg.magnitudes[16 + 7 - 5] == pytest.approx(1.0)
    back = conversions.spectrum_input(msg)
    np.testing.assert_array_equal(back.magnitudes, spectrum.magnitudes)
    assert back.channel_names == ("plunge", "pitch") and back.damping == 750.0
    msg.magnitudes = msg.magnitudes[:-1]
    with pytest.raises(ValueError, match="expected 2 channels x 16"):
        conversions.spectrum_input(msg)


def test_diagnostic_array_levels_and_values():
    array = conversions.diagnostic_array(conversions.ns_to_time(0), [
        conversions.diagnostic_status(conversions.WARN, "spectrum: window", "gap",
                                      {"expected_index": 10, "damping": math.nan})])
    (status,) = array.status
    assert status.level == DiagnosticStatus.WARN
    assert {kv.key: kv.value for kv in status.values} == {"expected_index": "10", "damping": "nan"}
    with pytest.raises(ValueError):
        conversions.diagnostic_status(7, "x", "y")


def test_sample_blocks_take_rows_in_the_wing_models_order():
    """The simulator's (3, n) and (4, n) arrays land in the fields the batch recorder uses."""
    from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES

    rows = np.arange(8.0).reshape(4, 2)
    acc = conversions.acceleration_block(0.25, 1000.0, 3, rows[:3])
    disp = conversions.displacement_block(0.25, 1000.0, 3, rows)
    for msg, names in ((acc, ACCELERATION_NAMES), (disp, DISPLACEMENT_NAMES)):
        assert msg.header.frame_id == "wing" and msg.header.stamp.nanosec == 250_000_000
        for row, name in zip(rows, names):
            np.testing.assert_array_equal(getattr(msg, name), row)
    force = conversions.force_block(0.25, 1000.0, 3, rows[0])
    assert force.header.frame_id == "" and list(force.aileron_force) == [0.0, 1.0]
    with pytest.raises(ValueError, match=r"needs \(3, n\) samples"):
        conversions.acceleration_block(0.0, 1000.0, 0, rows)
