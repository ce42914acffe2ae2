"""Bit flips in a closed bag, and what of it must survive (shared by the bench and the tests).

:func:`layout` maps an intact MCAP file's parts (header, chunks, message indexes, summary) from
its own summary; :func:`flip_copy` writes a copy of a bag with bits flipped at chosen offsets;
:func:`expected_messages` is the oracle: the messages of every chunk that still passes its CRC
in the damaged copy, found at the intact file's chunk offsets (which the recovery does not
know) and checked by ``mcap``'s own chunk reader; :func:`read_checked` reads a bag with
``mcap``'s reader, CRCs validated. Nothing here uses the project's scanner.
"""
from __future__ import annotations

import io
import shutil
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk

__all__ = ["PARTS", "Layout", "expected_messages", "flip_copy", "layout", "read_checked",
           "random_offsets"]

PARTS = ("header", "chunk", "index", "summary")
_RECORD_HEAD = 9  # opcode, length


@dataclass(frozen=True)
class Layout:
    """Byte ranges of an intact MCAP file: its chunks, its message index records, and where
    the summary starts; everything before the first chunk is the header."""

    size: int
    chunks: tuple[tuple[int, int], ...]  # [start, end) of each chunk record, file order
    indexes: tuple[tuple[int, int], ...]  # [start, end) of each chunk's message indexes
    summary_start: int
    topics: dict  # channel id -> topic

    def part(self, offset: int) -> str:
        if offset < self.chunks[0][0]:
            return "header"
        if offset >= self.summary_start:
            return "summary"
        if any(a <= offset < b for a, b in self.chunks):
            return "chunk"
        return "index"  # message indexes (and the data end record between them and summary)

    def ranges(self, part: str) -> list[tuple[int, int]]:
        if part == "header":
            return [(0, self.chunks[0][0])]
        if part == "chunk":
            return list(self.chunks)
        if part == "index":
            return [(self.chunks[i][1], (self.chunks[i + 1][0] if i + 1 < len(self.chunks)
                                         else self.summary_start))
                    for i in range(len(self.chunks))]
        return [(self.summary_start, self.size)]


def layout(mcap: Path) -> Layout:
    with open(mcap, "rb") as stream:
        summary = make_reader(stream).get_summary()
    indexes = sorted(summary.chunk_indexes, key=lambda i: i.chunk_start_offset)
    chunks = tuple((i.chunk_start_offset, i.chunk_start_offset + i.chunk_length)
                   for i in indexes)
    index_ranges = tuple((min(i.message_index_offsets.values(), default=a),
                          min(i.message_index_offsets.values(), default=a)
                          + i.message_index_length) for i, (a, _) in zip(indexes, chunks,
                                                                        strict=True))
    size = mcap.stat().st_size
    data = mcap.read_bytes()
    footer = size - 8 - 29
    summary_start = int.from_bytes(data[footer + 9:footer + 17], "little")
    return Layout(size, chunks, index_ranges, summary_start,
                  {c.id: c.topic for c in summary.channels.values()})


def random_offsets(rng: np.random.Generator, ranges: list[tuple[int, int]], n: int) -> list:
    """``n`` (byte offset, bit) uniform over the bytes of ``ranges``."""
    starts = np.array([a for a, _ in ranges])
    lengths = np.array([b - a for a, b in ranges])
    picks = rng.integers(0, lengths.sum(), n)
    edges = np.cumsum(lengths)
    out = []
    for p in picks:
        k = int(np.searchsorted(edges, p, side="right"))
        out.append((int(starts[k] + p - (edges[k] - lengths[k])), int(rng.integers(0, 8))))
    return out


def flip_copy(bag: Path, flips: list[tuple[int, int]], out: Path) -> Path:
    """A copy of bag directory ``bag`` (metadata.yaml included) with ``flips`` applied to its
    one MCAP file."""
    (mcap,) = bag.glob("*.mcap")
    shutil.copytree(bag, out)
    data = bytearray(mcap.read_bytes())
    for offset, bit in flips:
        data[offset] ^= 1 << bit
    (out / mcap.name).write_bytes(bytes(data))
    return out


def _chunk_messages(data: bytes, start: int, end: int) -> list[Message] | None:
    """The messages of the chunk record at [start, end) if it reads and its CRC holds."""
    try:
        chunk = Chunk.read(ReadDataStream(io.BytesIO(data[start + _RECORD_HEAD:end])))
        records = breakup_chunk(chunk, validate_crc=True)
    except Exception:  # noqa: BLE001 - CRC and decompression errors of assorted types
        return None
    return [r for r in records if isinstance(r, Message)]


def expected_messages(intact: Path, damaged: Path, lay: Layout) -> tuple[Counter, int]:
    """(messages that must survive, CRC-valid chunks): the intact file's messages of every
    chunk whose bytes in the damaged copy still read and pass their CRC, as a Counter of
    (topic, log time, publish time, sequence, data)."""
    good, valid = Counter(), 0
    whole, bad = intact.read_bytes(), damaged.read_bytes()
    for start, end in lay.chunks:
        if _chunk_messages(bad, start, end) is None:
            continue
        valid += 1
        good.update((lay.topics[m.channel_id], m.log_time, m.publish_time, m.sequence, m.data)
                    for m in _chunk_messages(whole, start, end))
    return good, valid


def read_checked(bag: Path) -> list[tuple]:
    """Every message of a (recovered) bag's MCAP files in file order, read by ``mcap`` with
    CRC validation: (topic, log time, publish time, sequence, data)."""
    out = []
    for mcap in sorted(bag.glob("*.mcap")):
        with open(mcap, "rb") as stream:
            reader = make_reader(stream, validate_crcs=True)
            out.extend((c.topic, m.log_time, m.publish_time, m.sequence, m.data)
                       for _, c, m in reader.iter_messages(log_time_order=False))
    return out
