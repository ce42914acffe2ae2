"""How much a bag reader holds at once: the one place MCAP chunks are decompressed.

A chunk's compressed bytes can expand without bound (83 KB of zstd to 2.5 GiB), and a zstd
frame's own content size makes ``zstandard.decompress`` allocate it whatever the caller's
limit. So every reader of the project decompresses through :func:`decompress_chunk` (and the
start of a cut chunk through :func:`decompress_prefix`): streaming, it stops at
``min(declared uncompressed size, MAX_CHUNK_BYTES)`` + 1 bytes and refuses the chunk
(:class:`ChunkLimitError`) when there is more. ``MAX_CHUNK_BYTES`` is the documented ceiling
(docs/bags.md, docs/reliability.md): this project's recorders write 1 MiB chunks, rosbag2's
MCAP storage 768 KiB by default. A chunk record larger than the ceiling is not read either.

Readers that merge chunks in log-time order hold the messages of every chunk overlapping in
time at once; :class:`MergeBudget` counts them (data plus :data:`MESSAGE_OVERHEAD` per
message for the parsed record) and refuses past ``MAX_MERGE_BYTES``, so a file of many chunks
all spanning the same times cannot make a reader hold them all.
"""
from __future__ import annotations

import zlib

__all__ = ["MAX_CHUNK_BYTES", "MAX_MERGE_BYTES", "MESSAGE_OVERHEAD", "ChunkLimitError",
           "MergeBudget", "chunk_records", "decompress_chunk", "decompress_prefix"]

#: [bytes] most a chunk's records (decompressed) or a chunk record (compressed) may hold.
MAX_CHUNK_BYTES = 16 * 2**20
#: [bytes] most the messages held by a log-time merge of chunks may take.
MAX_MERGE_BYTES = 128 * 2**20
#: [bytes] what a parsed message costs besides its data (record object, queue entry).
MESSAGE_OVERHEAD = 200
_PREFIX_FEED = 256  # [bytes] compressed input per step of a prefix (bounds one step's output)


class ChunkLimitError(ValueError):
    """A chunk (or a merge of chunks) would take more memory than the readers allow."""


def _limit(declared: int | None) -> int:
    if declared is None:
        return MAX_CHUNK_BYTES
    if declared > MAX_CHUNK_BYTES:
        raise ChunkLimitError(f"a chunk declares {declared:,} bytes of records, more than the "
                              f"{MAX_CHUNK_BYTES:,} a chunk may hold (the readers' ceiling)")
    return int(declared)


def _too_big(limit: int, declared: int | None) -> ChunkLimitError:
    what = (f"its declared {declared:,} bytes" if declared is not None else
            f"the {MAX_CHUNK_BYTES:,} bytes a chunk may hold (the readers' ceiling)")
    return ChunkLimitError(f"a chunk decompresses to more than {what}")


def decompress_chunk(compression: str, data, declared: int | None = None) -> bytes:
    """A chunk's records from its compressed ``data``, at most ``declared`` bytes (its header's
    uncompressed size; None when that field is not trusted) and never more than
    :data:`MAX_CHUNK_BYTES`. ChunkLimitError when there would be more; the decompressors' own
    errors (damaged data) pass through."""
    limit = _limit(declared)
    if len(data) > MAX_CHUNK_BYTES + 2**16:  # compressed data a little above the records
        raise ChunkLimitError(f"a chunk record of {len(data):,} bytes is larger than the "
                              f"{MAX_CHUNK_BYTES:,} a chunk may hold (the readers' ceiling)")
    if compression == "":
        out = bytes(data)
    elif compression == "zstd":
        import zstandard

        content = zstandard.frame_content_size(data)  # -1: not stated in the frame
        if content > limit:
            raise _too_big(limit, declared)
        out = zstandard.ZstdDecompressor().stream_reader(data).read(limit + 1)
    elif compression == "lz4":
        import lz4.frame

        out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=limit + 1)
    else:
        raise ValueError(f"unknown chunk compression {compression!r}")
    if len(out) > limit:
        raise _too_big(limit, declared)
    return out


def decompress_prefix(compression: str, data) -> bytes:
    """What the first bytes of a compressed chunk (a file cut inside it, or damaged) decompress
    to, up to :data:`MAX_CHUNK_BYTES` (the rest is not read)."""
    if compression == "":
        return bytes(data[:MAX_CHUNK_BYTES])
    if compression == "zstd":
        import zstandard

        inflate = zstandard.ZstdDecompressor().decompressobj()
        out = bytearray()
        view = memoryview(data)
        for at in range(0, len(view), _PREFIX_FEED):
            # a small feed bounds what one step can expand to (zstd blocks of 128 KiB)
            out += inflate.decompress(view[at:at + _PREFIX_FEED])
            if len(out) >= MAX_CHUNK_BYTES or inflate.eof:
                break
        return bytes(out[:MAX_CHUNK_BYTES])
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.LZ4FrameDecompressor().decompress(bytes(data),
                                                           max_length=MAX_CHUNK_BYTES)
    raise ValueError(f"unknown chunk compression {compression!r}")


def chunk_records(chunk, validate_crc: bool = True) -> list:
    """The records of an ``mcap.records.Chunk`` (``breakup_chunk``'s), decompressed through
    :func:`decompress_chunk` and CRC-checked; ``breakup_chunk`` itself would let zstd allocate
    whatever the frame states."""
    from mcap.records import Chunk
    from mcap.stream_reader import CRCValidationError, breakup_chunk

    raw = decompress_chunk(chunk.compression, chunk.data, chunk.uncompressed_size)
    if validate_crc and chunk.uncompressed_crc and zlib.crc32(raw) != chunk.uncompressed_crc:
        raise CRCValidationError(chunk.uncompressed_crc, zlib.crc32(raw), chunk)
    return breakup_chunk(Chunk(compression="", data=raw,
                               message_start_time=chunk.message_start_time,
                               message_end_time=chunk.message_end_time,
                               uncompressed_crc=0, uncompressed_size=len(raw)))


class MergeBudget:
    """Bytes held by a log-time merge of chunks (module docstring): :meth:`hold` when a
    chunk's messages are queued, :meth:`release` as each is handed out."""

    def __init__(self, where: str, limit: int = MAX_MERGE_BYTES):
        self.where, self.limit, self.held = where, int(limit), 0

    @staticmethod
    def cost(message) -> int:
        return len(message.data) + MESSAGE_OVERHEAD

    def hold(self, messages) -> None:
        self.held += sum(self.cost(m) for m in messages)
        if self.held > self.limit:
            raise ChunkLimitError(
                f"{self.where}: its chunks overlap in log time so much that merging them "
                f"would hold {self.held:,} bytes of messages at once, more than the "
                f"{self.limit:,} a reader holds")

    def release(self, message) -> None:
        self.held -= self.cost(message)
