"""Every chunk of an MCAP file that passes its CRC, wherever the damage is, and what it cost.

``mcap``'s readers stop at the first record that does not read (``mcap.stream_reader``) or
trust the summary's offsets (``mcap.reader.SeekingReader``); neither finds the next good record
after a damaged one. :func:`survey_file` does that part: it walks the data section record by
record and, after a record that does not read, resynchronises on the next chunk, found by its
opcode and length (or by an offset in the summary's chunk index, if one reads) and accepted
only if its CRC holds. The records themselves are parsed and the CRCs checked by ``mcap``
(``mcap.records``, ``mcap.stream_reader.breakup_chunk``); this module only finds where they are.

Besides the chunks it checks what else can be checked: the magic at both ends, the header
record, every message index record against the chunk it follows (message indexes carry no CRC
of their own), the data section CRC when the writer stored one, and the summary against the
footer's summary CRC. Each unreadable stretch is a :class:`DamagedRange` with, when the message
index records in it still read, the topics, messages and log-time span it held. A file cut
short keeps, as before, the whole message records at the start of the chunk it ends inside.
Chunks are decompressed within the readers' limits (:mod:`aero_dva.bag.chunk_limits`): one
larger than the ceiling is a damaged range, named as such.
"""
from __future__ import annotations

import heapq
import mmap
import os
import re
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, ChunkIndex, Header, Message, Metadata, Schema, Statistics
from mcap.records import Chunk as ChunkRecord
from mcap.stream_reader import breakup_chunk

from aero_dva.bag.chunk_limits import (
    MAX_CHUNK_BYTES,
    ChunkLimitError,
    MergeBudget,
    decompress_chunk,
    decompress_prefix,
)
from aero_dva.bag.mcap_scan import MCAP_MAGIC, ScannedMessage

__all__ = ["DamagedRange", "FileSurvey", "GoodChunk", "survey_file"]

_HEAD = struct.Struct("<BQ")  # opcode, record length
_CHUNK_FIXED = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, name length
_FOOTER = struct.Struct("<BQQQI")  # opcode, length, summary start, summary offset start, crc
_MESSAGE_KEY = struct.Struct("<HIQ")  # channel id, sequence, log time (a message's first fields)
_COMPRESSIONS = ("", "zstd", "lz4")
_NAMES = {int(op): op.name.lower() for op in Opcode}
_MIN_CHUNK_BODY = _CHUNK_FIXED.size + 8


@dataclass(frozen=True)
class GoodChunk:
    """A chunk record whose CRC holds: bytes [offset, end) of the file, its log-time span [ns]
    and message count taken from its records, and its message count per channel id."""

    offset: int
    end: int
    start_ns: int
    end_ns: int
    messages: int
    counts: dict = field(repr=False, compare=False)  # channel id -> messages


@dataclass(frozen=True)
class DamagedRange:
    """Bytes [start, end) of ``file`` that do not read, and what they held as far as known.

    ``lost`` is the number of messages the range held according to the message index records
    found in it (None: none read, the count is unknown); ``topics`` the same per topic;
    ``start_ns``/``end_ns`` their log-time span (None if unknown).
    """

    file: Path
    start: int
    end: int
    reason: str
    lost: int | None = 0
    topics: tuple[tuple[str, int], ...] = ()
    start_ns: int | None = None
    end_ns: int | None = None

    def __str__(self) -> str:
        text = f"{self.file.name} bytes {self.start}-{self.end}: {self.reason}"
        if self.lost is None:
            return text + "; messages lost: unknown (no message index read)"
        if self.lost == 0:
            return text + "; no message lost"
        span = ("" if self.start_ns is None else
                f", log time {self.start_ns * 1e-9:.3f}-{self.end_ns * 1e-9:.3f} s")
        return (text + f"; {self.lost} messages lost{span} ("
                + ", ".join(f"{t} {n}" for t, n in self.topics) + ")")

    def to_dict(self) -> dict:
        return {"file": str(self.file), "start": self.start, "end": self.end,
                "reason": self.reason, "lost": self.lost, "topics": dict(self.topics),
                "start_ns": self.start_ns, "end_ns": self.end_ns}


