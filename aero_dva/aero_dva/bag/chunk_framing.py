"""MCAP chunk framing for pre-framed message records: the file ``mcap.writer.Writer`` writes.

:class:`ChunkedMcapFile` takes message records already framed (opcode, length, channel,
sequence, times, CDR bytes; :data:`MESSAGE_RECORD` is their head) in batches, as the batch
recorder lays them out with numpy, and writes the rosbag2-layout MCAP file that
:class:`~aero_dva.bag.writer.BagWriter` (``mcap.writer.Writer`` with chunking, every
index, statistics, summary offsets and chunk CRCs) writes for the same messages: same records,
same chunk boundaries (a chunk ends after the message that takes it over ``chunk_size``
bytes), same message and chunk indexes, same metadata (a test compares the bytes). It exists
because the sweep recording cannot afford a Python call per message
(``bench/bench_batch_recording.py``). A split bag (one file per process) gets its
``metadata.yaml`` from :func:`close_split_bag` once every file is closed.
"""
from __future__ import annotations

import os
import struct
import threading
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import yaml

try:  # ISA-L's CRC-32 (same polynomial and values as zlib's) is 3x faster with SIMD
    from isal.isal_zlib import crc32 as _crc32
except ImportError:  # pragma: no cover - the project's environment installs isal
    _crc32 = zlib.crc32
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from aero_dva.bag.mcap_scan import MCAP_MAGIC
from aero_dva.bag.schemas import message_definition, normalize_type_name
from aero_dva.bag.writer import (
    BagSummary,
    bag_metadata,
    create_bag_directory,
    default_ros_distro,
    open_new_bag_file,
    qos_profile_yaml,
    summary_of,
    write_metadata_yaml,
)

__all__ = ["COMPRESSIONS", "MESSAGE_RECORD", "ChunkedMcapFile", "close_split_bag"]

#: Head of an MCAP message record, up to its data: opcode, record length, channel id,
#: sequence, log time, publish time (31 bytes).
MESSAGE_RECORD = struct.Struct("<BQHIQQ")
#: Chunk compressions.
COMPRESSIONS = ("none", "zstd", "lz4")
_SYNC_EVERY = 32 << 20  # [bytes] written between background fdatasyncs


class _BackgroundSync:
    """Flush what was written to the disk while the caller computes the rest.

    The bag is fsynced when it closes; without this, the page cache holds the whole file until
    then (a GB or two of dirty pages stay below the kernel's writeback threshold) and the
    disk only starts when everything is computed. A thread calls ``fdatasync`` every ``every``
    bytes, so computing and writing to disk overlap (fdatasync does not hold the GIL).
    """

    def __init__(self, fd: int, every: int):
        self._fd, self._every, self._pending = fd, every, 0
        self._wake = threading.Event()
        self._stop = False
        self._error: OSError | None = None
        self._thread = threading.Thread(target=self._run, name="bag-fdatasync", daemon=True)
        self._thread.start()

    def wrote(self, nbytes: int) -> None:
        self._pending += nbytes
        if self._pending >= self._every:
            self._pending = 0
            self._wake.set()

    def _run(self) -> None:
        sync = getattr(os, "fdatasync", os.fsync)
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._stop:
                return
            try:
                sync(self._fd)
            except OSError as exc:  # reported by stop(); the final fsync would fail too
                self._error = exc
                return

    def stop(self) -> OSError | None:
        """Join the thread (idempotent); returns its error, if any."""
        self._stop = True
        self._wake.set()
        self._thread.join()
        return self._error


