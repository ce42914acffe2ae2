"""Record simulated flights to rosbag2 MCAP bags without the ROS graph: the batch path.

The simulator node (:mod:`aero_dva_sim.simulator_node`) publishes, per block of samples,
``/clock`` then ``wing/acceleration``, ``wing/displacement``, ``wing/excitation``,
``flight/condition`` and ``dva/damper_state``, and ``/diagnostics`` when the flight ends; the
``mcap_recorder`` node writes them to a bag. This module writes the same bag directly from
:class:`~aero_dva.flight.flight_runtime.FlightBlock`s: same topics (absolute names, under an
optional namespace like the graph's), same types and ``ros2msg`` schemas, same QoS metadata as
the recorder writes (:func:`~aero_dva.bag.mcap_io.qos_profile_yaml` defaults), same field values
and header stamps as :mod:`aero_dva_sim.messages` sets (CDR from
:mod:`aero_dva.bag.cdr_encoding`).

Times. Header stamps are the node's: the first sample of the block (``t0``) for the sample
blocks and the flight condition, ``t_end`` for ``/clock``, the snapshot time for the damper
state. Log (and publish) time of every message of a block is ``t_end`` in ns: the node publishes
``/clock`` = ``t_end`` before the block, so that is the sim time a recorder on sim time stamps the
block with. Log times therefore never decrease through the file.

Two writers produce the same bytes (a test compares the files):

- ``engine="numpy"`` (default): a block run of equal length is laid out as one numpy structured
  array holding the MCAP message records of all its messages, chunked, indexed and written with
  the record layout of ``mcap.writer.Writer`` as :class:`~aero_dva.bag.mcap_io.BagWriter`
  configures it. No Python work per message.
- ``engine="bagwriter"``: one :meth:`BagWriter.write <aero_dva.bag.mcap_io.BagWriter.write>` of
  CDR bytes per message (the reference; tens of microseconds per message).

Entry points: :meth:`BatchRecorder.write_blocks` (FlightBlock objects),
:meth:`BatchRecorder.write_samples` (whole sample arrays cut into blocks, no per-block Python
objects) and :func:`record_runtime` (steps a FlightRuntime);
:func:`aero_dva.bag.sweep_recording_io.record_sweep` records a stepped sweep simulated
parallel in time. ``displacement=False`` leaves out ``wing/displacement`` (what a wing test
measures, as the recorder node's ``exclude``).

The bag is complete only when closed (``metadata.yaml`` written last, atomically), as with
:class:`~aero_dva.bag.mcap_io.BagWriter`. A split bag (``file_name``, one file per process)
gets its ``metadata.yaml`` from :func:`close_split_bag` once every file is closed.
"""
from __future__ import annotations

import math
import os
import struct
import tempfile
import threading
import time
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
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

from aero_dva.bag import cdr_encoding as cdr
from aero_dva.bag.mcap_io import (
    BagSummary,
    BagWriter,
    TopicInfo,
    bag_metadata,
    create_bag_directory,
    message_definition,
    normalize_type_name,
    qos_profile_yaml,
)

__all__ = [
    "DIAGNOSTIC_NAME",
    "ENGINES",
    "HARDWARE_ID",
    "BatchRecorder",
    "RecordedFlight",
    "close_split_bag",
    "flight_topics",
    "record_flight_blocks",
    "record_runtime",
]

#: Writers (see the module docstring).
ENGINES = ("numpy", "bagwriter")
#: DiagnosticStatus name and hardware_id of the simulator's flight diagnostics.
DIAGNOSTIC_NAME = "simulator: flight"
HARDWARE_ID = "aero_dva_sim"
_LEVELS = {"ok": 0, "warn": 1, "error": 2, "stale": 3}

# Topics of one block in the node's publish order: (key, name relative to the namespace).
_BLOCK_TOPICS = (
    ("clock", "/clock"),
    ("acceleration", "wing/acceleration"),
    ("displacement", "wing/displacement"),
    ("excitation", "wing/excitation"),
    ("condition", "flight/condition"),
    ("damper", "dva/damper_state"),
)
_TYPES = {
    "clock": cdr.CLOCK,
    "acceleration": cdr.ACCELERATION_BLOCK,
    "displacement": cdr.DISPLACEMENT_BLOCK,
    "excitation": cdr.FORCE_BLOCK,
    "condition": cdr.FLIGHT_CONDITION,
    "damper": cdr.DAMPER_STATE,
    "diagnostics": cdr.DIAGNOSTIC_ARRAY,
}
_LIBRARY = "aero_dva.bag.batch_recording_io"
_MCAP_MAGIC = struct.pack("<8B", 137, 77, 67, 65, 80, 48, 13, 10)
_RECORD_HEADER = struct.Struct("<BQHIQQ")  # MCAP message record up to its data (31 bytes)
_COMPRESSIONS = ("none", "zstd", "lz4")
_SYNC_EVERY = 32 << 20  # [bytes] written between background fdatasyncs
_ACC = ("plunge", "pitch", "leading_edge")
_DISP = ("plunge", "pitch", "leading_edge", "absorber_stroke")
_DAMPER_COLUMNS = ("time", "commanded_damping", "applied_damping", "min_damping",
                   "max_damping", "command_age", "status")