@dataclass
class FileSurvey:
    """What :func:`survey_file` found in one MCAP file.

    ``chunks`` are the CRC-valid chunks in file order; ``damaged`` the unreadable ranges in
    file order; ``summary_ok`` whether the summary passed the footer's CRC (then ``promised``
    is its statistics' message count and ``promised_topics`` per topic); ``salvaged`` the
    messages kept from the start of a chunk the file ends inside; ``cut`` whether the file
    ends before its footer.
    """

    path: Path
    size: int
    chunks: list[GoodChunk] = field(default_factory=list)
    damaged: list[DamagedRange] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    summary_ok: bool = False
    promised: int | None = None
    promised_topics: dict[str, int] = field(default_factory=dict)
    compression: str | None = None
    salvaged: list[Message] = field(default_factory=list)
    cut: bool = False
    orphans: int = 0  # messages of good chunks whose channel record was lost

    @property
    def lost(self) -> int | None:
        """Messages the damage cost: the index's promise minus what reads, else the sum the
        damaged ranges' message indexes give (None when some range's count is unknown)."""
        kept = sum(c.messages for c in self.chunks) - self.orphans + len(self.salvaged)
        if self.promised is not None:
            return max(self.promised - kept, 0)
        counts = [d.lost for d in self.damaged]
        return None if None in counts else sum(counts) + self.orphans

    def messages(self) -> Iterator[ScannedMessage]:
        """The messages of the good chunks (and salvaged ones) in log-time order; a chunk is
        decompressed only when the merge reaches its first log time."""
        order = sorted(range(len(self.chunks)), key=lambda i: (self.chunks[i].start_ns, i))
        heap: list = []
        budget = MergeBudget(f"MCAP file {str(self.path)!r}")
        with open(self.path, "rb") as stream:
            k = 0
            while k < len(order) or heap:
                while k < len(order) and (not heap or
                                          self.chunks[order[k]].start_ns <= heap[0][0]):
                    i = order[k]
                    messages = _chunk_messages(stream, self.chunks[i])
                    budget.hold(messages)
                    for j, message in enumerate(messages):
                        heapq.heappush(heap, (message.log_time, i, j, message))
                    k += 1
                *_, message = heapq.heappop(heap)
                budget.release(message)
                item = self._item(message)
                if item is not None:
                    yield item
        for message in sorted(self.salvaged, key=lambda m: m.log_time):
            item = self._item(message)
            if item is not None:
                yield item

    def _item(self, message: Message) -> ScannedMessage | None:
        channel = self.channels.get(message.channel_id)
        if channel is None:
            return None
        return ScannedMessage(self.schemas.get(channel.schema_id), channel, message)


def _chunk_messages(stream, chunk: GoodChunk) -> list[Message]:
    stream.seek(chunk.offset)
    data = stream.read(chunk.end - chunk.offset)
    checked = _check_chunk(data, 0, len(data))
    if isinstance(checked, str):  # the file changed under us
        raise ValueError(f"chunk at byte {chunk.offset} no longer reads: {checked}")
    return [r for r in checked[1] if isinstance(r, Message)]


def _check_chunk(data, pos: int, limit: int):
    """(end, records, raw, header fields) of a chunk at ``pos`` whose CRC holds, else why not.

    The extent comes from the chunk's own fields (not the record's length, which may be the
    damaged part); the records are decompressed without trusting the stored uncompressed size
    and then checked and parsed by ``breakup_chunk``.
    """
    body = pos + _HEAD.size
    if body + _MIN_CHUNK_BODY > limit:
        return "the file ends inside a chunk record"
    start_ns, end_ns, _, crc, name_length = _CHUNK_FIXED.unpack_from(data, body)
    if name_length > 8:
        return "a chunk record does not read (compression name length)"
    at = body + _CHUNK_FIXED.size
    name = bytes(data[at:at + name_length])
    try:
        compression = name.decode("ascii")
    except UnicodeDecodeError:
        compression = None
    if compression not in _COMPRESSIONS:
        return f"a chunk record does not read (compression {name!r})"
    at += name_length
    (records_length,) = struct.unpack_from("<Q", data, at)
    at += 8
    if at + records_length > limit:
        declared = _HEAD.unpack_from(data, pos)[1]
        return (f"the file ends inside a chunk record ({limit - body} of {declared} bytes)"
                if limit - body < declared else "a chunk record runs past the data section")
    if crc == 0:
        return "a chunk record without CRC (cannot be checked)"
    if records_length > MAX_CHUNK_BYTES + 2**16:
        return (f"a chunk record of {records_length:,} bytes, more than the "
                f"{MAX_CHUNK_BYTES:,} a chunk may hold (the readers' ceiling)")
    try:
        raw = decompress_chunk(compression, bytes(data[at:at + records_length]))
        records = breakup_chunk(ChunkRecord(compression="", data=raw, message_start_time=start_ns,
                                            message_end_time=end_ns, uncompressed_crc=crc,
                                            uncompressed_size=len(raw)), validate_crc=True)
    except ChunkLimitError as exc:
        return str(exc)
    except Exception as exc:  # noqa: BLE001 - decompression and CRC errors of assorted types
        return f"chunk fails its CRC or does not decompress ({type(exc).__name__})"
    fields = {"log-time start": start_ns, "log-time end": end_ns,
              "uncompressed size": _CHUNK_FIXED.unpack_from(data, body)[2],
              "record length": _HEAD.unpack_from(data, pos)[1], "body": at + records_length - body}
    return at + records_length, records, raw, fields


