"""dva bag info / recover: a bag cut at any byte keeps every message of every complete chunk."""
from __future__ import annotations

import io
import shutil
from pathlib import Path

import numpy as np
import pytest
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk

from aero_dva.bag.reader import BagReadError, bag_topics, read_messages
from aero_dva.bag.recovery import bag_info, recover_bag
from aero_dva.bag.writer import BagWriter
from tests.unit.aero_dva.bag.reference_bag import write_batch_bag

ACC = "dva_msgs/msg/AccelerationBlock"
FLIGHT = "dva_msgs/msg/FlightCondition"


def _stamp(t):
    return {"sec": int(t), "nanosec": int(round((t % 1) * 1e9))}


@pytest.fixture(scope="module")
def zstd_bag(tmp_path_factory):
    """A recorder-node-like bag: zstd chunks of 4 KiB, two topics."""
    path = tmp_path_factory.mktemp("z") / "run"
    rng = np.random.default_rng(1)
    with BagWriter(path, chunk_size=4096) as writer:
        writer.add_topic("wing/acceleration", ACC)
        writer.add_topic("flight/condition", FLIGHT)
        for k in range(300):
            writer.write("wing/acceleration", {
                "header": {"stamp": _stamp(0.02 * k), "frame_id": "wing"},
                "sample_rate": 1e3, "first_sample_index": 20 * k,
                "plunge": rng.standard_normal(20), "pitch": rng.standard_normal(20),
                "leading_edge": rng.standard_normal(20)}, 20_000_000 * k)
            if k % 5 == 0:
                writer.write("flight/condition", {"header": {"stamp": _stamp(0.02 * k)},
                                                  "airspeed": 80.0 + k}, 20_000_000 * k + 1)
    return path


@pytest.fixture(scope="module")
def batch_bag(tmp_path_factory):
    """A batch-recorder bag: uncompressed chunks of 20 kB."""
    return write_batch_bag(tmp_path_factory.mktemp("b") / "run")


def _file_records(mcap: Path) -> list[tuple]:
    with open(mcap, "rb") as stream:
        return [(c.topic, m.log_time, m.publish_time, m.sequence, m.data)
                for _, c, m in make_reader(stream).iter_messages(log_time_order=False)]