def flight_topics(namespace: str = "", damper_state: bool = True,
                  displacement: bool = True) -> dict[str, str]:
    """Topic name -> ``pkg/msg/Type`` of a recorded flight, in the node's publish order.

    ``/clock`` and ``/diagnostics`` are global; the others are relative in the graph and land
    under ``namespace`` (e.g. ``"wing1"`` -> ``/wing1/wing/acceleration``). ``damper_state``
    and ``displacement`` False leave out ``dva/damper_state`` and ``wing/displacement``.
    """
    names = _topic_names(namespace)
    return {names[k]: _TYPES[k] for k in _recorded_keys(damper_state, displacement)}


def _recorded_keys(damper_state: bool, displacement: bool) -> list[str]:
    left_out = {k for k, wanted in (("damper", damper_state), ("displacement", displacement))
                if not wanted}
    return [k for k, _ in _BLOCK_TOPICS if k not in left_out] + ["diagnostics"]


def _topic_names(namespace: str) -> dict[str, str]:
    if not isinstance(namespace, str):
        raise TypeError(f"namespace must be a string, got {type(namespace).__name__}")
    prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
    names = {k: (t if t.startswith("/") else f"{prefix}/{t}") for k, t in _BLOCK_TOPICS}
    names["diagnostics"] = "/diagnostics"
    return names


# --------------------------------------------------------------------------------------------
# MCAP bag writer for pre-framed message records
# --------------------------------------------------------------------------------------------


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


class _ChunkedBag:
    """A rosbag2-layout MCAP bag written from batches of framed message records.

    The file is what :class:`~aero_dva.bag.mcap_io.BagWriter` (``mcap.writer.Writer`` with
    chunking, all indexes, statistics, summary offsets and chunk CRCs) writes for the same
    messages: same records, same chunk boundaries (a chunk ends after the message that takes
    it over ``chunk_size`` bytes), same message and chunk indexes, same metadata.

    ``file_name`` writes one file of a split bag instead: the file ``file_name`` in the
    existing ``directory``, and no ``metadata.yaml`` (:func:`close_split_bag` writes it for
    all the files).
    """

    def __init__(self, directory, *, compression: str, chunk_size: int,
                 ros_distro: str | None, library: str | None = None, chunk_crc: bool = True,
                 background_sync: bool = True, file_name: str | None = None):
        if compression not in _COMPRESSIONS:
            raise ValueError(f"compression must be one of {_COMPRESSIONS}, got {compression!r}")
        self._crc = bool(chunk_crc)
        self._compress = _compressor(compression)
        self._compression = "" if compression == "none" else compression
        self._split = file_name is not None
        if self._split:
            self.directory, self.mcap_path = _split_file(directory, file_name)
        else:
            self.directory, self.mcap_path = create_bag_directory(directory)
        self._chunk_size = chunk_size
        self._ros_distro = ros_distro or os.environ.get("ROS_DISTRO") or "jazzy"
        self._stream = open(self.mcap_path, "wb")
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
        self._emit(_MCAP_MAGIC)
        builder = RecordBuilder()
        Header(profile="ros2", library=library or _LIBRARY).write(builder)
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
        # rosbag2 metadata exactly as mcap_io.BagWriter writes it.
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
            text = yaml.safe_dump({"rosbag2_bagfile_information": metadata}, sort_keys=False)
            _atomic_write_text(self.directory / "metadata.yaml", text)
        self._summary = BagSummary(
            directory=self.directory, mcap_path=self.mcap_path,
            topics=tuple(TopicInfo(t, self._schema_name(c), self.counts[t])
                         for t, c in self._channels.items()),
            message_count=metadata["message_count"],
            starting_time_ns=metadata["starting_time"]["nanoseconds_since_epoch"],
            duration_ns=metadata["duration"]["nanoseconds"])
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
        self._emit(_MCAP_MAGIC)


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

    Each part is the summary of one closed :class:`BatchRecorder` with ``file_name`` set.
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
    distro = ros_distro or os.environ.get("ROS_DISTRO") or "jazzy"
    qos = qos_profile_yaml()
    files = [(p.mcap_path.name, p.starting_time_ns, p.duration_ns, p.message_count)
             for p in parts]
    metadata = bag_metadata(parts[0].mcap_path.name,
                            [(t, types[t], qos, n) for t, n in counts.items()],
                            t_min, t_max, distro, files=files)
    text = yaml.safe_dump({"rosbag2_bagfile_information": metadata}, sort_keys=False)
    _atomic_write_text(directory / "metadata.yaml", text)
    return BagSummary(directory=directory, mcap_path=parts[0].mcap_path,
                      topics=tuple(TopicInfo(t, types[t], n) for t, n in counts.items()),
                      message_count=metadata["message_count"],
                      starting_time_ns=metadata["starting_time"]["nanoseconds_since_epoch"],
                      duration_ns=metadata["duration"]["nanoseconds"])


def _compressor(name: str) -> Callable:
    if name == "zstd":
        import zstandard

        return zstandard.compress
    if name == "lz4":
        import lz4.frame

        return lz4.frame.compress
    return lambda data: data


def _atomic_write_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# --------------------------------------------------------------------------------------------
# Block layouts: the MCAP message records of one block, as a numpy structured dtype
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)  # identity hash: cached per (n, source, channels)
class _GroupLayout:
    dtype: np.dtype
    template: np.ndarray  # uint8, one group
    sizes: np.ndarray  # record sizes in order
    keys: tuple[str, ...]