def _message_index(raw: bytes) -> dict[int, list[tuple[int, int]]]:
    """channel id -> [(log time, offset)] of the message records in decompressed chunk data."""
    out: dict[int, list] = {}
    pos = 0
    while pos + _HEAD.size <= len(raw):
        opcode, length = _HEAD.unpack_from(raw, pos)
        if opcode == Opcode.MESSAGE:
            channel, _, log_time = _MESSAGE_KEY.unpack_from(raw, pos + _HEAD.size)
            out.setdefault(channel, []).append((log_time, pos))
        pos += _HEAD.size + length
    return out


def _read_message_index(data, pos: int, limit: int):
    """(end, channel id, entries) of a message index record at ``pos`` whose lengths agree."""
    if pos + _HEAD.size + 6 > limit:
        return None
    opcode, length = _HEAD.unpack_from(data, pos)
    if opcode != Opcode.MESSAGE_INDEX or pos + _HEAD.size + length > limit:
        return None
    channel, entries_length = struct.unpack_from("<HI", data, pos + _HEAD.size)
    if length != 6 + entries_length or entries_length % 16:
        return None
    flat = struct.unpack_from(f"<{entries_length // 8}Q", data, pos + _HEAD.size + 6)
    return pos + _HEAD.size + length, channel, list(zip(flat[::2], flat[1::2], strict=True))


class _Walker:
    """The state of one survey (see :func:`survey_file`)."""

    def __init__(self, path: Path, data, size: int):
        self.out = FileSurvey(path, size)
        self.data, self.size = data, size
        self.index_offsets: list[int] = []  # chunk offsets the summary names (trusted or not)
        self.previous: dict | None = None  # channel id -> [(log time, offset)] of the last chunk
        self.unchecked: list = []  # schema and channel records of a summary failing its CRC
        self.loose: list = []  # ... and of chunks failing theirs, as far as they read
        self.declared: dict | None = None  # topic -> (type, QoS YAML) of rosbag2's metadata

    def damage(self, start, end, reason, lost=0, topics=(), span=(None, None)):
        self.out.damaged.append(DamagedRange(self.out.path, start, end, reason, lost,
                                             tuple(topics), *span))

    def accept(self, pos: int, checked) -> int:
        end, records, raw, fields = checked
        index = _message_index(raw)
        times = [t for entries in index.values() for t, _ in entries]
        wrong = [name for name, ok in (
            ("log-time start", fields["log-time start"] == min(times, default=0)),
            ("log-time end", fields["log-time end"] == max(times, default=0)),
            ("uncompressed size", fields["uncompressed size"] == len(raw)),
            ("record length", fields["record length"] == fields["body"])) if not ok]
        if wrong:  # fields outside the CRC: the messages are whole, the header is not
            self.damage(pos, pos + _HEAD.size + _CHUNK_FIXED.size, "a chunk whose CRC holds "
                        f"has a wrong {' and '.join(wrong)} in its header")
        for record in records:
            if isinstance(record, Schema):
                self.out.schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                self.out.channels.setdefault(record.id, record)
        if self.out.compression is None:
            self.out.compression = _compression_of(self.data, pos)
        self.out.chunks.append(GoodChunk(pos, end, min(times, default=0), max(times, default=0),
                                         len(times), {c: len(e) for c, e in index.items()}))
        self.previous = index  # to check the message indexes that follow it
        return end

    def next_chunk(self, after: int, limit: int):
        """The first CRC-valid chunk starting after byte ``after``: (offset, checked) or None."""
        candidates = {p for p in self.index_offsets if after < p < limit}
        for match in re.finditer(rb"\x06", memoryview(self.data)[after + 1:limit]):
            p = after + 1 + match.start()
            if p + _HEAD.size + _MIN_CHUNK_BODY > limit:
                break
            length = _HEAD.unpack_from(self.data, p)[1]
            if _MIN_CHUNK_BODY <= length <= limit - p - _HEAD.size:
                candidates.add(p)
        for p in sorted(candidates):
            checked = _check_chunk(self.data, p, limit)
            if not isinstance(checked, str):
                return p, checked
        return None

    def lost_in(self, start: int, end: int, previous: dict | None):
        """(messages, topics, span) the message indexes in bytes [start, end) list, leaving
        out those that match the good chunk before the range; (None, (), span) if none read."""
        counts: dict[int, int] = {}
        times: list[int] = []
        found = False
        before = set() if previous is None else {e for v in previous.values() for e in v}
        for match in re.finditer(rb"\x07", memoryview(self.data)[start:end]):
            read = _read_message_index(self.data, start + match.start(), end)
            if read is None:
                continue
            _, channel, entries = read
            found = True
            if 2 * sum(e in before for e in entries) > len(entries):
                continue  # the chunk before's own index, damaged or not: nothing lost
            counts[channel] = counts.get(channel, 0) + len(entries)
            times.extend(t for t, _ in entries)
        if not found:
            return None, (), (None, None)
        topics = sorted(counts.items())  # channel ids: named once every channel is known
        return sum(counts.values()), topics, (min(times, default=None), max(times, default=None))

    def topic(self, channel_id: int) -> str:
        channel = self.out.channels.get(channel_id)
        return channel.topic if channel is not None else f"channel {channel_id}"


