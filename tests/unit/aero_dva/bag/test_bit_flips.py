"""Bit flips anywhere in a closed bag: every chunk whose CRC holds is kept, the damage is seen.

The oracle and the reader of the recovered bag are ``mcap``'s (``bench.faults.bit_flips``):
the chunks that must survive are found at the intact file's offsets, which the recovery does
not know, and the copy is read back with CRC validation.
"""
from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from aero_dva.bag.recovery import bag_info, recover_bag
from aero_dva.bag.writer import BagWriter
from bench.faults.bit_flips import (
    PARTS,
    expected_messages,
    flip_copy,
    layout,
    random_offsets,
    read_checked,
)
from tests.unit.aero_dva.bag.reference_bag import write_batch_bag

COPIES = 5  # per part and bag


@pytest.fixture(scope="module")
def zstd_bag(tmp_path_factory):
    """A recorder-like bag: zstd chunks of 4 KiB (schemas and channels in the first one)."""
    path = tmp_path_factory.mktemp("z") / "run"
    rng = np.random.default_rng(3)
    with BagWriter(path, chunk_size=4096) as writer:
        writer.add_topic("wing/acceleration", "dva_msgs/msg/AccelerationBlock")
        writer.add_topic("clock", "rosgraph_msgs/msg/Clock")
        for k in range(200):
            t = 10_000_000 * k
            writer.write("clock", {"clock": {"sec": 0, "nanosec": t}}, t)
            writer.write("wing/acceleration", {
                "header": {"stamp": {"sec": 0, "nanosec": t}, "frame_id": "wing"},
                "sample_rate": 1e3, "first_sample_index": 10 * k,
                "plunge": rng.standard_normal(10), "pitch": rng.standard_normal(10),
                "leading_edge": rng.standard_normal(10)}, t + 1)
    return path


@pytest.fixture(scope="module")
def batch_bag(tmp_path_factory):
    """A batch-recorder bag: uncompressed chunks of 20 kB."""
    return write_batch_bag(tmp_path_factory.mktemp("b") / "run")


def _header_strings(mcap, lay) -> range:
    """Bytes of the header record's profile and library strings: no CRC covers them (the
    writers store no data section CRC), so a flip there is not seen."""
    return range(8 + 9, lay.chunks[0][0])


@pytest.mark.parametrize("name", ["zstd_bag", "batch_bag"])
@pytest.mark.parametrize("part", PARTS)
def test_flips_keep_every_crc_valid_chunk(name, part, request, tmp_path):
    bag = request.getfixturevalue(name)
    (mcap,) = bag.glob("*.mcap")
    lay = layout(mcap)
    intact = Counter(read_checked(bag))
    rng = np.random.default_rng([PARTS.index(part), len(name)])
    for k in range(COPIES):
        flips = random_offsets(rng, lay.ranges(part), int(rng.integers(1, 6)))
        copy = flip_copy(bag, flips, tmp_path / f"copy{k}")
        expected, valid = expected_messages(mcap, copy / mcap.name, lay)
        result = recover_bag(copy, tmp_path / f"new{k}")
        kept = read_checked(tmp_path / f"new{k}")  # mcap's reader, CRCs validated
        assert result.kept == len(kept)
        assert not expected - Counter(kept), (flips, result.damaged)  # every CRC-valid chunk
        assert not Counter(kept) - intact  # nothing that was not in the intact bag
        times = [m[1] for m in kept]
        assert times == sorted(times)  # log-time order
        assert result.lost == sum(intact.values()) - len(kept)  # the index's promise
        if part == "chunk":
            assert valid < len(lay.chunks) or result.damaged  # a flip the CRC sees
        info = bag_info(copy)
        if not all(o in _header_strings(mcap, lay) for o, _ in flips):
            assert info.damaged, flips
            assert not info.closed and any(p.startswith("damaged") for p in info.problems)
        assert info.message_count == len(kept) and info.lost == result.lost