@lru_cache(maxsize=32)
def _group_layout(n: int, source: str | None, keys: tuple[str, ...],
                  channels: tuple[int, ...]) -> _GroupLayout:
    """One block's records of the topics ``keys`` (in publish order; "damper" needs
    ``source``) on MCAP ``channels``."""
    make = {
        "clock": cdr.clock_layout,
        "acceleration": lambda: cdr.acceleration_block_layout(n),
        "displacement": lambda: cdr.displacement_block_layout(n),
        "excitation": lambda: cdr.force_block_layout(n),
        "condition": cdr.flight_condition_layout,
        "damper": lambda: cdr.damper_state_layout(source),
    }
    layouts = {key: make[key]() for key in keys}
    fields: dict[str, tuple] = {}
    template = bytearray()
    sizes = []
    for (key, layout), channel in zip(layouts.items(), channels, strict=True):
        base = len(template)
        template += _RECORD_HEADER.pack(Opcode.MESSAGE, 22 + layout.size, channel, 0, 0, 0)
        template += layout.template
        fields[f"{key}.sequence"] = (np.dtype("<u4"), base + 11)
        fields[f"{key}.log_time"] = (np.dtype("<u8"), base + 15)
        fields[f"{key}.publish_time"] = (np.dtype("<u8"), base + 23)
        fields.update(layout.dtype_fields(offset=base + _RECORD_HEADER.size, prefix=f"{key}."))
        sizes.append(_RECORD_HEADER.size + layout.size)
    dtype = np.dtype({"names": list(fields), "formats": [d for d, _ in fields.values()],
                      "offsets": [o for _, o in fields.values()], "itemsize": len(template)})
    return _GroupLayout(dtype, np.frombuffer(bytes(template), dtype=np.uint8),
                        np.array(sizes, dtype=np.int64), tuple(layouts))


@dataclass(frozen=True)
class _SampleBlock:
    """What :meth:`BatchRecorder.write_blocks` reads of a FlightBlock."""

    first_index: int
    t0: float
    t_end: float
    force: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    displacements: np.ndarray
    accelerations: np.ndarray


@dataclass(frozen=True)
class _Snapshot:
    """What :meth:`BatchRecorder.write_blocks` reads of a DamperSnapshot."""

    time: float
    commanded_damping: float
    applied_damping: float
    min_damping: float
    max_damping: float
    command_age: float
    status: int
    source: str


def _snapshot_values(snapshots: Sequence) -> dict[str, np.ndarray]:
    rows = [(s.time, s.commanded_damping, s.applied_damping, s.min_damping, s.max_damping,
             s.command_age, int(s.status)) for s in snapshots]
    table = np.array(rows, dtype=np.float64).reshape(-1, 7)
    status = table[:, 6]
    if np.any((status < 0) | (status > 255) | (status != np.round(status))):
        raise ValueError("damper_states: status must be an integer in 0..255")
    names = ("time", "commanded_damping", "applied_damping", "min_damping", "max_damping",
             "command_age", "status")
    return dict(zip(names, table.T))


# --------------------------------------------------------------------------------------------
# Recorder
# --------------------------------------------------------------------------------------------


