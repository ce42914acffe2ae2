"""The indexed, batch-decoded reading of a closed bag against the message-by-message route."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.bag.batch_decode import decode_batch
from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.indexed_read import indexed_messages
from aero_dva.bag.reader import BagReadError, bag_files, read_messages
from aero_dva.bag.writer import BagWriter

RATE = 1000.0


def _stamp(t: float, frame: str = "wing") -> dict:
    ns = int(round(t * 1e9))
    return {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": frame}


def _write(bag, n=3000, compression="zstd"):
    """Blocks of several lengths, a gap, damper states with sources of several lengths, in
    chunks of 4 KiB."""
    rng = np.random.default_rng(1)
    with BagWriter(bag, compression=compression, chunk_size=4096) as writer:
        writer.add_topic("/wing/displacement", "dva_msgs/msg/DisplacementBlock")
        writer.add_topic("/wing/acceleration", "dva_msgs/msg/AccelerationBlock")
        writer.add_topic("/flight/condition", "dva_msgs/msg/FlightCondition")
        writer.add_topic("/dva/damper_state", "dva_msgs/msg/DamperState")
        i0, b = 0, 0
        while i0 < n:
            size = (50, 20, 37)[b % 3]
            t0, t_ns = i0 / RATE, int(round(i0 / RATE * 1e9))
            rows = rng.standard_normal((7, size))
            if b != 5:  # a missing displacement block
                writer.write("/wing/displacement", {
                    "header": _stamp(t0), "sample_rate": RATE, "first_sample_index": i0,
                    "plunge": rows[0], "pitch": rows[1], "leading_edge": rows[2],
                    "absorber_stroke": rows[3]}, t_ns)
            writer.write("/wing/acceleration", {
                "header": _stamp(t0), "sample_rate": RATE, "first_sample_index": i0,
                "plunge": rows[4], "pitch": rows[5], "leading_edge": rows[6]}, t_ns)
            writer.write("/flight/condition", {"header": _stamp(t0), "airspeed": 80.0 + b,
                                               "air_density": 1.2 - 1e-3 * b}, t_ns)
            writer.write("/dva/damper_state", {
                "header": _stamp(t0), "applied_damping": 500.0 + 10 * b, "status": 0,
                "source": ("fixed", "airspeed_schedule", "rbf_network")[b % 3]}, t_ns)
            i0 += size
            b += 1


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_indexed_flight_log_equals_the_message_by_message_route(tmp_path, compression):
    _write(tmp_path / "bag", compression=compression)
    new = load_flight_log(tmp_path / "bag")
    old = load_flight_log(tmp_path / "bag", indexed=False)
    for name in ("time", "airspeed", "density", "displacements", "accelerations", "force",
                 "applied_damping"):
        np.testing.assert_array_equal(getattr(new, name), getattr(old, name), err_msg=name)
    assert new.missing_samples == old.missing_samples > 0
    assert new.sample_rate == old.sample_rate == RATE
    assert np.isnan(new.force).all()  # no excitation topic in this bag


def test_the_batches_cover_every_message_of_the_topic(tmp_path):
    _write(tmp_path / "bag")
    (file,) = bag_files(tmp_path / "bag")
    batches = list(indexed_messages(file, ["/dva/damper_state"]))
    assert len({m.data.shape[1] for m in batches}) == 3  # three source lengths
    raw = [r.message for r in read_messages(tmp_path / "bag", ["/dva/damper_state"],
                                            decode=False)]
    order = np.argsort(np.concatenate([m.position for m in batches]), kind="stable")
    rows = [bytes(row) for m in batches for row in m.data]
    assert [rows[i] for i in order] == raw


def test_a_batch_whose_constant_bytes_differ_is_left_to_the_slow_path(tmp_path):
    _write(tmp_path / "bag", n=500)
    records = list(read_messages(tmp_path / "bag", ["/flight/condition"], decode=False))
    raw = [r.message for r in records]
    type_name, text = records[0].type_name, records[0].schema_text
    got = decode_batch(raw, type_name, text, ["airspeed", "header.stamp.nanosec"])
    np.testing.assert_array_equal(got["airspeed"], 80.0 + np.arange(len(raw)))
    # Same length, another frame id ("wing" -> "winG"): not one layout, so no batch result.
    changed = bytearray(raw[3])
    at = bytes(changed).index(b"wing")
    changed[at + 3] = ord("G")
    assert decode_batch([*raw[:3], bytes(changed)], type_name, text, ["airspeed"]) is None


@pytest.mark.parametrize("indexed", [True, False])
def test_a_flipped_byte_in_a_chunk_is_an_error_naming_recover(tmp_path, indexed):
    _write(tmp_path / "bag", compression="none")
    (file,) = bag_files(tmp_path / "bag")
    data = bytearray(file.read_bytes())
    at = data.index(b"wing", len(data) // 3)  # inside a message of a middle chunk
    data[at] ^= 0x01
    file.write_bytes(bytes(data))
    with pytest.raises(BagReadError, match="recover"):
        load_flight_log(tmp_path / "bag", indexed=indexed)