def _compression_of(data, pos: int) -> str:
    at = pos + _HEAD.size + _CHUNK_FIXED.size
    return bytes(data[at:at + _CHUNK_FIXED.unpack_from(data, pos + _HEAD.size)[-1]]).decode()


def survey_file(path) -> FileSurvey:
    """Find every CRC-valid chunk of an MCAP file and every damaged range (module docstring).

    A file without the MCAP magic and without any valid chunk gives a survey with no chunks
    and one damaged range covering it; the caller decides whether that is an error.
    """
    path = Path(path)
    with open(path, "rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        if size == 0:
            out = FileSurvey(path, 0, cut=True)
            out.damaged.append(DamagedRange(path, 0, 0, "empty file (0 bytes)", None))
            return out
        with mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as data:
            walker = _Walker(path, data, size)
            _walk(walker)
            del walker.data  # no view may outlive the map
            return walker.out


def _walk(w: _Walker) -> None:
    data, size, out = w.data, w.size, w.out
    limit = _summary(w)  # where the data section ends, if the footer says so
    if data[:len(MCAP_MAGIC)] != MCAP_MAGIC:
        w.damage(0, min(len(MCAP_MAGIC), size), "no MCAP magic at the start")
    pos = len(MCAP_MAGIC)
    header_ok = False
    if pos + _HEAD.size <= limit and data[pos] == Opcode.HEADER:
        length = _HEAD.unpack_from(data, pos)[1]
        try:
            header = Header.read(ReadDataStream(_bytes_io(data, pos + _HEAD.size, length)))
            strings = len(header.profile.encode()) + len(header.library.encode())
            header_ok = (pos + _HEAD.size + length <= limit and header.profile.isprintable()
                         and 8 + strings == length)
        except Exception:  # noqa: BLE001 - a damaged header record
            header_ok = False
        if header_ok:
            pos += _HEAD.size + length
    if not header_ok:  # the first chunk is found by the resync below
        found = w.next_chunk(pos - 1, limit)
        end = found[0] if found else limit
        w.damage(pos, end, "the header record does not read")
        pos = end
    data_end = None
    stopped = False  # at damage with nothing readable after it
    while pos < limit:
        reason = None
        if pos + _HEAD.size > limit:
            reason = "the file ends inside a record header"
        else:
            opcode, length = _HEAD.unpack_from(data, pos)
            if opcode == Opcode.MESSAGE_INDEX:
                read = _read_message_index(data, pos, limit)
                if read is not None:
                    end, channel, entries = read
                    if w.previous is not None and w.previous.get(channel) == entries:
                        pos = end
                        continue
                    reason = "a message index that does not match the chunk before it"
                else:
                    reason = "a message index record does not read"
            elif opcode == Opcode.DATA_END and length == 4 and pos + 13 <= limit:
                data_end = pos
                break
            elif opcode == Opcode.METADATA and _reads_whole(Metadata, data, pos, limit):
                w.declared = _declared_topics(data, pos) or w.declared
                pos += _HEAD.size + length  # rosbag2's metadata record, at the end
                continue
            else:
                checked = _check_chunk(data, pos, limit)  # also a chunk whose opcode flipped
                if not isinstance(checked, str):
                    pos = w.accept(pos, checked)
                    continue
                reason = (checked if opcode == Opcode.CHUNK else
                          f"invalid record opcode 0x{opcode:02x}" if opcode not in _NAMES
                          else f"a {_NAMES[opcode]} record where the data section has none")
        w.loose.extend(_loose_records(data, pos, limit))
        found = w.next_chunk(pos, limit)
        end = found[0] if found else _data_end_after(data, pos, limit)
        lost, topics, span = w.lost_in(pos, end, w.previous)
        if found is None and out.cut and data[pos] == Opcode.CHUNK:
            _salvage(w, pos)
            reason = (f"the file ends inside a chunk record ({size - pos - _HEAD.size} of "
                      f"{_HEAD.unpack_from(data, pos)[1]} bytes)"
                      if pos + _HEAD.size <= size else reason)
        w.damage(pos, end, reason, lost, topics, span)
        if found is None:
            data_end, stopped = (end if end < limit else None), True
            break
        pos = w.accept(*found)
    if data_end is None and not stopped:
        w.damage(size, size, "the file ends without a footer (not closed)", None)
    elif data_end is not None:
        crc = struct.unpack_from("<I", data, data_end + _HEAD.size)[0]
        if crc and zlib.crc32(memoryview(data)[:data_end]) != crc:
            w.damage(0, data_end, "the data section CRC does not match")
    _agreeing_copies(w)
    out.orphans = sum(n for c in out.chunks for ch, n in c.counts.items()
                      if ch not in out.channels)
    if out.orphans:
        w.damage(0, 0, f"{out.orphans} messages of CRC-valid chunks are on channels whose "
                 "channel record was lost", out.orphans)
    out.damaged = sorted((replace(d, topics=tuple(sorted(
        (w.topic(c) if isinstance(c, int) else c, n) for c, n in d.topics)))
        for d in out.damaged), key=lambda d: (d.start, d.end))


def _reads_whole(record_type, data, pos: int, limit: int) -> bool:
    """Whether the record at ``pos`` fits and reads to exactly its length."""
    length = _HEAD.unpack_from(data, pos)[1]
    if pos + _HEAD.size + length > limit:
        return False
    stream = ReadDataStream(_bytes_io(data, pos + _HEAD.size, length))
    try:
        record_type.read(stream)
    except Exception:  # noqa: BLE001 - a damaged record
        return False
    return stream.count == length


def _data_end_after(data, pos: int, limit: int) -> int:
    """The data end record after ``pos`` (opcode 0x0f, length 4), else ``limit``."""
    at = data.find(b"\x0f\x04\x00\x00\x00\x00\x00\x00\x00", pos + 1, limit)
    return limit if at < 0 else at


def _bytes_io(data, start: int, length: int):
    import io

    return io.BytesIO(bytes(data[start:start + length]))


def _summary(w: _Walker) -> int:
    """Check the footer and summary; note their damage; return where the data section ends
    (the summary start if the footer reads, else the file size). Sets ``summary_ok``,
    ``promised``, the summary's schemas and channels (only if its CRC holds) and the chunk
    offsets of its chunk index (as resync candidates, checked by their CRC like any other)."""
    data, size, out = w.data, w.size, w.out
    tail = _FOOTER.size + len(MCAP_MAGIC)
    if size < len(MCAP_MAGIC) + tail or data[size - len(MCAP_MAGIC):] != MCAP_MAGIC:
        if size >= tail and data[size - tail] == Opcode.FOOTER:
            w.damage(size - len(MCAP_MAGIC), size, "no MCAP magic at the end")
        else:
            out.cut = True
            return size
    footer = size - tail
    opcode, length, start, offsets, crc = _FOOTER.unpack_from(data, footer)
    if opcode != Opcode.FOOTER or length != _FOOTER.size - _HEAD.size:
        w.damage(footer, size, "the footer record does not read")
        return size
    if start == 0:
        return footer
    if not len(MCAP_MAGIC) < start <= footer:
        w.damage(footer, size, "the footer's summary start is outside the file")
        return size
    records = _records(data, start, footer)
    for record in records:
        if isinstance(record, ChunkIndex):
            w.index_offsets.append(record.chunk_start_offset)
    if crc == 0 or zlib.crc32(memoryview(data)[start:footer + _FOOTER.size - 4]) != crc:
        w.unchecked = [r for r in records if isinstance(r, Schema | Channel)]
        w.damage(start, size, "the summary fails the footer's CRC" if crc else
                 "the summary has no CRC (cannot be checked)")
        return start
    out.summary_ok = True
    channels = {}
    for record in records:
        if isinstance(record, Schema):
            out.schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Statistics):
            out.promised = record.message_count
            counts = record.channel_message_counts
            out.promised_topics = {}
            for cid, n in counts.items():
                topic = channels[cid].topic if cid in channels else f"channel {cid}"
                out.promised_topics[topic] = out.promised_topics.get(topic, 0) + n
    out.channels.update(channels)
    return start


