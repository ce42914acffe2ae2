"""The fast flight-log decoders invert the encoders (which match ROS 2 bytes) and refuse junk."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.bag import cdr_encoding as cdr
from aero_dva.bag.cdr_decoding import (
    CdrDecodeError,
    decode_damper_state_applied,
    decode_flight_condition,
    decode_sample_block,
)
from aero_dva.flight.damper import DamperSnapshot, DamperStatus

RNG = np.random.default_rng(3)


@pytest.mark.parametrize("n", [1, 7, 50, 4000])
@pytest.mark.parametrize("frame_id", ["", "wing", "w"])
def test_sample_blocks_round_trip(n, frame_id):
    acc, disp, force = RNG.normal(size=(3, n)), RNG.normal(size=(4, n)), RNG.normal(size=n)
    for data, channels, values in [
        (cdr.encode_acceleration_block(1.25, 1000.0, 77, acc, frame_id), 3, acc),
        (cdr.encode_displacement_block(1.25, 1000.0, 77, disp, frame_id), 4, disp),
        (cdr.encode_force_block(1.25, 1000.0, 77, force, frame_id), 1, force[None]),
    ]:
        block = decode_sample_block(data, channels)
        assert block.stamp == pytest.approx(1.25, abs=1e-9)
        assert (block.sample_rate, block.first_index) == (1000.0, 77)
        np.testing.assert_array_equal(np.stack(block.channels), values)


def test_flight_condition_and_damper_state_round_trip():
    assert decode_flight_condition(cdr.encode_flight_condition(2.5, 101.5, 1.19)) == \
        pytest.approx((2.5, 101.5, 1.19))
    snapshot = DamperSnapshot(time=3.0, commanded_damping=700.0, applied_damping=612.5,
                              min_damping=0.0, max_damping=2500.0, command_age=0.05,
                              status=DamperStatus.OK, source="airspeed_schedule",
                              rejection=None)
    assert decode_damper_state_applied(cdr.encode_damper_state(snapshot)) == \
        pytest.approx((3.0, 612.5))


def test_truncated_or_foreign_bytes_are_refused():
    data = cdr.encode_displacement_block(0.0, 1000.0, 0, RNG.normal(size=(4, 50)))
    with pytest.raises(CdrDecodeError, match="claims 50 samples"):
        decode_sample_block(data[:-8], 4)
    with pytest.raises(CdrDecodeError, match="not little-endian"):
        decode_sample_block(b"\x00\x00" + data[2:], 4)  # big-endian encapsulation
    with pytest.raises(CdrDecodeError, match="different lengths"):
        # a ForceBlock read as if it had two channels: the second "count" is past the end
        decode_sample_block(cdr.encode_force_block(0.0, 1000.0, 0, np.ones(3))
                            + b"\x01\x00\x00\x00" + b"\x00" * 12, 2)
    with pytest.raises(CdrDecodeError):
        decode_flight_condition(b"\x00\x01\x00\x00\x01")