class ChunkedMcapFile:
    """A rosbag2-layout MCAP bag written from batches of framed message records.

    ``file_name`` writes one file of a split bag instead: the file ``file_name`` in the
    existing ``directory``, and no ``metadata.yaml`` (:func:`close_split_bag` writes it for
    all the files). ``library`` is the writer's name in the MCAP header.
    """

    def __init__(self, directory, *, compression: str, chunk_size: int,
                 ros_distro: str | None, library: str = "aero_dva.bag.batch_recorder",
                 chunk_crc: bool = True,
                 background_sync: bool = True, file_name: str | None = None):
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {COMPRESSIONS}, got {compression!r}")
        self._crc = bool(chunk_crc)
        self._compress = _compressor(compression)
        self._compression = "" if compression == "none" else compression
        self._split = file_name is not None
        if self._split:
            self.directory, self.mcap_path = _split_file(directory, file_name)
        else:
            self.directory, self.mcap_path = create_bag_directory(directory)
        self._chunk_size = chunk_size
        self._ros_distro = default_ros_distro(ros_distro)
        self._stream = open_new_bag_file(self.mcap_path)
        self._closed = False
        self._summary: BagSummary | None = None
        self._sync = _BackgroundSync(self._stream.fileno(), _SYNC_EVERY) if background_sync \
            else None
        self._pos = 0
        self._schemas: dict[str, Schema] = {}  # type -> schema record
        self._channels: dict[str, Channel] = {}  # topic -> channel record
        self._qos: dict[str, str] = {}
        self.counts: dict[str, int] = {}  # topic -> messages written (next sequence number)
        self._stat_counts: dict[int, int] = {}  # channel id -> count, first-message order
        self._t_min: int | None = None
        self._t_max = 0
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._reset_chunk()
        self._emit(MCAP_MAGIC)
        builder = RecordBuilder()
        Header(profile="ros2", library=library).write(builder)
        self._emit(builder.end())

    # ---------------------------------------------------------------- low level
    def _emit(self, data) -> None:
        self._stream.write(data)
        size = len(data) if not isinstance(data, memoryview) else data.nbytes
        self._pos += size
        if self._sync is not None:
            self._sync.wrote(size)

    def _reset_chunk(self) -> None:
        self._pieces: list = []
        self._size = 0  # uncompressed bytes in the chunk
        self._messages = 0
        # channel id -> [(log times, offsets in the chunk), ...]; the dict's order is the
        # order of each channel's first message in the chunk (mcap's message index order)
        self._index: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        self._chunk_t_min: int | None = None
        self._chunk_t_max = 0

    def _add_record(self, data: bytes) -> None:
        """A schema or channel record goes into the open chunk (as mcap's writer does)."""
        self._pieces.append(data)
        self._size += len(data)
        if self._size > self._chunk_size:
            self._finish_chunk()

    def _finish_chunk(self) -> None:
        if self._messages == 0:
            return
        size = self._size
        crc = 0  # MCAP: 0 = no CRC to check
        if self._compression:
            data = self._pieces[0] if len(self._pieces) == 1 else b"".join(self._pieces)
            crc = _crc32(data) if self._crc else 0
            packed = [self._compress(data)]
        else:  # uncompressed: the pieces go out as they are, no joined copy
            packed = self._pieces
            if self._crc:
                for piece in packed:
                    crc = _crc32(piece, crc)
        name = self._compression.encode()
        packed_size = sum(len(p) if not isinstance(p, memoryview) else p.nbytes
                          for p in packed)
        body = 8 + 8 + 8 + 4 + 4 + len(name) + 8 + packed_size
        start = self._pos
        self._emit(struct.pack("<BQQQQI", Opcode.CHUNK, body, self._chunk_t_min,
                               self._chunk_t_max, size, crc)
                   + struct.pack("<I", len(name)) + name + struct.pack("<Q", packed_size))
        for piece in packed:
            self._emit(piece)
        index_start = self._pos
        offsets: dict[int, int] = {}
        records = []
        length = 0
        for channel, parts in self._index.items():
            entries = np.empty((sum(len(t) for t, _ in parts), 2), dtype="<u8")
            entries[:, 0] = parts[0][0] if len(parts) == 1 else np.concatenate(
                [t for t, _ in parts])
            entries[:, 1] = parts[0][1] if len(parts) == 1 else np.concatenate(
                [o for _, o in parts])
            data = entries.tobytes()
            record = struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + len(data), channel,
                                 len(data)) + data
            offsets[channel] = index_start + length
            length += len(record)
            records.append(record)
        self._emit(b"".join(records))
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=self._chunk_t_min, message_end_time=self._chunk_t_max,
            chunk_start_offset=start, chunk_length=9 + body, message_index_offsets=offsets,
            message_index_length=length, compression=self._compression,
            compressed_size=packed_size, uncompressed_size=size))
        self._reset_chunk()

    # ---------------------------------------------------------------- API
    @property
    def closed(self) -> bool:
        return self._closed

    def add_topic(self, topic: str, type_name: str, qos: str) -> int:
        """Register a topic (absolute name); returns its channel id."""
        type_name = normalize_type_name(type_name)
        if topic in self._channels:
            raise ValueError(f"topic {topic!r} is already registered")
        if type_name not in self._schemas:
            text = message_definition(type_name)
            schema = Schema(id=len(self._schemas) + 1, data=text.encode("utf-8"),
                            encoding="ros2msg", name=type_name)
            self._schemas[type_name] = schema
            builder = RecordBuilder()
            schema.write(builder)
            self._add_record(builder.end())
        channel = Channel(id=len(self._channels) + 1, topic=topic, message_encoding="cdr",
                          schema_id=self._schemas[type_name].id,
                          metadata={"offered_qos_profiles": qos})
        self._channels[topic] = channel
        self._qos[topic] = qos
        self.counts[topic] = 0
        builder = RecordBuilder()
        channel.write(builder)
        self._add_record(builder.end())
        return channel.id

    def channel_id(self, topic: str) -> int:
        return self._channels[topic].id

    def add_messages(self, records: memoryview, sizes: np.ndarray, channels: np.ndarray,
                     log_times: np.ndarray) -> None:
        """Append framed MCAP message records lying back to back in ``records``.

        ``sizes`` (m,) bytes of each record, ``channels`` (m,) channel ids, ``log_times`` (m,)
        [ns]. Sequence numbers are already in the records; :attr:`counts` is the caller's.
        The caller may reuse ``records`` afterwards: what stays in the open chunk is copied.
        """
        m = len(sizes)
        if m == 0:
            return
        ends = np.cumsum(sizes, dtype=np.int64)
        starts = ends - sizes
        self._statistics(channels, log_times)
        # Each channel's records in file order, found once for the whole batch.
        order = np.argsort(channels.astype(np.uint16), kind="stable")  # a radix sort
        ids, begin, counts = np.unique(channels[order], return_index=True, return_counts=True)
        own = [(int(c), order[b:b + n]) for c, b, n in zip(ids, begin, counts)]
        first = 0
        while first < m:
            # The chunk closes after the first message whose end passes chunk_size.
            limit = self._chunk_size - self._size + starts[first]
            last = int(np.searchsorted(ends, limit, side="right"))
            stop = min(last + 1, m)
            begin, end = int(starts[first]), int(ends[stop - 1])
            self._pieces.append(records[begin:end])
            new = []
            for channel, rows in own:
                lo, hi = np.searchsorted(rows, (first, stop))
                if hi > lo:
                    sel = rows[lo:hi]
                    if channel not in self._index:
                        new.append((int(sel[0]), channel))
                    self._index.setdefault(channel, []).append(
                        (log_times[sel], starts[sel] - begin + self._size))
            for _, channel in sorted(new):  # channels new to the chunk: in order of appearance
                self._index[channel] = self._index.pop(channel)
            low, high = int(log_times[first:stop].min()), int(log_times[first:stop].max())
            self._chunk_t_min = low if self._chunk_t_min is None else min(self._chunk_t_min, low)
            self._chunk_t_max = max(self._chunk_t_max, high)
            self._size += end - begin
            self._messages += stop - first
            if last < m:
                self._finish_chunk()
            first = stop
        self._pieces = [bytes(p) if isinstance(p, memoryview) else p for p in self._pieces]

    def _statistics(self, channels: np.ndarray, log_times: np.ndarray) -> None:
        ids, first, counts = np.unique(channels, return_index=True, return_counts=True)
        for k in np.argsort(first, kind="stable"):
            channel = int(ids[k])
            self._stat_counts[channel] = self._stat_counts.get(channel, 0) + int(counts[k])
        low, high = int(log_times.min()), int(log_times.max())
        self._t_min = low if self._t_min is None else min(self._t_min, low)
        self._t_max = max(self._t_max, high)

    def _metadata(self) -> dict:
        # rosbag2 metadata exactly as BagWriter writes it.
        topics = [(topic, self._schema_name(channel), self._qos[topic], self.counts[topic])
                  for topic, channel in self._channels.items()]
        return bag_metadata(self.mcap_path.name, topics, self._t_min, self._t_max,
                            self._ros_distro)

    def _schema_name(self, channel: Channel) -> str:
        return next(s.name for s in self._schemas.values() if s.id == channel.schema_id)

    def close(self) -> BagSummary | None:
        """Finish the MCAP file and write metadata.yaml atomically (idempotent)."""
        if self._closed:
            return self._summary
        self._closed = True
        metadata = self._metadata()
        try:
            builder = RecordBuilder()
            Metadata(name="rosbag2", metadata={
                "serialized_metadata": yaml.safe_dump(metadata, sort_keys=False),
                "ROS_DISTRO": self._ros_distro,
            }).write(builder)
            record = builder.end()
            self._metadata_indexes.append(
                MetadataIndex(offset=self._pos, length=len(record), name="rosbag2"))
            self._emit(record)
            self._finish_chunk()
            self._write_summary()
            self._stream.flush()
            if self._sync is not None and (error := self._sync.stop()) is not None:
                raise error
            os.fsync(self._stream.fileno())
        finally:
            if self._sync is not None:
                self._sync.stop()
            self._stream.close()
        if not self._split:
            write_metadata_yaml(self.directory, metadata)
        self._summary = summary_of(self.directory, self.mcap_path, metadata)
        return self._summary

    def _write_summary(self) -> None:
        builder = RecordBuilder()
        DataEnd(0).write(builder)
        self._emit(builder.end())
        summary_start = self._pos
        summary = RecordBuilder()
        offsets = []

        def group(opcode, records):
            begin = summary.count
            for record in records:
                record.write(summary)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + begin,
                                         group_length=summary.count - begin))

        statistics = Statistics(
            attachment_count=0, channel_count=len(self._channels),
            channel_message_counts=dict(self._stat_counts),
            chunk_count=len(self._chunk_indexes),
            message_count=sum(self._stat_counts.values()),
            metadata_count=len(self._metadata_indexes),
            message_start_time=self._t_min or 0, message_end_time=self._t_max,
            schema_count=len(self._schemas))
        group(Opcode.SCHEMA, self._schemas.values())
        group(Opcode.CHANNEL, self._channels.values())
        group(Opcode.STATISTICS, [statistics])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.ATTACHMENT_INDEX, [])
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offset_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        data = summary.end()
        crc = zlib.crc32(data)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start),
                         crc)
        self._emit(data)
        builder = RecordBuilder()
        Footer(summary_start=summary_start, summary_offset_start=offset_start,
               summary_crc=crc).write(builder)
        self._emit(builder.end())
        self._emit(MCAP_MAGIC)