def _records(data, start: int, end: int) -> list:
    """The schema, channel, chunk index and statistics records in [start, end), as far as
    they read (a damaged summary gives what precedes its damage)."""
    parsers = {Opcode.SCHEMA: Schema.read, Opcode.CHANNEL: Channel.read,
               Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.STATISTICS: Statistics.read}
    out = []
    pos = start
    while pos + _HEAD.size <= end:
        opcode, length = _HEAD.unpack_from(data, pos)
        if pos + _HEAD.size + length > end:
            break
        if opcode in parsers:
            try:
                out.append(parsers[opcode](ReadDataStream(
                    _bytes_io(data, pos + _HEAD.size, length))))
            except Exception:  # noqa: BLE001 - a damaged summary record ends the list
                break
        pos += _HEAD.size + length
    return out


def _agreeing_copies(w: _Walker) -> None:
    """Schemas and channels whose only good copy was lost: a record of a summary failing its
    CRC is taken when an independent copy agrees with it (one damaged copy alone is not
    trusted):

    - the same record, field for field, at the start of a chunk failing its CRC; or
    - for a channel (and its schema): rosbag2's own description of the topic, in the file's
      ``rosbag2`` metadata record or else the ``metadata.yaml`` beside it, giving the same
      type and offered QoS, with the schema's text the one the type's ``.msg`` files give
      (:func:`aero_dva.bag.schemas.message_definition`). A flipped bit in a topic, type, QoS
      or schema text then disagrees and the record is refused; a flipped channel or schema id
      names no message of the file, so nothing is decoded wrongly.
    """
    out = w.out
    for record in w.unchecked:
        known = out.schemas if isinstance(record, Schema) else out.channels
        if record.id not in known and record in w.loose:
            known[record.id] = record
    declared = w.declared if w.declared is not None else _declared_in_yaml(out.path)
    if not declared:
        return
    schemas = {r.id: r for r in w.unchecked if isinstance(r, Schema)}
    for channel in (r for r in w.unchecked if isinstance(r, Channel)):
        if channel.id in out.channels or channel.message_encoding != "cdr":
            continue
        schema = out.schemas.get(channel.schema_id) or schemas.get(channel.schema_id)
        qos = channel.metadata.get("offered_qos_profiles")
        if schema is None or declared.get(channel.topic) != (schema.name, qos):
            continue
        if schema.id not in out.schemas:
            if schema.encoding != "ros2msg" or not _is_definition_of(schema):
                continue
            out.schemas[schema.id] = schema
        out.channels[channel.id] = channel


