"""The serialized messages of chosen topics of a closed MCAP file, as byte matrices.

A closed file's summary lists every chunk and, per chunk and channel, a message index (the
offsets of that channel's message records in the decompressed chunk). This reader checks each
chunk's CRC, decompresses it, and cuts the messages of the chosen channels out of it with
numpy: messages of one length come out as one (k, length) uint8 matrix, with no Python work
per message (the mcap package's reader parses every record of every chunk in Python, most of
the time of reading a large bag). Messages are in file order. A file without chunk and message
indexes gives None: the caller reads it with :func:`aero_dva.bag.reader.read_messages`.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.reader import SeekingReader

from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES, ChunkLimitError, decompress_chunk
from aero_dva.bag.reader import BagReadError
from aero_dva.bag.schemas import normalize_type_name

__all__ = ["IndexedReadError", "MessageMatrix", "indexed_messages"]

_MESSAGE_OP, _CHUNK_OP, _INDEX_OP = 0x05, 0x06, 0x07
_RECORD_HEAD = 9  # opcode u8, body length u64
_MESSAGE_HEAD = 22  # channel u16, sequence u32, log time u64, publish time u64


@dataclass(frozen=True)
class MessageMatrix:
    """Messages of one topic and one serialized length, from one chunk.

    Attributes
    ----------
    topic, type_name, schema_text : str
    data : ndarray of uint8, shape (k, length)
        One serialized CDR message per row, in file order.
    position : ndarray of int, shape (k,)
        Where each message lies in the file (chunk offset * 2**32 + offset in the chunk):
        sorting by it gives the file order across chunks and lengths.
    """

    topic: str
    type_name: str
    schema_text: str
    data: np.ndarray
    position: np.ndarray


class IndexedReadError(BagReadError):
    """A chunk that fails its CRC or whose index does not point at its messages."""


def _gather(buf: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray:
    return buf[starts[:, None] + np.arange(width)]


def indexed_messages(file: Path, topics: Iterable[str]) -> Iterator[MessageMatrix] | None:
    """Messages of ``topics`` in the MCAP ``file``, or None if it has no usable index."""
    with open(file, "rb") as stream:
        try:
            summary = SeekingReader(stream, record_size_limit=MAX_CHUNK_BYTES).get_summary()
        except Exception:  # noqa: BLE001 - an unclosed or damaged file: no index to use
            return None
    if summary is None or not summary.chunk_indexes:
        return None
    wanted = set(topics)
    channels = {cid: c for cid, c in summary.channels.items() if c.topic in wanted}
    if any(not index.message_index_offsets and index.message_index_length
           for index in summary.chunk_indexes):
        return None
    meta = {}
    for cid, c in channels.items():
        schema = summary.schemas.get(c.schema_id)
        if schema is None or c.message_encoding != "cdr" or schema.encoding != "ros2msg":
            return None
        meta[cid] = (c.topic, normalize_type_name(schema.name),
                     schema.data.decode("utf-8", "replace"))
    return _iterate(file, summary.chunk_indexes, meta)


def _iterate(file: Path, chunk_indexes, meta) -> Iterator[MessageMatrix]:
    # Plain reads, chunk by chunk (a memory map would keep the whole file resident).
    with open(file, "rb") as stream:
        for index in chunk_indexes:
            present = [cid for cid in meta if cid in index.message_index_offsets]
            if not present:
                continue
            records = _chunk_records(stream, index, file)
            first = min(index.message_index_offsets.values())
            if index.message_index_length > MAX_CHUNK_BYTES:
                raise IndexedReadError(f"{file}: a chunk's message index declares "
                                       f"{index.message_index_length:,} bytes, more than "
                                       f"the {MAX_CHUNK_BYTES:,} the readers read")
            stream.seek(first)
            indexes = np.frombuffer(stream.read(index.message_index_length), dtype=np.uint8)
            for cid in present:
                offsets = _index_offsets(indexes, index.message_index_offsets[cid] - first,
                                         file)
                yield from _cut(records, offsets, index, cid, meta[cid], file)


def _cut(records, offsets, index, cid, meta, file) -> Iterator[MessageMatrix]:
    """The messages at ``offsets`` of the decompressed chunk ``records``, by length."""
    if offsets.size == 0:
        return
    if offsets.max() + _RECORD_HEAD + _MESSAGE_HEAD > records.size:
        raise IndexedReadError(f"{file}: a message index points past its chunk")
    head = _gather(records, offsets, _RECORD_HEAD + 2)
    lengths = head[:, 1:9].copy().view("<u8")[:, 0]
    ids = head[:, 9:11].copy().view("<u2")[:, 0]
    if np.any(head[:, 0] != _MESSAGE_OP) or np.any(ids != cid) or np.any(
            lengths < _MESSAGE_HEAD) or np.any(offsets + _RECORD_HEAD + lengths
                                               > records.size):
        raise IndexedReadError(f"{file}: a message index does not point at messages of "
                               "its channel")
    sizes = lengths - _MESSAGE_HEAD
    topic, type_name, text = meta
    for size in np.unique(sizes):
        at = offsets[sizes == size]
        starts = (at + _RECORD_HEAD + _MESSAGE_HEAD).astype(np.intp)
        yield MessageMatrix(topic, type_name, text, _gather(records, starts, int(size)),
                            (index.chunk_start_offset << 32) + at)


def _chunk_records(stream, index, file: Path) -> np.ndarray:
    """The decompressed records of a chunk, CRC checked."""
    at = index.chunk_start_offset
    if index.chunk_length > MAX_CHUNK_BYTES + 2**16:
        raise IndexedReadError(f"{file}: the chunk at offset {at} declares "
                               f"{index.chunk_length:,} bytes, more than the "
                               f"{MAX_CHUNK_BYTES:,} a chunk may hold (the readers' ceiling)")
    stream.seek(at)
    raw = stream.read(index.chunk_length)
    if len(raw) != index.chunk_length or raw[0] != _CHUNK_OP:
        raise IndexedReadError(f"{file}: no whole chunk at offset {at}")
    _, _, size, crc, name_len = struct.unpack_from("<QQQII", raw, _RECORD_HEAD)
    pos = _RECORD_HEAD + 32
    compression = raw[pos:pos + name_len].decode("ascii", "replace")
    pos += name_len
    (stored,) = struct.unpack_from("<Q", raw, pos)
    pos += 8
    if pos + stored > len(raw):
        raise IndexedReadError(f"{file}: the chunk at offset {at} runs past its record")
    data = memoryview(raw)[pos:pos + stored]
    if compression not in ("", "zstd", "lz4"):
        raise IndexedReadError(f"{file}: chunk compression {compression!r} is not known")
    try:
        data = decompress_chunk(compression, data, size)
    except ChunkLimitError as exc:
        raise IndexedReadError(f"{file}: the chunk at offset {at}: {exc}") from None
    if len(data) != size:
        raise IndexedReadError(f"{file}: the chunk at offset {at} holds {len(data)} bytes, "
                               f"its header says {size}")
    if crc and zlib.crc32(data) != crc:
        raise IndexedReadError(f"{file}: the chunk at offset {at} fails its CRC")
    return np.frombuffer(data, dtype=np.uint8)


def _index_offsets(block: np.ndarray, at: int, file: Path) -> np.ndarray:
    """Record offsets (file order) of the message index record at ``at`` in ``block``."""
    if at < 0 or at + _RECORD_HEAD + 6 > block.size or block[at] != _INDEX_OP:
        raise IndexedReadError(f"{file}: no message index where the summary says")
    (length,) = struct.unpack_from("<I", block, at + _RECORD_HEAD + 2)
    start = at + _RECORD_HEAD + 6
    if length % 16 or start + length > block.size:
        raise IndexedReadError(f"{file}: a damaged message index")
    pairs = block[start:start + length].view("<u8").reshape(-1, 2)
    return np.sort(pairs[:, 1]).astype(np.int64)