def test_an_intact_bag_has_no_damage(zstd_bag, tmp_path):
    info = bag_info(zstd_bag)
    assert info.verified and not info.damaged and info.closed and info.lost == 0
    assert info.message_count == info.promised == 400
    result = recover_bag(zstd_bag, tmp_path / "copy")
    assert result.lost == 0 and not result.damaged
    assert read_checked(tmp_path / "copy") == sorted(read_checked(zstd_bag),
                                                     key=lambda m: m[1])


@pytest.fixture(scope="module")
def late_topic_bag(tmp_path_factory):
    """A bag whose second topic first appears in a later chunk: its schema and channel records
    are in that chunk and in the summary only."""
    path = tmp_path_factory.mktemp("late") / "run"
    with BagWriter(path, chunk_size=2048) as writer:
        writer.add_topic("clock", "rosgraph_msgs/msg/Clock")
        writer.add_topic("dva/damper_command", "dva_msgs/msg/DamperCommand")
        for k in range(300):
            t = 10_000_000 * k
            writer.write("clock", {"clock": {"sec": 0, "nanosec": t}}, t)
            if k >= 100:
                writer.write("dva/damper_command", {
                    "header": {"stamp": {"sec": 0, "nanosec": t}, "frame_id": ""},
                    "damping": 400.0 + k, "source": "fixed"}, t + 1)
    return path


def _late_damage(bag, tmp_path, summary_flip):
    """A copy with the chunk that first holds the late topic damaged and one summary flip."""
    (mcap,) = bag.glob("*.mcap")
    lay = layout(mcap)
    data = mcap.read_bytes()
    first = next(a for a, b in lay.chunks
                 if b"dva_msgs/msg/DamperCommand" in _chunk_records(data[a:b]))
    copy = flip_copy(bag, [(first + 40, 0), (summary_flip(data, lay), 0)], tmp_path / "copy")
    expected, _ = expected_messages(mcap, copy / mcap.name, lay)
    return copy, expected


def _chunk_records(chunk: bytes) -> bytes:
    import zstandard

    try:  # the writer's chunks are zstd frames after the chunk's fixed fields
        return zstandard.ZstdDecompressor().decompressobj().decompress(chunk[chunk.find(
            b"\x28\xb5\x2f\xfd"):])
    except zstandard.ZstdError:
        return chunk


def test_a_lost_channel_record_is_taken_from_the_summary_when_rosbag2_vouches(
        late_topic_bag, tmp_path):
    # The summary fails the footer's CRC (a flip after its schema and channel records, which
    # come first and still read); the topic's type and QoS in the rosbag2 metadata agree and
    # the schema text is the .msg's.
    def after_the_channels(data, lay):
        return data.rindex(b"\x08", lay.summary_start) + 20
    copy, expected = _late_damage(late_topic_bag, tmp_path, after_the_channels)
    assert sum(t == "/dva/damper_command" for t, *_ in expected) > 100
    result = recover_bag(copy, tmp_path / "new")
    kept = Counter(read_checked(tmp_path / "new"))
    assert not expected - kept and not kept - expected
    assert not any("channel record was lost" in d.reason for d in result.damaged)


def test_a_flipped_topic_in_the_summary_is_not_vouched_for(late_topic_bag, tmp_path):
    def in_topic_name(data, lay):
        return data.index(b"/dva/damper_command", lay.summary_start) + 5
    copy, expected = _late_damage(late_topic_bag, tmp_path, in_topic_name)
    result = recover_bag(copy, tmp_path / "new")
    kept = read_checked(tmp_path / "new")
    assert {t for t, *_ in kept} == {"/clock"}  # the late topic's messages: lost, not misread
    assert result.lost == sum(Counter(read_checked(late_topic_bag)).values()) - len(kept)
    assert any("channel record was lost" in d.reason for d in result.damaged)