def _split_file(directory, file_name: str) -> tuple[Path, Path]:
    directory = Path(directory)
    if not directory.is_dir():
        raise FileNotFoundError(f"bag directory {str(directory)!r} does not exist")
    if Path(file_name).name != file_name or not file_name.endswith(".mcap"):
        raise ValueError(f"file_name must be a plain *.mcap name, got {file_name!r}")
    path = directory / file_name
    if path.exists():
        raise FileExistsError(f"bag file {str(path)!r} exists: a bag is never overwritten")
    return directory, path


def close_split_bag(directory, parts: Sequence[BagSummary],
                    ros_distro: str | None = None) -> BagSummary:
    """Write ``metadata.yaml`` (atomically) of a bag whose files ``parts`` are, in order.

    Each part is the summary of one closed :class:`ChunkedMcapFile` with ``file_name`` set.
    rosbag2 splits bags the same way: each file a complete MCAP file with every topic's
    schema and channel, the messages in time order across the files. Returns the bag's
    summary (``mcap_path`` = the first file).
    """
    if not parts:
        raise ValueError("close_split_bag needs at least one file")
    directory = Path(directory)
    counts: dict[str, int] = {}
    types: dict[str, str] = {}
    for part in parts:
        for topic in part.topics:
            counts[topic.name] = counts.get(topic.name, 0) + topic.message_count
            types.setdefault(topic.name, topic.type_name)
    used = [p for p in parts if p.message_count]
    t_min = min((p.starting_time_ns for p in used), default=None)
    t_max = max((p.starting_time_ns + p.duration_ns for p in used), default=None)
    distro = default_ros_distro(ros_distro)
    qos = qos_profile_yaml()
    files = [(p.mcap_path.name, p.starting_time_ns, p.duration_ns, p.message_count)
             for p in parts]
    metadata = bag_metadata(parts[0].mcap_path.name,
                            [(t, types[t], qos, n) for t, n in counts.items()],
                            t_min, t_max, distro, files=files)
    write_metadata_yaml(directory, metadata)
    return summary_of(directory, parts[0].mcap_path, metadata)


def _compressor(name: str) -> Callable:
    if name == "zstd":
        import zstandard

        return zstandard.compress
    if name == "lz4":
        import lz4.frame

        return lz4.frame.compress
    return lambda data: data