class BatchRecorder:
    """Write flight blocks to a bag as the simulator node and the recorder would.

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create; it must not exist or be empty.
    sample_rate : float
        [Hz] sample rate written into the sample blocks (the flight's).
    namespace : str
        Namespace of the simulator node ("" = none): ``/<ns>/wing/acceleration`` etc.
    damper_state : bool
        Record ``dva/damper_state`` (then every :meth:`write_blocks` call needs snapshots).
    displacement : bool
        Record ``wing/displacement`` (the model's displacement truth; False records only what
        a wing test measures, as the recorder node's ``exclude`` does; the displacements
        given to the write methods are then ignored and may be None).
    compression : {"none", "zstd", "lz4"}
        Chunk compression. "none" by default: a flight's bag shrinks by about 14 % with zstd,
        which takes several times longer than encoding and writing it uncompressed.
    chunk_size : int
        [bytes] uncompressed MCAP chunk size.
    ros_distro : str, optional
        Written to the metadata; default ``$ROS_DISTRO`` or "jazzy".
    engine : {"numpy", "bagwriter"}
        How the bag is written (see the module docstring); both give the same messages.
    chunk_crc : bool
        Write each chunk's CRC-32 (True, as ``mcap``'s writer does by default). False writes
        0, "not computed" in the MCAP specification, and saves hashing every byte (about
        0.7 ms per MB here); readers then cannot detect a flipped byte inside a chunk.
        Only with ``engine="numpy"``.
    file_name : str, optional
        Write one file of a split bag (``engine="numpy"`` only): ``bag_dir`` exists,
        ``file_name`` (``*.mcap``) is created in it, and :func:`close_split_bag` writes the
        bag's ``metadata.yaml`` once every file is closed.
    first_block : int
        Blocks the files before this one hold: the sequence numbers of the block topics
        start there (0 for the first or only file).

    Notes
    -----
    Topics are registered in the node's publish order, ``/diagnostics`` last, before any
    message. Use as a context manager; :meth:`close` is idempotent and runs on errors too.
    """

    def __init__(self, bag_dir, sample_rate: float, *, namespace: str = "",
                 damper_state: bool = True, displacement: bool = True,
                 compression: str = "none",
                 chunk_size: int = 1 << 20, ros_distro: str | None = None,
                 engine: str = "numpy", chunk_crc: bool = True, file_name: str | None = None,
                 first_block: int = 0):
        rate = float(sample_rate)
        if not (math.isfinite(rate) and rate > 0.0):
            raise ValueError(f"sample_rate must be a finite rate > 0 Hz, got {sample_rate!r}")
        if engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
        if compression not in _COMPRESSIONS:
            raise ValueError(f"compression must be one of {_COMPRESSIONS}, got {compression!r}")
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
            raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
        if not chunk_crc and engine != "numpy":
            raise ValueError("chunk_crc=False needs engine='numpy' (BagWriter always hashes)")
        if file_name is not None and engine != "numpy":
            raise ValueError("file_name (a split bag) needs engine='numpy'")
        if isinstance(first_block, bool) or not isinstance(first_block, (int, np.integer)) \
                or first_block < 0:
            raise ValueError(f"first_block must be an integer >= 0, got {first_block!r}")
        self.sample_rate = rate
        self.engine = engine
        self.damper_state = bool(damper_state)
        self.displacement = bool(displacement)
        names = _topic_names(namespace)
        self.topics = {k: names[k]
                       for k in _recorded_keys(self.damper_state, self.displacement)}
        qos = qos_profile_yaml()
        if engine == "numpy":
            self._bag = _ChunkedBag(bag_dir, compression=compression, chunk_size=chunk_size,
                                    ros_distro=ros_distro, chunk_crc=chunk_crc,
                                    file_name=file_name)
        else:
            self._bag = BagWriter(bag_dir, compression=compression, chunk_size=chunk_size,
                                  ros_distro=ros_distro)
        # Sequence numbers go on across the files of a split bag; /diagnostics is not per block
        self._first = {topic: 0 if key == "diagnostics" else int(first_block)
                       for key, topic in self.topics.items()}
        self._counts = dict(self._first)
        # The records of the last block runs, reused (fresh memory costs a page fault per 4 KiB)
        self._records: dict[tuple, np.ndarray] = {}
        try:
            for key, topic in self.topics.items():
                self._bag.add_topic(topic, _TYPES[key], qos)
        except BaseException:
            self.close()
            raise

    @property
    def directory(self) -> Path:
        return self._bag.directory

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far per topic (into this file)."""
        return {topic: n - self._first[topic] for topic, n in self._counts.items()}

    def __enter__(self) -> BatchRecorder:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    def close(self) -> BagSummary | None:
        """Close the bag (idempotent); returns what was written."""
        return self._bag.close()

    # ---------------------------------------------------------------- blocks
    def write_blocks(self, blocks: Sequence, damper_states: Sequence | None = None) -> None:
        """Write blocks (and the damper snapshot taken after each) in the node's order.

        Parameters
        ----------
        blocks : sequence of FlightBlock
            ``first_index``, ``t0``, ``t_end`` [s], ``force`` (n,) [N], ``airspeed`` and
            ``density`` (n,) (the first sample goes into flight/condition),
            ``displacements`` (4, n), ``accelerations`` (3, n). Consecutive blocks of equal
            length (and damper source) are encoded together.
        damper_states : sequence of DamperSnapshot, optional
            One per block; required when the recorder records ``dva/damper_state``.

        Raises
        ------
        ValueError
            Bad shapes, times that are not finite or negative, a length mismatch.
        """
        blocks = list(blocks)
        if self.damper_state:
            if damper_states is None:
                raise ValueError("damper_states is required: this recorder writes "
                                 "dva/damper_state (or create it with damper_state=False)")
            damper_states = list(damper_states)
            if len(damper_states) != len(blocks):
                raise ValueError(f"damper_states has {len(damper_states)} snapshots for "
                                 f"{len(blocks)} blocks")
        elif damper_states is not None:
            raise ValueError("damper_states given, but this recorder has no dva/damper_state")
        if not blocks:
            return
        self._check_open()
        lengths = [np.size(b.force) if not hasattr(b.force, "shape") else b.force.shape[-1]
                   for b in blocks]
        sources = [s.source for s in damper_states] if self.damper_state else None
        start = 0
        for stop in range(1, len(blocks) + 1):
            if stop < len(blocks) and lengths[stop] == lengths[start] and (
                    sources is None or sources[stop] == sources[start]):
                continue
            self._write_run(blocks[start:stop],
                            damper_states[start:stop] if sources is not None else None,
                            lengths[start], sources[start] if sources is not None else None,
                            start)
            start = stop

    def _check_open(self) -> None:
        if self._bag.closed:
            raise ValueError(f"bag {str(self.directory)!r} is closed")

    def _write_run(self, blocks, snapshots, n: int, source, offset: int) -> None:
        if n == 0:
            raise ValueError(f"blocks[{offset}] has no samples")
        t0 = np.array([b.t0 for b in blocks], dtype=np.float64)
        t_end = np.array([b.t_end for b in blocks], dtype=np.float64)
        if not (np.all(np.isfinite(t0)) and np.all(np.isfinite(t_end))):
            raise ValueError("blocks: t0 and t_end must be finite")
        if t0.min() < 0.0 or t_end.min() < 0.0:
            raise ValueError("blocks: t0 and t_end must be >= 0 s (bag log times are unsigned)")
        first_index = np.array([b.first_index for b in blocks])
        if first_index.dtype.kind not in "iu" or first_index.min() < 0:
            raise ValueError("blocks: first_index must be integers >= 0")
        ns_t0 = cdr.stamps_from_seconds(t0, "blocks t0")
        ns_end = cdr.stamps_from_seconds(t_end, "blocks t_end")
        if self.engine == "bagwriter":
            for name, shape in (("accelerations", (3, n)), ("displacements", (4, n)),
                                ("force", (n,))):
                if name != "displacements" or self.displacement:
                    _stack([getattr(b, name) for b in blocks], shape, name, offset)
            self._write_run_messages(blocks, snapshots, ns_end)
        else:
            self._write_run_numpy(blocks, snapshots, n, source, offset, first_index, ns_t0,
                                  ns_end)

    def _write_run_messages(self, blocks, snapshots, ns_end) -> None:
        rate = self.sample_rate
        for k, block in enumerate(blocks):
            log = int(ns_end[k])
            messages = [
                ("clock", cdr.encode_clock(block.t_end)),
                ("acceleration", cdr.encode_acceleration_block(
                    block.t0, rate, block.first_index, block.accelerations)),
            ]
            if self.displacement:
                messages.append(("displacement", cdr.encode_displacement_block(
                    block.t0, rate, block.first_index, block.displacements)))
            messages += [
                ("excitation", cdr.encode_force_block(
                    block.t0, rate, block.first_index, block.force)),
                ("condition", cdr.encode_flight_condition(
                    block.t0, block.airspeed[0], block.density[0])),
            ]
            if snapshots is not None:
                messages.append(("damper", cdr.encode_damper_state(snapshots[k])))
            for key, data in messages:
                topic = self.topics[key]
                self._bag.write(topic, data, log)
                self._counts[topic] += 1

    def _write_run_numpy(self, blocks, snapshots, n, source, offset, first_index, ns_t0,
                         ns_end) -> None:
        acc = _stack([b.accelerations for b in blocks], (3, n), "accelerations", offset)
        force = _stack([b.force for b in blocks], (n,), "force", offset)
        samples = {f"acceleration.{name}": acc[:, i] for i, name in enumerate(_ACC)}
        if self.displacement:
            disp = _stack([b.displacements for b in blocks], (4, n), "displacements", offset)
            samples.update({f"displacement.{name}": disp[:, i]
                            for i, name in enumerate(_DISP)})
        samples["excitation.aileron_force"] = force
        damper = _snapshot_values(snapshots) if snapshots is not None else None
        self._encode_run(n, source, first_index, ns_t0, ns_end, samples,
                         [b.airspeed[0] for b in blocks], [b.density[0] for b in blocks], damper)

    def _encode_run(self, n: int, source, first_index, ns_t0, ns_end, samples: dict,
                    airspeed, density, damper: dict | None) -> None:
        """Encode and append ``k`` blocks of ``n`` samples in the node's message order.

        ``samples`` maps a record field (``"acceleration.plunge"`` ...) to (k, n) values (any
        strides); ``airspeed``, ``density`` (k,) and ``damper`` columns (k,) (``time`` [s]
        and the DamperState fields) are per block.
        """
        keys = tuple(k for k, _ in _BLOCK_TOPICS if k in self.topics)
        channels = tuple(self._bag.channel_id(self.topics[k]) for k in keys)
        group = _group_layout(n, source, keys, channels)
        count = len(ns_end)
        raw = self._records.get((group, count))
        if raw is None:  # the constant bytes stay valid while the layout is the same
            if len(self._records) > 4:
                self._records.clear()
            raw = self._records[(group, count)] = np.tile(group.template, count)
        rows = raw.view(group.dtype)
        sec0, nsec0 = cdr.split_stamps(ns_t0, "blocks t0")
        for key in group.keys:
            topic = self.topics[key]
            rows[f"{key}.sequence"] = np.arange(self._counts[topic], self._counts[topic] + count)
            rows[f"{key}.log_time"] = ns_end
            rows[f"{key}.publish_time"] = ns_end
            if key in ("acceleration", "displacement", "excitation", "condition"):
                rows[f"{key}.stamp_sec"] = sec0
                rows[f"{key}.stamp_nanosec"] = nsec0
            if key in ("acceleration", "displacement", "excitation"):
                rows[f"{key}.sample_rate"] = self.sample_rate
                rows[f"{key}.first_sample_index"] = first_index
        rows["clock.stamp_sec"], rows["clock.stamp_nanosec"] = cdr.split_stamps(ns_end)
        for field, values in samples.items():
            rows[field] = values
        rows["condition.airspeed"] = airspeed
        rows["condition.air_density"] = density
        if damper is not None:
            values = dict(damper)
            sec, nsec = cdr.split_stamps(
                cdr.stamps_from_seconds(values.pop("time"), "damper_states time"))
            rows["damper.stamp_sec"], rows["damper.stamp_nanosec"] = sec, nsec
            for name, column in values.items():
                rows[f"damper.{name}"] = column
        per_block = len(group.keys)
        self._bag.add_messages(
            memoryview(raw), np.tile(group.sizes, count), np.tile(np.array(channels), count),
            np.repeat(ns_end.astype(np.uint64), per_block))
        for key in group.keys:
            topic = self.topics[key]
            self._counts[topic] += count
            self._bag.counts[topic] = self._counts[topic] - self._first[topic]

    # ---------------------------------------------------------------- sample arrays
    def write_samples(self, first_index: int, accelerations, displacements, force, *,
                      block_size: int, airspeed, density, damper: Mapping | None = None,
                      source: str | None = None) -> int:
        """Write consecutive samples as blocks of ``block_size`` (the last may be shorter).

        The same messages as :meth:`write_blocks` with blocks ``first_index + j block_size``
        (t0 = first sample / rate, t_end = one past the last sample / rate, as FlightRuntime
        sets them), without FlightBlock objects: one vectorised encoding for all blocks.

        Parameters
        ----------
        first_index : int
            Index of the first sample since the start of the flight (>= 0).
        accelerations : (3, T); displacements : (4, T) or None; force : (T,)
            Time on the last axis (any strides), T >= 1. ``displacements`` is ignored (may
            be None) when the recorder records no ``wing/displacement``.
        block_size : int
            Samples per block.
        airspeed, density : (k,)
            [m/s], [kg/m^3] at each block's first sample (flight/condition), k = ceil(T / n).
        damper : mapping of (k,) arrays, optional
            ``time`` [s], ``commanded_damping``, ``applied_damping``, ``min_damping``,
            ``max_damping`` [N s/m], ``command_age`` [s], ``status`` (0..255); required
            when the recorder writes dva/damper_state.
        source : str
            The damper state's ``source`` (one for all blocks).

        Returns
        -------
        int
            Blocks written.
        """
        self._check_open()
        if isinstance(block_size, bool) or not isinstance(block_size, (int, np.integer)) \
                or block_size < 1:
            raise ValueError(f"block_size must be a positive integer, got {block_size!r}")
        if isinstance(first_index, bool) or not isinstance(first_index, (int, np.integer)) \
                or first_index < 0:
            raise ValueError(f"first_index must be an integer >= 0, got {first_index!r}")
        acc = np.asarray(accelerations, dtype=np.float64)
        force = np.asarray(force, dtype=np.float64)
        total = force.shape[-1] if force.ndim == 1 else -1
        arrays = [("accelerations", acc, 3)]
        if self.displacement:
            disp = np.asarray(displacements, dtype=np.float64)
            arrays.append(("displacements", disp, 4))
        for name, array, rows in arrays:
            if array.shape != (rows, total):
                raise ValueError(f"{name} must have shape ({rows}, T) with T = len(force) = "
                                 f"{total}, got {array.shape}")
        if total < 1:
            raise ValueError(f"force must have shape (T,) with T >= 1, got {force.shape}")
        n, first = int(block_size), int(first_index)
        count = -(-total // n)
        per_block = {"airspeed": airspeed, "density": density}
        if self.damper_state:
            if damper is None or source is None:
                raise ValueError("damper and source are required: this recorder writes "
                                 "dva/damper_state")
            missing = set(_DAMPER_COLUMNS) - set(damper)
            if missing:
                raise ValueError(f"damper lacks the columns {sorted(missing)}")
            per_block.update({f"damper {k}": damper[k] for k in _DAMPER_COLUMNS})
        elif damper is not None:
            raise ValueError("damper given, but this recorder has no dva/damper_state")
        columns = {}
        for name, values in per_block.items():
            column = np.asarray(values, dtype=np.float64)
            if column.shape != (count,):
                raise ValueError(f"{name} must have shape ({count},) (one per block), "
                                 f"got {column.shape}")
            columns[name] = column
        if self.damper_state:
            status = columns["damper status"]
            if np.any((status < 0) | (status > 255) | (status != np.round(status))):
                raise ValueError("damper status must be an integer in 0..255")
        full = total // n
        for begin, stop, length in ((0, full, n), (full, count, total - full * n)):
            if stop == begin:
                continue
            index = first + np.arange(begin, stop, dtype=np.int64) * n
            lo, hi = begin * n, begin * n + (stop - begin) * length
            samples = {f"acceleration.{name}": acc[i, lo:hi].reshape(-1, length)
                       for i, name in enumerate(_ACC)}
            if self.displacement:
                samples.update({f"displacement.{name}": disp[i, lo:hi].reshape(-1, length)
                                for i, name in enumerate(_DISP)})
            samples["excitation.aileron_force"] = force[lo:hi].reshape(-1, length)
            sel = slice(begin, stop)
            damper_rows = ({k: columns[f"damper {k}"][sel] for k in _DAMPER_COLUMNS}
                           if self.damper_state else None)
            if self.engine == "bagwriter":
                self._write_samples_messages(index, length, samples, columns, sel, damper_rows,
                                             source)
                continue
            self._encode_run(
                length, source if self.damper_state else None, index,
                cdr.stamps_from_seconds(index / self.sample_rate, "t0"),
                cdr.stamps_from_seconds((index + length) / self.sample_rate, "t_end"),
                samples, columns["airspeed"][sel], columns["density"][sel], damper_rows)
        return count

    def _write_samples_messages(self, index, n, samples, columns, sel, damper_rows,
                                source) -> None:
        """The reference route of :meth:`write_samples`: FlightBlocks through write_blocks."""
        acc = np.stack([samples[f"acceleration.{c}"] for c in _ACC], axis=1)
        disp = (np.stack([samples[f"displacement.{c}"] for c in _DISP], axis=1)
                if self.displacement else [None] * len(index))
        force = samples["excitation.aileron_force"]
        blocks = [_SampleBlock(first_index=int(i), t0=int(i) / self.sample_rate,
                               t_end=(int(i) + n) / self.sample_rate, force=force[j],
                               airspeed=columns["airspeed"][sel][j:j + 1],
                               density=columns["density"][sel][j:j + 1],
                               displacements=disp[j], accelerations=acc[j])
                  for j, i in enumerate(index)]
        snaps = None
        if damper_rows is not None:
            snaps = [_Snapshot(source=source, **{k: v[j] for k, v in damper_rows.items()})
                     for j in range(len(blocks))]
        self.write_blocks(blocks, snaps)

    # ---------------------------------------------------------------- diagnostics
    def write_diagnostics(self, t: float, statuses: Iterable[tuple[str, str, Mapping]], *,
                          name: str = DIAGNOSTIC_NAME, hardware_id: str = HARDWARE_ID) -> None:
        """Write a ``/diagnostics`` DiagnosticArray at sim time ``t`` [s] (also its log time).

        ``statuses`` = [(level, message, values), ...] with level "ok", "warn", "error" or
        "stale" and values a mapping rendered as the node renders them (floats ``%.9g``).
        """
        rows = []
        for level, text, values in statuses:
            if level not in _LEVELS:
                raise ValueError(f"level must be one of {sorted(_LEVELS)}, got {level!r}")
            rows.append((_LEVELS[level], name, text, hardware_id,
                         [(str(k), _text(v)) for k, v in values.items()]))
        ns = cdr.stamp_ns(t, "t")
        if ns < 0:
            raise ValueError(f"t must be >= 0 s, got {t}")
        self._write_one("diagnostics", cdr.encode_diagnostic_array(t, rows), ns)

    def _write_one(self, key: str, data: bytes, log_time: int) -> None:
        self._check_open()
        topic = self.topics[key]
        if self.engine == "bagwriter":
            self._bag.write(topic, data, log_time)
        else:
            record = _RECORD_HEADER.pack(Opcode.MESSAGE, 22 + len(data),
                                         self._bag.channel_id(topic), self._counts[topic],
                                         log_time, log_time) + data
            self._bag.add_messages(memoryview(record), np.array([len(record)]),
                                   np.array([self._bag.channel_id(topic)]),
                                   np.array([log_time], dtype=np.uint64))
            self._bag.counts[topic] = self._counts[topic] + 1 - self._first[topic]
        self._counts[topic] += 1


def _samples(runtime) -> int:
    return int(round(runtime.time * runtime.sample_rate))


def _stack(arrays: list, shape: tuple[int, ...], name: str, offset: int) -> np.ndarray:
    """(k, *shape) float64 array of k equally shaped arrays; ValueError naming a bad block."""
    float64 = np.dtype(np.float64)
    try:
        uniform = ([a.shape for a in arrays].count(shape) == len(arrays)
                   and [a.dtype for a in arrays].count(float64) == len(arrays))
    except AttributeError:  # not arrays
        uniform = False
    if uniform:
        try:  # contiguous float64 arrays: one C-level copy, no per-array numpy overhead
            data = b"".join(arrays)
        except (BufferError, TypeError, ValueError):
            pass
        else:
            return np.frombuffer(data, dtype=float64).reshape((len(arrays), *shape))
    fixed = []
    for i, array in enumerate(arrays):
        converted = np.ascontiguousarray(array, dtype=float64)
        if converted.shape != shape:
            raise ValueError(f"blocks[{offset + i}].{name} must have shape {shape}, "
                             f"got {converted.shape}")
        fixed.append(converted)
    return np.concatenate(fixed, axis=0).reshape((len(arrays), *shape))


def _text(value) -> str:
    # As aero_dva_sim.messages renders diagnostic values.
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.9g}"
    return str(value)


# --------------------------------------------------------------------------------------------
# Convenience
# --------------------------------------------------------------------------------------------


def record_flight_blocks(bag_dir, blocks: Iterable, damper_states: Iterable | None,
                         sample_rate: float, *, batch_blocks: int = 1000,
                         **options) -> BagSummary:
    """Record blocks (and optional damper snapshots, one per block) into a new bag.

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create.
    blocks : iterable of FlightBlock
        Consumed lazily, ``batch_blocks`` at a time.
    damper_states : iterable of DamperSnapshot or None
        One per block; None records no ``dva/damper_state`` topic.
    sample_rate : float
        [Hz]
    batch_blocks : int
        Blocks encoded together.
    **options
        ``namespace``, ``compression``, ``chunk_size``, ``ros_distro``, ``engine``,
        ``chunk_crc`` of :class:`BatchRecorder`.

    Returns
    -------
    BagSummary
    """
    if isinstance(batch_blocks, bool) or not isinstance(batch_blocks, int) or batch_blocks < 1:
        raise ValueError(f"batch_blocks must be a positive integer, got {batch_blocks!r}")
    with BatchRecorder(bag_dir, sample_rate, damper_state=damper_states is not None,
                       **options) as recorder:
        states = iter(damper_states) if damper_states is not None else None
        batch, snaps = [], []
        for i, block in enumerate(blocks):
            batch.append(block)
            if states is not None:
                try:
                    snaps.append(next(states))
                except StopIteration:
                    raise ValueError(f"damper_states ended after {i} snapshots; one per block "
                                     "is needed") from None
            if len(batch) == batch_blocks:
                recorder.write_blocks(batch, snaps if states is not None else None)
                batch, snaps = [], []
        if batch:
            recorder.write_blocks(batch, snaps if states is not None else None)
        if states is not None and next(states, None) is not None:
            raise ValueError("damper_states has more snapshots than there are blocks")
        return recorder.close()


@dataclass(frozen=True)
class RecordedFlight:
    """What :func:`record_runtime` recorded.

    Attributes
    ----------
    summary : BagSummary
    outcome : {"completed", "diverged"}
    sim_time : float
        [s] sim time flown.
    wall_time : float
        [s] wall time of stepping and recording.
    samples, blocks : int
    method : {"stepped", "parallel"}
        FlightRuntime stepped block by block, or the parallel-in-time sweep.
    """

    summary: BagSummary
    outcome: str
    sim_time: float
    wall_time: float
    samples: int
    blocks: int
    method: str = "stepped"


def record_runtime(bag_dir, runtime, progress: Callable[[int, int], None] | None = None, *,
                   batch_blocks: int = 1000, **options) -> RecordedFlight:
    """Fly a :class:`~aero_dva.flight.flight_runtime.FlightRuntime` to its end and record it.

    What the simulator node publishes, in its order: per block ``/clock``, the sample blocks,
    the flight condition and the damper state; a ``/diagnostics`` warning when the damper falls
    back to its stale value; at the end a ``/diagnostics`` status "simulator: flight" ("flight
    completed", level OK, or "wing diverged at U = ...", level ERROR, stopping the flight) with
    the node's key-values (sim_time_s, wall_time_s, real_time_factor, critical_airspeed_no_dva,
    published:<topic>). No controller runs: c2 is the sweep's own or the damper's initial one.

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create.
    runtime : FlightRuntime
        A fresh runtime (stepped here to the end).
    progress : callable, optional
        Called as ``progress(samples_done, samples_total)`` after each batch.
    batch_blocks : int
        Blocks encoded together.
    **options
        ``namespace``, ``compression``, ``chunk_size``, ``ros_distro``, ``engine``,
        ``chunk_crc`` of :class:`BatchRecorder`.

    Returns
    -------
    RecordedFlight
    """
    if isinstance(batch_blocks, bool) or not isinstance(batch_blocks, int) or batch_blocks < 1:
        raise ValueError(f"batch_blocks must be a positive integer, got {batch_blocks!r}")
    total = int(runtime.scenario.n_samples)
    started = time.monotonic()
    published = dict.fromkeys((t for k, t in _BLOCK_TOPICS if not t.startswith("/")), 0)
    blocks_done = 0
    with BatchRecorder(bag_dir, runtime.sample_rate, **options) as recorder:
        batch, snaps = [], []

        def flush():
            nonlocal batch, snaps
            if batch:
                recorder.write_blocks(batch, snaps if recorder.damper_state else None)
                for topic in published:
                    published[topic] += len(batch)
                batch, snaps = [], []
                if progress is not None:
                    progress(_samples(runtime), total)

        def summary() -> dict:
            return _summary_values(runtime.time, started, runtime, published)

        last_status = None
        outcome = "completed"
        while not runtime.done:
            block = runtime.step()
            snapshot = runtime.damper_snapshot()
            batch.append(block)
            snaps.append(snapshot)
            blocks_done += 1
            status = int(snapshot.status)
            if status != last_status and status == 2:  # DamperStatus.FALLBACK_STALE
                flush()
                recorder.write_diagnostics(runtime.time, [(
                    "warn", "no damper command within "
                    f"{runtime.config.damper.stale_timeout:g} s: fallback c2 = "
                    f"{snapshot.applied_damping:g} N s/m applied", {})])
            last_status = status
            if block.diverged:
                flush()
                u = float(block.airspeed[-1])
                recorder.write_diagnostics(runtime.time, [(
                    "error", f"wing diverged at U = {u:.2f} m/s (U/U_cr = "
                    f"{u / runtime.critical_airspeed:.3f}, t = {block.t0:.3f} s): flight stopped",
                    summary())])
                outcome = "diverged"
                break
            if len(batch) >= batch_blocks:
                flush()
        else:
            flush()
            recorder.write_diagnostics(runtime.time, [("ok", "flight completed", summary())])
        bag = recorder.close()
    return RecordedFlight(summary=bag, outcome=outcome, sim_time=float(runtime.time),
                          wall_time=time.monotonic() - started,
                          samples=_samples(runtime),
                          blocks=blocks_done)


def _summary_values(sim: float, started: float, runtime, published: dict) -> dict:
    """The key-values of the node's final "simulator: flight" status."""
    wall = time.monotonic() - started
    values = {"sim_time_s": sim, "wall_time_s": wall,
              "real_time_factor": sim / wall if wall > 0 else math.inf,
              "critical_airspeed_no_dva": runtime.critical_airspeed}
    values.update({f"published:{t}": n for t, n in published.items()})
    return values