def _declared_topics(data, pos: int) -> dict | None:
    """topic -> (type, offered QoS YAML) from rosbag2's metadata record at ``pos``."""
    from aero_dva.safe_files import parse_yaml  # depth, alias and size limits of every loader

    length = _HEAD.unpack_from(data, pos)[1]
    record = Metadata.read(ReadDataStream(_bytes_io(data, pos + _HEAD.size, length)))
    text = record.metadata.get("serialized_metadata")
    if record.name != "rosbag2" or not text:
        return None
    try:
        return _topics_of(parse_yaml(text, "rosbag2 metadata record"))
    except ValueError:
        return None


def _declared_in_yaml(path: Path) -> dict | None:
    """The same from the ``metadata.yaml`` of the bag directory holding ``path``."""
    from aero_dva.safe_files import read_yaml

    try:
        info = read_yaml(path.parent / "metadata.yaml", "bag metadata")
        return _topics_of(info["rosbag2_bagfile_information"])
    except (ValueError, OSError, KeyError, TypeError):
        return None


def _topics_of(info) -> dict | None:
    try:
        return {t["topic_metadata"]["name"]: (t["topic_metadata"]["type"],
                                              t["topic_metadata"]["offered_qos_profiles"])
                for t in info["topics_with_message_count"]}
    except (KeyError, TypeError, AttributeError):
        return None  # a damaged description vouches for nothing