def _chunks(mcap: Path) -> list[tuple[int, int, int]]:
    """(start, end, messages) of each chunk in file order, from the chunk and message indexes
    (a message index record: opcode, length, channel id, entries length, 16-byte entries)."""
    with open(mcap, "rb") as stream:
        summary = make_reader(stream).get_summary()
    data = mcap.read_bytes()
    out = []
    for index in sorted(summary.chunk_indexes, key=lambda i: i.chunk_start_offset):
        entries = sum(int.from_bytes(data[at + 11:at + 15], "little")
                      for at in index.message_index_offsets.values())
        start = index.chunk_start_offset
        out.append((start, start + index.chunk_length, entries // 16))
    return out


def _cut(bag: Path, offset: int, where: Path) -> Path:
    """A copy of ``bag`` as a crash leaves it: no metadata.yaml, the file cut at ``offset``."""
    copy = where / "cut"
    copy.mkdir()
    (mcap,) = bag.glob("*.mcap")
    (copy / "cut_0.mcap").write_bytes(mcap.read_bytes()[:offset])
    return copy


@pytest.mark.parametrize("name", ["zstd_bag", "batch_bag"])
def test_recover_keeps_every_complete_chunk_at_20_random_cuts(name, request, tmp_path):
    bag = request.getfixturevalue(name)
    (mcap,) = bag.glob("*.mcap")
    size = mcap.stat().st_size
    full = _file_records(mcap)
    chunks = _chunks(mcap)
    assert len(chunks) > 5 and sum(n for *_, n in chunks) == len(full)
    rng = np.random.default_rng(20)
    for k, offset in enumerate(sorted(rng.integers(len(b"\x89MCAP0\r\n"), size, 20))):
        where = tmp_path / str(k)
        where.mkdir()
        cut = _cut(bag, int(offset), where)
        result = recover_bag(cut, where / "new")
        whole = sum(n for start, end, n in chunks if end <= offset)
        started = sum(n for start, end, n in chunks if start < offset)
        assert whole <= result.kept <= started, (offset, result)
        if chunks[-1][1] <= offset:
            assert result.kept == len(full)
        else:
            assert result.damage is not None and result.damage.offset <= offset
        # The new bag is complete and holds the uncut bag's first messages, unchanged.
        info = bag_info(where / "new")
        assert info.closed and info.message_count == result.kept
        assert _file_records(where / "new" / "new_0.mcap") == full[:result.kept]
        counts = {t.name: t.message_count for t in bag_topics(where / "new").values()}
        assert sum(counts.values()) == result.kept


def test_an_uncompressed_cut_chunk_keeps_its_whole_messages(batch_bag, tmp_path):
    """The file ends inside a chunk: the message records before the cut are kept too."""
    (mcap,) = batch_bag.glob("*.mcap")
    with open(mcap, "rb") as stream:
        index = sorted(make_reader(stream).get_summary().chunk_indexes,
                       key=lambda i: i.chunk_start_offset)[2]
    data = mcap.read_bytes()
    offsets = sorted(  # where each message record starts in the chunk's records
        int.from_bytes(data[at + 15 + 16 * e + 8:at + 15 + 16 * e + 16], "little")
        for at in index.message_index_offsets.values()
        for e in range(int.from_bytes(data[at + 11:at + 15], "little") // 16))
    records = index.chunk_start_offset + 9 + 8 + 8 + 8 + 4 + 4 + 8  # no compression name
    j = len(offsets) // 2
    cut = _cut(batch_bag, records + offsets[j] + 5, tmp_path)  # 5 bytes into message j
    result = recover_bag(cut, tmp_path / "new")
    before = sum(n for _, end, n in _chunks(mcap) if end <= index.chunk_start_offset)
    assert result.salvaged == j and result.kept == before + j
    assert "ends inside a chunk record" in result.damage.reason
    assert _file_records(tmp_path / "new" / "new_0.mcap") == _file_records(mcap)[:before + j]


def test_a_corrupt_chunk_costs_only_its_own_messages(batch_bag, tmp_path):
    (mcap,) = batch_bag.glob("*.mcap")
    chunks = _chunks(mcap)
    start, end, lost = chunks[3]
    data = bytearray(mcap.read_bytes())
    data[(start + end) // 2] ^= 0xFF  # one flipped bit pattern inside chunk 3 (CRC fails)
    copy = tmp_path / "bad"
    shutil.copytree(batch_bag, copy)
    (copy / mcap.name).write_bytes(bytes(data))
    result = recover_bag(copy, tmp_path / "new")
    assert result.kept == sum(n for *_, n in chunks) - lost and result.salvaged == 0
    assert result.lost == lost and result.promised == sum(n for *_, n in chunks)
    (damaged,) = result.damaged
    assert (damaged.start, damaged.end) == (start, chunks[4][0]) and damaged.lost == lost
    assert result.damage.offset == start and "crc" in result.damage.reason.lower()
    kept = _file_records(tmp_path / "new" / "new_0.mcap")
    assert kept == [r for r in _file_records(mcap) if r not in _chunk_records(mcap, 3)]


def _chunk_records(mcap: Path, k: int) -> list[tuple]:
    """The message records of the k-th chunk (file order) of an intact file, read by mcap."""
    with open(mcap, "rb") as stream:
        summary = make_reader(stream).get_summary()
    start, end, _ = _chunks(mcap)[k]
    body = io.BytesIO(mcap.read_bytes()[start + 9:end])  # after opcode and record length
    records = breakup_chunk(Chunk.read(ReadDataStream(body)), validate_crc=True)
    return [(summary.channels[m.channel_id].topic, m.log_time, m.publish_time, m.sequence,
             m.data) for m in records if isinstance(m, Message)]


def test_info_of_closed_and_unclosed_bags(zstd_bag, tmp_path):
    info = bag_info(zstd_bag)
    assert info.closed and info.damage is None and info.message_count == 360
    assert {t.name: t.message_count for t in info.topics} == {
        "/wing/acceleration": 300, "/flight/condition": 60}
    assert info.duration_ns == 20_000_000 * 299
    (mcap,) = zstd_bag.glob("*.mcap")
    cut = _cut(zstd_bag, mcap.stat().st_size // 2, tmp_path)
    info = bag_info(cut)
    assert not info.closed and info.damage is not None
    assert "no metadata.yaml" in info.problems[0] and 0 < info.message_count < 360
    assert info.to_dict()["damage"]["offset"] == info.damage.offset


def test_readers_name_the_recover_command(zstd_bag, tmp_path):
    (mcap,) = zstd_bag.glob("*.mcap")
    cut = _cut(zstd_bag, mcap.stat().st_size // 2, tmp_path)
    with pytest.raises(BagReadError, match=r"run `dva bag recover .*cut --out NEW_BAG`") as err:
        read_messages(cut)
    assert "allow_truncated" not in str(err.value)
    (cut / "metadata.yaml").write_text((zstd_bag / "metadata.yaml").read_text().replace(
        "run_0.mcap", "cut_0.mcap"))
    with pytest.raises(BagReadError, match="truncated or corrupt.*dva bag recover"):
        read_messages(cut)


def test_recover_refuses_what_it_cannot_do(zstd_bag, tmp_path):
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"not an mcap file at all")
    with pytest.raises(BagReadError, match="nothing to recover: no MCAP magic"):
        recover_bag(garbage, tmp_path / "new")
    assert not (tmp_path / "new").exists()
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x").write_text("x")
    with pytest.raises(FileExistsError, match="exists and is not empty"):
        recover_bag(zstd_bag, tmp_path / "taken")
    with pytest.raises(BagReadError, match="does not exist"):
        recover_bag(tmp_path / "nowhere", tmp_path / "new")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["garbage.mcap", "taken"]


def test_recover_of_a_whole_bag_copies_it(zstd_bag, tmp_path):
    result = recover_bag(zstd_bag, tmp_path / "copy")
    assert result.damage is None and result.kept == 360
    (mcap,) = zstd_bag.glob("*.mcap")
    assert _file_records(tmp_path / "copy" / "copy_0.mcap") == _file_records(mcap)


def test_a_flipped_byte_in_a_closed_bag_is_an_error_naming_recover(batch_bag, tmp_path):
    copy = tmp_path / "flipped"
    shutil.copytree(batch_bag, copy)
    (mcap,) = copy.glob("*.mcap")
    start, end, _ = _chunks(mcap)[2]
    data = bytearray(mcap.read_bytes())
    data[(start + end) // 2] ^= 0x01  # one bit in chunk 2, most of which is float samples
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagReadError, match=rf"CRCValidationError.*dva bag recover {copy} --out"):
        list(read_messages(copy))
