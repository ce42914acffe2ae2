"""Read an MCAP file record by record from its start, stopping where it is damaged.

What a truncated, unclosed or corrupt file still holds: every message of every chunk that is
whole and passes its CRC, in file order, and, when the file ends inside a chunk (a recorder
killed while writing it), the whole message records at the start of that chunk. A complete
chunk that fails its CRC or does not decompress ends the scan: nothing after damage is
trusted. The scan never reads more than the file holds, whatever a corrupt length field says,
nor a record or chunk past the readers' ceiling (:mod:`aero_dva.bag.chunk_limits`).

Used by the reader (``allow_truncated``), ``dva bag info`` and ``dva bag recover``.
"""
from __future__ import annotations

import io
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Message, Schema

from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES, chunk_records, decompress_prefix

__all__ = ["MCAP_MAGIC", "Damage", "FileScan", "ScannedMessage"]

MCAP_MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEAD = struct.Struct("<BQ")  # opcode, body length
_CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, name length
_NAMES = {int(op): op.name.lower() for op in Opcode}
_READ = (Opcode.CHUNK, Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.FOOTER)


@dataclass(frozen=True)
class Damage:
    """Where a file stops being readable: ``offset`` [bytes from its start] and why."""

    file: Path
    offset: int
    reason: str

    def __str__(self) -> str:
        return f"{self.file.name} at byte {self.offset}: {self.reason}"


@dataclass(frozen=True)
class ScannedMessage:
    """A message record with its channel and schema (None for a schemaless channel)."""

    schema: Schema | None
    channel: Channel
    message: Message


class FileScan:
    """Scan one MCAP file (see the module docstring).

    Iterate :meth:`messages` once; afterwards :attr:`damage` says where and why reading
    stopped (None: the file ended with its footer), :attr:`compression` names the chunk
    compression seen first, :attr:`chunks` counts the whole chunks read and
    :attr:`salvaged` the messages taken from a chunk the file ends inside.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.damage: Damage | None = None
        self.footer = False
        self.compression: str | None = None
        self.chunks = 0
        self.salvaged = 0
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}

    def _stop(self, offset: int, reason: str) -> None:
        self.damage = Damage(self.path, offset, reason)

    def messages(self) -> Iterator[ScannedMessage]:
        with open(self.path, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                self._stop(0, "no MCAP magic: not an MCAP file")
                return
            pos = len(MCAP_MAGIC)
            while True:
                head = stream.read(_RECORD_HEAD.size)
                if len(head) < _RECORD_HEAD.size:
                    self._stop(pos, "the file ends without a footer (not closed)" if not head
                               else "the file ends inside a record header")
                    return
                opcode, length = _RECORD_HEAD.unpack(head)
                name = _NAMES.get(opcode)
                if name is None:
                    self._stop(pos, f"invalid record opcode 0x{opcode:02x}")
                    return
                available = size - pos - _RECORD_HEAD.size
                if length > available:
                    if opcode == Opcode.CHUNK:
                        yield from self._salvage(stream.read(min(available,
                                                                 MAX_CHUNK_BYTES + 2**16)))
                    self._stop(pos, f"the file ends inside a {name} record ({available} of "
                               f"{length} bytes)")
                    return
                if opcode not in _READ:  # nothing of it is used: not read
                    stream.seek(length, os.SEEK_CUR)
                    pos += _RECORD_HEAD.size + length
                    continue
                if length > MAX_CHUNK_BYTES + 2**16:
                    self._stop(pos, f"a {name} record of {length:,} bytes is larger than the "
                               f"{MAX_CHUNK_BYTES:,} the readers read")
                    return
                body = stream.read(length)
                try:
                    records = self._records(opcode, body)
                except Exception as exc:  # noqa: BLE001 - any parse error is damage here
                    self._stop(pos, f"{name} record does not read ({type(exc).__name__}: "
                               f"{exc})")
                    return
                if opcode == Opcode.FOOTER:
                    self.footer = True
                    return
                for record in records:
                    if isinstance(record, Message):
                        yield ScannedMessage(self.schemas.get(
                            self.channels[record.channel_id].schema_id),
                            self.channels[record.channel_id], record)
                pos += _RECORD_HEAD.size + length

    def _records(self, opcode: int, body: bytes) -> list:
        """The schema, channel and message records of one record (all of a chunk's), checked:
        a message must name a known channel. Other records give an empty list."""
        data = ReadDataStream(io.BytesIO(body))
        if opcode == Opcode.CHUNK:
            chunk = Chunk.read(data)
            if self.compression is None:
                self.compression = chunk.compression
            records = chunk_records(chunk, validate_crc=True)
        elif opcode == Opcode.SCHEMA:
            records = [Schema.read(data)]
        elif opcode == Opcode.CHANNEL:
            records = [Channel.read(data)]
        elif opcode == Opcode.MESSAGE:
            records = [Message.read(data, len(body))]
        else:
            return []
        schemas, channels = dict(self.schemas), dict(self.channels)
        for record in records:
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message) and record.channel_id not in channels:
                raise ValueError(f"a message on unknown channel {record.channel_id}")
        self.schemas, self.channels = schemas, channels  # only once the whole record is good
        if opcode == Opcode.CHUNK:
            self.chunks += 1
        return records

    def _salvage(self, partial: bytes) -> Iterator[ScannedMessage]:
        """The whole message records at the start of a chunk the file ends inside."""
        if len(partial) < _CHUNK_HEAD.size:
            return
        *_, name_length = _CHUNK_HEAD.unpack_from(partial)
        start = _CHUNK_HEAD.size + name_length + 8  # + compression name + records length
        if len(partial) < start:
            return
        compression = partial[_CHUNK_HEAD.size:_CHUNK_HEAD.size + name_length].decode(
            "utf-8", "replace")
        try:
            data = decompress_prefix(compression, partial[start:])
        except Exception:  # noqa: BLE001 - an undecodable prefix holds nothing to keep
            return
        pos = 0
        while pos + _RECORD_HEAD.size <= len(data):
            opcode, length = _RECORD_HEAD.unpack_from(data, pos)
            end = pos + _RECORD_HEAD.size + length
            if end > len(data) or opcode not in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
                return
            try:
                (record,) = self._records(opcode, data[pos + _RECORD_HEAD.size:end])
            except Exception:  # noqa: BLE001 - the cut went through this record
                return
            if isinstance(record, Message):
                self.salvaged += 1
                channel = self.channels[record.channel_id]
                yield ScannedMessage(self.schemas.get(channel.schema_id), channel, record)
            pos = end