def _is_definition_of(schema: Schema) -> bool:
    """Whether the schema's text is the one the type's ``.msg`` files give."""
    from aero_dva.bag.schemas import message_definition

    try:
        return schema.data.decode("utf-8") == message_definition(schema.name)
    except Exception:  # noqa: BLE001 - unknown type or undecodable text: not vouched for
        return False


def _loose_records(data, pos: int, limit: int) -> list:
    """The schema and channel records at the start of a chunk that fails its CRC, as far as
    its bytes decompress and read (unchecked: see :func:`_agreeing_copies`)."""
    body = pos + _HEAD.size
    if body + _MIN_CHUNK_BODY > limit or data[pos] != Opcode.CHUNK:
        return []
    *_, name_length = _CHUNK_FIXED.unpack_from(data, body)
    at = body + _CHUNK_FIXED.size + name_length + 8
    if name_length > 8 or at > limit:
        return []
    compression = bytes(data[at - 8 - name_length:at - 8]).decode("ascii", "replace")
    length = struct.unpack_from("<Q", data, at - 8)[0]
    try:
        raw = decompress_prefix(compression,
                                bytes(data[at:min(at + length, limit, at + MAX_CHUNK_BYTES)]))
    except Exception:  # noqa: BLE001 - nothing readable
        return []
    out, i = [], 0
    while i + _HEAD.size <= len(raw):
        opcode, length = _HEAD.unpack_from(raw, i)
        if opcode not in (Opcode.SCHEMA, Opcode.CHANNEL) or i + _HEAD.size + length > len(raw):
            break
        stream = ReadDataStream(_bytes_io(raw, i + _HEAD.size, length))
        try:
            out.append(Schema.read(stream) if opcode == Opcode.SCHEMA else Channel.read(stream))
        except Exception:  # noqa: BLE001 - the damage is here
            break
        i += _HEAD.size + length
    return out


def _salvage(w: _Walker, pos: int) -> None:
    """The whole message records at the start of the chunk the file ends inside."""
    data, out = w.data, w.out
    partial = bytes(data[pos + _HEAD.size:pos + _HEAD.size + MAX_CHUNK_BYTES + 2**16])
    if len(partial) < _CHUNK_FIXED.size:
        return
    *_, name_length = _CHUNK_FIXED.unpack_from(partial)
    start = _CHUNK_FIXED.size + name_length + 8
    if len(partial) < start:
        return
    compression = partial[_CHUNK_FIXED.size:_CHUNK_FIXED.size + name_length].decode(
        "utf-8", "replace")
    try:
        raw = decompress_prefix(compression, partial[start:])
    except Exception:  # noqa: BLE001 - an undecodable prefix holds nothing to keep
        return
    at = 0
    while at + _HEAD.size <= len(raw):
        opcode, length = _HEAD.unpack_from(raw, at)
        end = at + _HEAD.size + length
        if end > len(raw) or opcode not in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
            return
        stream = ReadDataStream(_bytes_io(raw, at + _HEAD.size, length))
        try:
            record = (Schema.read(stream) if opcode == Opcode.SCHEMA else
                      Channel.read(stream) if opcode == Opcode.CHANNEL else
                      Message.read(stream, length))
        except Exception:  # noqa: BLE001 - the cut went through this record
            return
        if isinstance(record, Schema):
            out.schemas.setdefault(record.id, record)
        elif isinstance(record, Channel):
            out.channels.setdefault(record.id, record)
        elif record.channel_id in out.channels:
            out.salvaged.append(record)
        else:
            return
        at = end
