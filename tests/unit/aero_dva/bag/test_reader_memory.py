"""Every bag reader of the project, on bags built to exhaust memory, in a child process whose
address space is capped at 1 GiB (resource.setrlimit): none reaches the cap. A chunk that
expands past its declared size or the readers' ceiling, chunks overlapping in log time past
the merge budget and a file listed twice in metadata.yaml are refused in one line (or, by the
readers that report damage, reported as a damaged range) and never read whole."""
from __future__ import annotations

from pathlib import Path

import pytest

from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES, ChunkLimitError, decompress_chunk
from bench.faults import resource_bombs as rb

pytestmark = pytest.mark.slow

CAP = 2**30  # [bytes] of address space; "No reader takes more than 1 GB"

# readers that refuse a damaged bag; the others describe it, copy what reads, or play it
STRICT = ("read_messages", "indexed_messages")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("bombs")
    bags = {"valid": rb.valid_bag(root / "valid"),
            "bomb": rb.bomb_bag(root / "bomb"),  # 2.5 GiB of zeros in 80 KB, size declared
            "bomb_lie": rb.bomb_bag(root / "bomb_lie", declared=2**20),
            "bomb_nosize": rb.bomb_bag(root / "bomb_nosize", declared=2**20,
                                       content_size=False),
            "lz4": rb.lz4_bomb_bag(root / "lz4", expanded=256 * 2**20),
            "overlap": rb.overlap_bag(root / "overlap", chunks=150),
            "listed": rb.listed_bag(root / "listed", times=2000)}
    tasks = [(reader, bag) for bag in bags.values() for reader in rb.READERS]
    return {(Path(r.bag).name, r.reader): r for r in rb.run_capped(tasks, CAP)}


def test_no_reader_reaches_the_memory_cap_or_crashes(runs):
    bad = [(k, r.outcome, r.line) for k, r in runs.items() if r.outcome in ("memory",
                                                                            "crashed")]
    assert not bad
    assert max(r.peak for r in runs.values()) < CAP


def test_a_valid_bag_reads_in_every_reader(runs):
    assert all(r.outcome == "read" for (bag, _), r in runs.items() if bag == "valid"), [
        (k, r.line) for k, r in runs.items() if k[0] == "valid" and r.outcome != "read"]


@pytest.mark.parametrize("bag", ["bomb", "bomb_lie", "bomb_nosize", "lz4"])
def test_a_decompression_bomb_is_refused_or_reported_as_damage(runs, bag):
    for reader in rb.READERS:
        run = runs[bag, reader]
        if reader in STRICT and not (bag == "lz4" and reader == "indexed_messages"):
            assert run.outcome == "refused" and "chunk" in run.line, (reader, run)
        elif reader != "load_flight_log":  # that one wants flight topics the bomb lacks
            assert run.outcome == "read", (reader, run)


def test_chunks_overlapping_past_the_merge_budget_are_refused(runs):
    for reader in ("dva bag recover", "read_messages", "read_messages allow_truncated"):
        run = runs["overlap", reader]
        assert run.outcome == "refused" and "overlap in log time" in run.line, (reader, run)


def test_a_file_listed_twice_is_refused_in_one_line(runs):
    for reader in rb.READERS:
        if reader == "indexed_messages":  # reads the .mcap files, not the metadata
            continue
        run = runs["listed", reader]
        assert run.outcome == "refused", (reader, run)
        assert "metadata.yaml lists 'listed_0.mcap' 2000 times" in run.line, (reader, run)


def test_decompression_stops_at_the_declared_size_and_the_ceiling():
    frame = rb.zstd_zeros(4 * MAX_CHUNK_BYTES, content_size=False)
    assert len(decompress_chunk("zstd", rb.zstd_zeros(1000), 1000)) == 1000
    with pytest.raises(ChunkLimitError, match="more than its declared 999 bytes"):
        decompress_chunk("zstd", rb.zstd_zeros(1000), 999)
    with pytest.raises(ChunkLimitError, match="readers' ceiling"):
        decompress_chunk("zstd", frame, None)
    with pytest.raises(ChunkLimitError, match="declares"):
        decompress_chunk("zstd", frame, 4 * MAX_CHUNK_BYTES)
