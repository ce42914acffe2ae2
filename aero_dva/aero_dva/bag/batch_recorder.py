"""Record simulated flights to rosbag2 MCAP bags without the ROS graph: the batch recorder.

The simulator node publishes, per block of samples, the topics of
:data:`~aero_dva.bag.channels.SIMULATOR_BLOCK` (``/clock``, accelerations, displacements,
excitation, flight condition, damper state) and ``/diagnostics`` now and then; the
``mcap_recorder`` node writes them to a bag. :class:`BatchRecorder` writes the same bag
directly from sample arrays: same topics (absolute names, under an optional namespace like the
graph's), types, ``ros2msg`` schemas, QoS metadata and field values as the node and the recorder
(the ROS side builds them in ``dva_ros_common.conversions``).

A run of blocks of equal length is encoded at once: the message records of all its messages
are one numpy structured array whose layout :mod:`aero_dva.bag.batch_cdr` generates from the
.msg files, and :class:`~aero_dva.bag.chunk_framing.ChunkedMcapFile` chunks, indexes and
writes them. No Python work per message; ``/diagnostics`` (a few messages per flight) goes
through ``rosbags``' serializer.

Times. Header stamps are the node's: the first sample of the block (``t0``) for the sample
blocks and the flight condition, ``t_end`` for ``/clock``, the snapshot time for the damper
state. Log (and publish) time of every message of a block is ``t_end`` in ns: the node publishes
``/clock`` = ``t_end`` before the block, so that is the sim time a recorder on sim time stamps the
block with. Log times therefore never decrease through the file.

The bag is complete only when closed (``metadata.yaml`` written last, atomically). A split bag
(``file_name``, one file per process) gets its ``metadata.yaml`` from
:func:`~aero_dva.bag.chunk_framing.close_split_bag` once every file is closed.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from mcap.opcode import Opcode

from aero_dva.bag import channels as ch
from aero_dva.bag.batch_cdr import (
    CdrLayout,
    cdr_layout,
    sample_fields,
    split_stamps,
    stamp_ns,
    stamps_from_seconds,
    structured_dtype,
)
from aero_dva.bag.chunk_framing import COMPRESSIONS, MESSAGE_RECORD, ChunkedMcapFile
from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES
from aero_dva.bag.schemas import message_fields, typestore_of
from aero_dva.bag.writer import (
    BagSummary,
    interruption_reason,
    mark_interrupted,
    qos_profile_yaml,
)
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES

__all__ = ["DAMPER_COLUMNS", "BatchRecorder", "load_definitions", "recorded_topics"]

#: Per-block damper columns of :meth:`BatchRecorder.write_samples`: the snapshot time [s] and
#: the ``dva_msgs/DamperState`` fields of the same names.
DAMPER_COLUMNS = ("time", "commanded_damping", "applied_damping", "min_damping",
                  "max_damping", "command_age", "status")
#: ``dva/damper_state`` fields of the switching law, taken from the damper columns when given,
#: else those of a held c2 (mode constant, no switching).
DAMPER_LAW_COLUMNS = {"mode": 0, "switching_rate": 0.0}
# Rows of the sample arrays -> sample fields of the messages (the wing model's output order).
_SAMPLE_ROWS = {ch.ACCELERATION: ACCELERATION_NAMES, ch.DISPLACEMENT: DISPLACEMENT_NAMES,
                ch.EXCITATION: ("aileron_force",)}
_STAMPED_AT_T0 = (ch.ACCELERATION, ch.DISPLACEMENT, ch.EXCITATION, ch.FLIGHT_CONDITION)


def recorded_topics(namespace: str = "", damper_state: bool = True,
                    displacement: bool = True) -> dict[str, str]:
    """Topic name -> ``pkg/msg/Type`` of a recorded flight, in the node's publish order,
    ``/diagnostics`` last. ``damper_state`` and ``displacement`` False leave out
    ``dva/damper_state`` and ``wing/displacement``."""
    return {c.absolute(namespace): c.type_name
            for c in _recorded(damper_state, displacement)}


def load_definitions() -> None:
    """Parse the .msg definitions the recorder lays out and serializes (cached per process):
    called before forking, the processes of a split recording inherit them."""
    for channel in ch.SIMULATOR_BLOCK:
        message_fields(channel.type_name)
    typestore_of(ch.DIAGNOSTICS.type_name)


def _recorded(damper_state: bool, displacement: bool) -> list[ch.Channel]:
    left_out = {c for c, wanted in ((ch.DAMPER_STATE, damper_state),
                                    (ch.DISPLACEMENT, displacement)) if not wanted}
    return [c for c in ch.SIMULATOR_BLOCK if c not in left_out] + [ch.DIAGNOSTICS]


# --------------------------------------------------------------------------------------------
# Block layouts: the MCAP message records of one block, as a numpy structured dtype
# --------------------------------------------------------------------------------------------


def _message_layout(channel: ch.Channel, n: int, source: str | None) -> CdrLayout:
    if channel in _SAMPLE_ROWS:
        frame = ch.WING_FRAME if channel != ch.EXCITATION else ""
        fields = sample_fields(channel.type_name)
        if set(fields) != set(_SAMPLE_ROWS[channel]):
            raise ValueError(f"{channel.type_name} has the sample fields {list(fields)}; the "
                             f"recorder writes {list(_SAMPLE_ROWS[channel])}")
        return cdr_layout(channel.type_name, dict.fromkeys(fields, n),
                          {"header.frame_id": frame})
    if channel == ch.DAMPER_STATE:
        return cdr_layout(channel.type_name, strings={"source": source})
    return cdr_layout(channel.type_name)


def _filled_fields(channel: ch.Channel) -> set[str]:
    """The numeric fields :meth:`BatchRecorder._encode_run` fills for a topic."""
    if channel == ch.CLOCK:
        return {"clock.sec", "clock.nanosec"}
    stamp = {"header.stamp.sec", "header.stamp.nanosec"}
    if channel in _SAMPLE_ROWS:
        return stamp | {"sample_rate", "first_sample_index", *_SAMPLE_ROWS[channel]}
    if channel == ch.FLIGHT_CONDITION:
        return stamp | {"airspeed", "air_density"}
    return stamp | set(DAMPER_COLUMNS[1:]) | set(DAMPER_LAW_COLUMNS)


@dataclass(frozen=True, eq=False)  # identity hash: cached per (n, source, channels)
class _GroupLayout:
    dtype: np.dtype
    template: np.ndarray  # uint8, one group
    sizes: np.ndarray  # record sizes in order
    channels: tuple[ch.Channel, ...]


@lru_cache(maxsize=32)
def _group_layout(n: int, source: str | None, channels: tuple[ch.Channel, ...],
                  channel_ids: tuple[int, ...]) -> _GroupLayout:
    """One block's records of ``channels`` (in publish order; the damper state needs
    ``source``) on MCAP ``channel_ids``; dtype fields are ``"<topic>:<field path>"``."""
    entries: dict[str, tuple] = {}
    template = bytearray()
    sizes = []
    for channel, channel_id in zip(channels, channel_ids, strict=True):
        layout = _message_layout(channel, n, source)
        unfilled = set(layout.fields) - _filled_fields(channel)
        if unfilled:
            raise ValueError(f"{channel.type_name} has fields the batch recorder does not "
                             f"fill: {sorted(unfilled)}")
        base = len(template)
        template += MESSAGE_RECORD.pack(Opcode.MESSAGE, MESSAGE_RECORD.size - 9 + layout.size,
                                        channel_id, 0, 0, 0)
        template += layout.template
        key = channel.name
        entries[f"{key}:sequence"] = (np.dtype("<u4"), base + 11)
        entries[f"{key}:log_time"] = (np.dtype("<u8"), base + 15)
        entries[f"{key}:publish_time"] = (np.dtype("<u8"), base + 23)
        entries.update(layout.dtype_fields(offset=base + MESSAGE_RECORD.size, prefix=f"{key}:"))
        sizes.append(MESSAGE_RECORD.size + layout.size)
    return _GroupLayout(structured_dtype(entries, len(template)),
                        np.frombuffer(bytes(template), dtype=np.uint8),
                        np.array(sizes, dtype=np.int64), channels)


def _snapshot_values(snapshots: Sequence) -> dict[str, np.ndarray]:
    """DamperSnapshots -> the :data:`DAMPER_COLUMNS` as (k,) arrays."""
    rows = [(s.time, s.commanded_damping, s.applied_damping, s.min_damping, s.max_damping,
             s.command_age, int(s.status), int(s.mode), s.switching_rate) for s in snapshots]
    names = DAMPER_COLUMNS + tuple(DAMPER_LAW_COLUMNS)
    table = np.array(rows, dtype=np.float64).reshape(-1, len(names))
    _check_status(table[:, len(DAMPER_COLUMNS) - 1])
    return dict(zip(names, table.T))


def _check_status(status: np.ndarray) -> None:
    if np.any((status < 0) | (status > 255) | (status != np.round(status))):
        raise ValueError("damper status must be an integer in 0..255")


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
        Record ``dva/damper_state`` (then every write needs the damper states).
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
    chunk_crc : bool
        Write each chunk's CRC-32 (True, as ``mcap``'s writer does by default). False writes
        0, "not computed" in the MCAP specification, and saves hashing every byte; readers
        then cannot detect a flipped byte inside a chunk.
    file_name : str, optional
        Write one file of a split bag: ``bag_dir`` exists, ``file_name`` (``*.mcap``) is
        created in it, and :func:`~aero_dva.bag.chunk_framing.close_split_bag` writes the
        bag's ``metadata.yaml`` once every file is closed.
    first_block : int
        Blocks the files before this one hold: the sequence numbers of the block topics
        start there (0 for the first or only file).
    library : str
        Writer name in the MCAP header.

    Notes
    -----
    Topics are registered in the node's publish order, ``/diagnostics`` last, before any
    message. Use as a context manager; :meth:`close` is idempotent and runs on errors too.
    """

    def __init__(self, bag_dir, sample_rate: float, *, namespace: str = "",
                 damper_state: bool = True, displacement: bool = True,
                 compression: str = "none", chunk_size: int = 1 << 20,
                 ros_distro: str | None = None, chunk_crc: bool = True,
                 file_name: str | None = None, first_block: int = 0,
                 library: str = "aero_dva.bag.batch_recorder"):
        rate = float(sample_rate)
        if not (math.isfinite(rate) and rate > 0.0):
            raise ValueError(f"sample_rate must be a finite rate > 0 Hz, got {sample_rate!r}")
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {COMPRESSIONS}, got {compression!r}")
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or \
                not 1 <= chunk_size <= MAX_CHUNK_BYTES // 2:
            raise ValueError(f"chunk_size must be an integer in [1, {MAX_CHUNK_BYTES // 2}] "
                             f"bytes (readers read chunks of at most {MAX_CHUNK_BYTES}), got "
                             f"{chunk_size!r}")
        if isinstance(first_block, bool) or not isinstance(first_block, (int, np.integer)) \
                or first_block < 0:
            raise ValueError(f"first_block must be an integer >= 0, got {first_block!r}")
        self.sample_rate = rate
        self.damper_state = bool(damper_state)
        self.displacement = bool(displacement)
        #: channel -> absolute topic name, in registration order
        self.topics = {c: c.absolute(namespace)
                       for c in _recorded(self.damper_state, self.displacement)}
        self._bag = ChunkedMcapFile(bag_dir, compression=compression, chunk_size=chunk_size,
                                    ros_distro=ros_distro, chunk_crc=chunk_crc,
                                    file_name=file_name, library=library)
        # Sequence numbers go on across the files of a split bag; /diagnostics is not per block
        self._first = {c: 0 if c == ch.DIAGNOSTICS else int(first_block) for c in self.topics}
        self._counts = dict(self._first)
        # The records of the last block runs, reused (fresh memory costs a page fault per 4 KiB)
        self._records: dict[tuple, np.ndarray] = {}
        try:
            qos = qos_profile_yaml()
            for channel, topic in self.topics.items():
                self._bag.add_topic(topic, channel.type_name, qos)
        except BaseException:
            self.close()
            raise

    @property
    def directory(self) -> Path:
        return self._bag.directory

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far per topic name (into this file)."""
        return {topic: self._counts[c] - self._first[c] for c, topic in self.topics.items()}

    def __enter__(self) -> BatchRecorder:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()
        if exc_type is not None:  # closed, and marked as not the whole recording
            mark_interrupted(self.directory, interruption_reason(exc_type, exc))

    def close(self) -> BagSummary | None:
        """Close the bag (idempotent); returns what was written."""
        return self._bag.close()

    def _check_open(self) -> None:
        if self._bag.closed:
            raise ValueError(f"bag {str(self.directory)!r} is closed")

    # ---------------------------------------------------------------- blocks
    def write_blocks(self, blocks: Sequence, damper_states: Sequence | None = None) -> None:
        """Write blocks (and the damper snapshot taken after each) in the node's order.

        Parameters
        ----------
        blocks : sequence of FlightSamples
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
        samples = {ch.ACCELERATION: _stack([b.accelerations for b in blocks],
                                           (len(ACCELERATION_NAMES), n), "accelerations",
                                           offset),
                   ch.EXCITATION: _stack([b.force for b in blocks], (n,), "force",
                                         offset)[:, None, :]}
        if self.displacement:
            samples[ch.DISPLACEMENT] = _stack([b.displacements for b in blocks],
                                              (len(DISPLACEMENT_NAMES), n), "displacements",
                                              offset)
        damper = _snapshot_values(snapshots) if snapshots is not None else None
        self._encode_run(n, source, first_index, stamps_from_seconds(t0, "blocks t0"),
                         stamps_from_seconds(t_end, "blocks t_end"), samples,
                         [b.airspeed[0] for b in blocks], [b.density[0] for b in blocks],
                         damper)

    def _encode_run(self, n: int, source, first_index, ns_t0, ns_end,
                    samples: Mapping[ch.Channel, np.ndarray], airspeed, density,
                    damper: dict | None) -> None:
        """Encode and append ``k`` blocks of ``n`` samples in the node's message order.

        ``samples`` maps a sample topic to its (k, rows, n) values (any strides), rows in the
        order of :data:`_SAMPLE_ROWS`; ``airspeed``, ``density`` (k,) and ``damper``
        columns (k,) (:data:`DAMPER_COLUMNS`) are per block.
        """
        channels = tuple(c for c in ch.SIMULATOR_BLOCK if c in self.topics)
        ids = tuple(self._bag.channel_id(self.topics[c]) for c in channels)
        group = _group_layout(n, source, channels, ids)
        count = len(ns_end)
        raw = self._records.get((group, count))
        if raw is None:  # the constant bytes stay valid while the layout is the same
            if len(self._records) > 4:
                self._records.clear()
            raw = self._records[(group, count)] = np.tile(group.template, count)
        rows = raw.view(group.dtype)
        sec0, nsec0 = split_stamps(ns_t0, "blocks t0")
        for channel in channels:
            key = channel.name
            rows[f"{key}:sequence"] = np.arange(self._counts[channel],
                                                self._counts[channel] + count)
            rows[f"{key}:log_time"] = ns_end
            rows[f"{key}:publish_time"] = ns_end
            if channel in _STAMPED_AT_T0:
                rows[f"{key}:header.stamp.sec"] = sec0
                rows[f"{key}:header.stamp.nanosec"] = nsec0
            if channel in _SAMPLE_ROWS:
                rows[f"{key}:sample_rate"] = self.sample_rate
                rows[f"{key}:first_sample_index"] = first_index
                for i, field in enumerate(_SAMPLE_ROWS[channel]):
                    rows[f"{key}:{field}"] = samples[channel][:, i]
        rows[f"{ch.CLOCK.name}:clock.sec"], rows[f"{ch.CLOCK.name}:clock.nanosec"] = \
            split_stamps(ns_end)
        rows[f"{ch.FLIGHT_CONDITION.name}:airspeed"] = airspeed
        rows[f"{ch.FLIGHT_CONDITION.name}:air_density"] = density
        if damper is not None:
            key = ch.DAMPER_STATE.name
            sec, nsec = split_stamps(stamps_from_seconds(damper["time"], "damper_states time"))
            rows[f"{key}:header.stamp.sec"], rows[f"{key}:header.stamp.nanosec"] = sec, nsec
            for name in DAMPER_COLUMNS[1:]:
                rows[f"{key}:{name}"] = damper[name]
            for name, held in DAMPER_LAW_COLUMNS.items():
                rows[f"{key}:{name}"] = damper.get(name, held)
        self._bag.add_messages(
            memoryview(raw), np.tile(group.sizes, count), np.tile(np.array(ids), count),
            np.repeat(ns_end.astype(np.uint64), len(channels)))
        for channel in channels:
            self._counts[channel] += count
            self._bag.counts[self.topics[channel]] = self._counts[channel] - self._first[channel]

    # ---------------------------------------------------------------- sample arrays
    def write_samples(self, first_index: int, accelerations, displacements, force, *,
                      block_size: int, airspeed, density, damper: Mapping | None = None,
                      source: str | None = None) -> int:
        """Write consecutive samples as blocks of ``block_size`` (the last may be shorter).

        The same messages as :meth:`write_blocks` with blocks ``first_index + j block_size``
        (t0 = first sample / rate, t_end = one past the last sample / rate, as FlightRuntime
        sets them), without FlightSamples objects: one vectorised encoding for all blocks.

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
            :data:`DAMPER_COLUMNS`; required when the recorder writes dva/damper_state.
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
        force = np.asarray(force, dtype=np.float64)
        total = force.shape[-1] if force.ndim == 1 else -1
        arrays = {ch.ACCELERATION: ("accelerations", accelerations)}
        if self.displacement:
            arrays[ch.DISPLACEMENT] = ("displacements", displacements)
        checked = {}
        for channel, (name, values) in arrays.items():
            array = np.asarray(values, dtype=np.float64)
            rows = len(_SAMPLE_ROWS[channel])
            if array.shape != (rows, total):
                raise ValueError(f"{name} must have shape ({rows}, T) with T = len(force) = "
                                 f"{total}, got {array.shape}")
            checked[channel] = array
        if total < 1:
            raise ValueError(f"force must have shape (T,) with T >= 1, got {force.shape}")
        checked[ch.EXCITATION] = force[None, :]
        n, first = int(block_size), int(first_index)
        count = -(-total // n)
        columns = self._block_columns(count, airspeed, density, damper, source)
        full = total // n
        for begin, stop, length in ((0, full, n), (full, count, total - full * n)):
            if stop == begin:
                continue
            index = first + np.arange(begin, stop, dtype=np.int64) * n
            lo, hi = begin * n, begin * n + (stop - begin) * length
            samples = {c: a[:, lo:hi].reshape(a.shape[0], -1, length).transpose(1, 0, 2)
                       for c, a in checked.items()}
            sel = slice(begin, stop)
            damper_rows = ({k: columns[f"damper {k}"][sel] for k in DAMPER_COLUMNS}
                           if self.damper_state else None)
            self._encode_run(
                length, source if self.damper_state else None, index,
                stamps_from_seconds(index / self.sample_rate, "t0"),
                stamps_from_seconds((index + length) / self.sample_rate, "t_end"),
                samples, columns["airspeed"][sel], columns["density"][sel], damper_rows)
        return count

    def _block_columns(self, count: int, airspeed, density, damper, source) -> dict:
        """The per-block arguments of :meth:`write_samples` as checked (count,) arrays."""
        per_block = {"airspeed": airspeed, "density": density}
        if self.damper_state:
            if damper is None or source is None:
                raise ValueError("damper and source are required: this recorder writes "
                                 "dva/damper_state")
            missing = set(DAMPER_COLUMNS) - set(damper)
            if missing:
                raise ValueError(f"damper lacks the columns {sorted(missing)}")
            per_block.update({f"damper {k}": damper[k] for k in DAMPER_COLUMNS})
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
            _check_status(columns["damper status"])
        return columns

    # ---------------------------------------------------------------- diagnostics
    def write_diagnostics(self, t: float, statuses: Iterable[tuple[str, str, Mapping]], *,
                          name: str = ch.FLIGHT_DIAGNOSTIC_NAME,
                          hardware_id: str = ch.SIMULATOR_HARDWARE_ID) -> None:
        """Write a ``/diagnostics`` DiagnosticArray at sim time ``t`` [s] (also its log time).

        ``statuses`` = [(level, message, values), ...] with level "ok", "warn", "error" or
        "stale" and values a mapping rendered as the node renders them
        (:func:`~aero_dva.bag.channels.diagnostic_text`).
        """
        store = typestore_of(ch.DIAGNOSTICS.type_name)
        types = store.types
        rows = []
        for level, text, values in statuses:
            if level not in ch.DIAGNOSTIC_LEVELS:
                raise ValueError(f"level must be one of {sorted(ch.DIAGNOSTIC_LEVELS)}, "
                                 f"got {level!r}")
            rows.append(types["diagnostic_msgs/msg/DiagnosticStatus"](
                level=ch.DIAGNOSTIC_LEVELS[level], name=name, message=text,
                hardware_id=hardware_id,
                values=[types["diagnostic_msgs/msg/KeyValue"](key=str(k),
                                                             value=ch.diagnostic_text(v))
                        for k, v in values.items()]))
        ns = stamp_ns(t, "t")
        if ns < 0:
            raise ValueError(f"t must be >= 0 s, got {t}")
        sec, nanosec = divmod(ns, 1_000_000_000)
        header = types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id="")
        message = types[ch.DIAGNOSTICS.type_name](header=header, status=rows)
        self._write_one(ch.DIAGNOSTICS,
                        bytes(store.serialize_cdr(message, ch.DIAGNOSTICS.type_name)), ns)

    def _write_one(self, channel: ch.Channel, data: bytes, log_time: int) -> None:
        self._check_open()
        topic = self.topics[channel]
        channel_id = self._bag.channel_id(topic)
        record = MESSAGE_RECORD.pack(Opcode.MESSAGE, MESSAGE_RECORD.size - 9 + len(data),
                                     channel_id, self._counts[channel], log_time,
                                     log_time) + data
        self._bag.add_messages(memoryview(record), np.array([len(record)]),
                               np.array([channel_id]), np.array([log_time], dtype=np.uint64))
        self._counts[channel] += 1
        self._bag.counts[topic] = self._counts[channel] - self._first[channel]


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
