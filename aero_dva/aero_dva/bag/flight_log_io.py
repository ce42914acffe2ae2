"""Read a recorded flight (rosbag2 MCAP bag) back into arrays, for analysis and training.

The sample blocks are concatenated by ``first_sample_index``, so a sample's place in the flight
is exact; blocks missing from the log leave NaN where they were (and are counted). Per-block
quantities (flight condition, damper state) are held over their block's samples.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from aero_dva.bag import channels as ch
from aero_dva.bag.batch_decode import decode_batch
from aero_dva.bag.indexed_read import IndexedReadError, indexed_messages
from aero_dva.bag.reader import (
    RECOVER_HINT,
    BagReadError,
    MessageTypeError,
    bag_files,
    bag_topics,
    deserialize,
    read_messages,
)
from aero_dva.bag.schemas import normalize_type_name, schema_typestore
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES

#: Topics a flight log reads, relative to the simulator's namespace (``/diagnostics`` global).
FLIGHT_TOPICS = (ch.DISPLACEMENT, ch.ACCELERATION, ch.EXCITATION, ch.FLIGHT_CONDITION,
                 ch.DAMPER_STATE, ch.DAMPER_BLOCK)
REQUIRED = (ch.DISPLACEMENT, ch.FLIGHT_CONDITION)
# Sample topics -> the message fields that make the rows of their FlightLog array.
SAMPLE_ROWS = {ch.DISPLACEMENT: DISPLACEMENT_NAMES, ch.ACCELERATION: ACCELERATION_NAMES,
               ch.EXCITATION: ("aileron_force",),
               ch.DAMPER_BLOCK: ("damping", "force", "commanded_damping")}
# Rows a bag written before their field existed lacks (NaN then): the commanded c2 of a
# per-sample law (dva_msgs/DamperBlock.commanded_damping).
OPTIONAL_ROWS = frozenset({(ch.DAMPER_BLOCK, "commanded_damping")})


@dataclass(frozen=True)
class FlightLog:
    """A flight as arrays (time on the last axis, SI units).

    Attributes
    ----------
    sample_rate : float
        [Hz]
    time : (n,) [s]
    airspeed, density : (n,) [m/s], [kg/m^3] held from the per-block flight condition
    displacements : (4, n) plunge [m], pitch [rad], leading edge [m], DVA stroke [m]
    accelerations : (3, n) plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2] (NaN if absent)
    force : (n,) [N] aileron force (NaN if absent)
    applied_damping : (n,) [N s/m] c2 held over each block (NaN if the damper state was not
        recorded; at a block a per-sample law flew, the c2 at its start)
    law_damping, damper_force : (n,) [N s/m], [N] a per-sample law's c2 acting over each
        sample (the damper's lag followed) and the damper force k2 delta at each
        (``dva/damper_block``; NaN where no law flew the block)
    law_command : (n,) [N s/m] the c2 a per-sample law commanded for each sample (its target,
        before the damper's lag: what the damper's controller logs; NaN where no law flew the
        block, and everywhere in a bag recorded before ``DamperBlock.commanded_damping``)
    missing_samples : int
        Samples of the flight with no displacement block in the log.
    diagnostics : tuple of dict
        The recorded /diagnostics statuses in order: name, message, level (int), values
        (dict of str).
    """

    sample_rate: float
    time: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    displacements: np.ndarray
    accelerations: np.ndarray
    force: np.ndarray
    applied_damping: np.ndarray
    missing_samples: int
    diagnostics: tuple[dict, ...]
    law_damping: np.ndarray | None = None
    damper_force: np.ndarray | None = None
    law_command: np.ndarray | None = None

    @property
    def damping(self) -> np.ndarray:
        """(n,) [N s/m] the c2 that acted at each sample: a per-sample law's where it flew,
        else the c2 the damper held over the block."""
        if self.law_damping is None:
            return self.applied_damping
        return np.where(np.isnan(self.law_damping), self.applied_damping, self.law_damping)


def _fill(target: np.ndarray, blocks: list[tuple[int, list[np.ndarray]]]) -> None:
    """Put each block's rows at its first sample index."""
    for index, channels in blocks:
        for row, values in zip(target, channels):
            row[index:index + values.size] = values


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def load_flight_log(bag: str | Path, namespace: str = "", *,
                    allow_truncated: bool = False, indexed: bool = True) -> FlightLog:
    """Read the flight topics of ``bag`` (optionally under ``namespace``).

    ``allow_truncated`` reads what a cut, unclosed or damaged bag still holds (with a
    RuntimeWarning); otherwise such a bag is refused with a message naming ``dva bag recover``.
    A closed bag is read through its chunk indexes, whole batches of messages at a time
    (:func:`read_flight_rows`); ``indexed=False`` decodes message by message (the previous
    route, kept as a baseline; the same arrays).

    Raises
    ------
    BagReadError
        Unreadable bag, a required topic (displacement, flight condition) missing, a topic of
        the wrong type, or a sample rate that changes within the flight.
    """
    present, wanted = flight_topics(bag, namespace, allow_truncated)
    diagnostics = flight_diagnostics(bag, present, allow_truncated)
    rows = read_flight_rows(bag, wanted, SAMPLE_ROWS) if indexed and not allow_truncated \
        else None
    if rows is not None:
        n = rows.samples
        displacements = _stack(rows, ch.DISPLACEMENT, n)
        return FlightLog(
            sample_rate=rows.sample_rate, time=np.arange(n) / rows.sample_rate,
            airspeed=rows.airspeed, density=rows.density, displacements=displacements,
            accelerations=_stack(rows, ch.ACCELERATION, n),
            force=_stack(rows, ch.EXCITATION, n)[0], applied_damping=rows.applied_damping,
            missing_samples=int(np.isnan(displacements[0]).sum()),
            diagnostics=diagnostics,
            **dict(zip(("law_damping", "damper_force", "law_command"),
                       _stack(rows, ch.DAMPER_BLOCK, n))))
    blocks: dict = {c: [] for c in SAMPLE_ROWS}  # sample topic -> [(first index, rows)]
    rates = set()
    conditions, damper = [], []
    for record in read_messages(bag, wanted, log_time_order=False,
                                allow_truncated=allow_truncated,
                                expected_types={t: c.type_name for t, c in wanted.items()}):
        channel, msg = wanted[record.topic], record.message
        if channel in SAMPLE_ROWS:
            rows = [getattr(msg, field, None) for field in SAMPLE_ROWS[channel]]
            size = next(row.size for row in rows if row is not None)
            rows = [np.full(size, np.nan) if row is None and (channel, field) in OPTIONAL_ROWS
                    else row for row, field in zip(rows, SAMPLE_ROWS[channel])]
            if len({row.size for row in rows}) > 1:
                raise BagReadError(f"{bag}: a message on {record.topic} has arrays of "
                                   f"different lengths {[row.size for row in rows]}")
            rates.add(float(msg.sample_rate))
            blocks[channel].append((int(msg.first_sample_index), rows))
        elif channel == ch.FLIGHT_CONDITION:
            conditions.append((_stamp(msg), msg.airspeed, msg.air_density))
        elif channel == ch.DAMPER_STATE:
            damper.append((_stamp(msg), msg.applied_damping))
    if len(rates) != 1:
        raise BagReadError(f"{bag}: sample rate must be one value over the flight, got {rates}")
    rate = rates.pop()
    if not blocks[ch.DISPLACEMENT]:
        raise BagReadError(f"{bag}: no displacement block to read")
    # The flight spans every sample any topic holds (a cut log may end between topics).
    n = max(i + v[0].size for topic_blocks in blocks.values() for i, v in topic_blocks)
    arrays = {}
    for channel, names in SAMPLE_ROWS.items():
        arrays[channel] = np.full((len(names), n), np.nan)
        _fill(arrays[channel], blocks[channel])
    time = np.arange(n) / rate
    airspeed, density = _held(time, conditions, 2)
    (applied,) = _held(time, damper, 1)
    displacements = arrays[ch.DISPLACEMENT]
    return FlightLog(
        sample_rate=rate, time=time, airspeed=airspeed, density=density,
        displacements=displacements, accelerations=arrays[ch.ACCELERATION],
        force=arrays[ch.EXCITATION][0], applied_damping=applied,
        missing_samples=int(np.isnan(displacements[0]).sum()),
        diagnostics=diagnostics, law_damping=arrays[ch.DAMPER_BLOCK][0],
        damper_force=arrays[ch.DAMPER_BLOCK][1], law_command=arrays[ch.DAMPER_BLOCK][2],
    )


def law_sources(bag, namespace: str = "", allow_truncated: bool = False) -> tuple[str, ...]:
    """The per-sample laws that flew blocks of ``bag``: the distinct ``source`` of its
    ``dva/damper_block`` messages, in order of first appearance (none: no such topic)."""
    topic = ch.DAMPER_BLOCK.absolute(namespace)
    if topic not in bag_topics(bag, allow_truncated=allow_truncated):
        return ()
    seen: dict[str, None] = {}
    for record in read_messages(bag, [topic], allow_truncated=allow_truncated,
                                expected_types={topic: ch.DAMPER_BLOCK.type_name}):
        seen.setdefault(str(record.message.source))
    return tuple(seen)


def flight_topics(bag, namespace: str, allow_truncated: bool) -> tuple[dict, dict]:
    """The bag's topics and the flight topics to read (name -> channel); BagReadError if a
    required one is missing."""
    topics = {c.absolute(namespace): c for c in FLIGHT_TOPICS}
    present = bag_topics(bag, allow_truncated=allow_truncated)
    for channel in REQUIRED:
        if channel.absolute(namespace) not in present:
            raise BagReadError(f"{bag}: no topic {channel.absolute(namespace)} (the flight's "
                               f"{channel.name.rsplit('/', 1)[-1]}); topics: {sorted(present)}")
    return present, {name: c for name, c in topics.items() if name in present}


def flight_diagnostics(bag, present, allow_truncated: bool = False) -> tuple[dict, ...]:
    """The /diagnostics statuses of ``bag`` (``present``: its topics), as
    :attr:`FlightLog.diagnostics`."""
    out = []
    if ch.DIAGNOSTICS.name in present:  # global name, shared by every node
        for record in read_messages(bag, [ch.DIAGNOSTICS.name], allow_truncated=allow_truncated,
                                    expected_types={ch.DIAGNOSTICS.name:
                                                    ch.DIAGNOSTICS.type_name}):
            out.extend(
                {"name": st.name, "message": st.message, "level": _level(st.level),
                 "values": {kv.key: kv.value for kv in st.values}}
                for st in record.message.status)
    return tuple(out)


def _stack(rows: FlightRows, channel, n: int) -> np.ndarray:
    names = SAMPLE_ROWS[channel]
    out = np.full((len(names), n), np.nan)
    for i, name in enumerate(names):
        if name in rows.rows.get(channel, {}):
            out[i] = rows.rows[channel].pop(name)  # the copy frees the block's memory
    return out


# -- the indexed route: whole batches of messages decoded at once ---------------------------

@dataclass(frozen=True)
class FlightRows:
    """Chosen sample rows of a flight with its held condition (:func:`read_flight_rows`).

    Attributes
    ----------
    sample_rate : float
        [Hz]
    samples : int
        Samples of the flight (every sample any topic holds).
    airspeed, density, applied_damping : (n,) as :class:`FlightLog`
    rows : dict
        Sample channel -> {row name: (n,) array}, NaN where no block holds the sample.
    """

    sample_rate: float
    samples: int
    airspeed: np.ndarray
    density: np.ndarray
    applied_damping: np.ndarray
    rows: dict


_STAMP = ("header.stamp.sec", "header.stamp.nanosec")
_SCALARS = {ch.FLIGHT_CONDITION: _STAMP + ("airspeed", "air_density"),
            ch.DAMPER_STATE: _STAMP + ("applied_damping",)}


def read_flight_rows(bag, wanted: dict, rows: dict) -> FlightRows | None:
    """The ``rows`` (sample channel -> row names) of the flight topics ``wanted`` (name ->
    channel), from the bag files' chunk and message indexes; None if a file has none (read
    it with :func:`load_flight_log`). Same values as :func:`load_flight_log`; only the chosen
    rows are held in memory."""
    present = bag_topics(bag)
    for topic, channel in wanted.items():  # as read_messages checks expected types
        actual, expected = present[topic].type_name, normalize_type_name(channel.type_name)
        if actual != expected:
            raise MessageTypeError(f"topic {topic!r} in bag {str(bag)!r} carries {actual!r}, "
                                   f"expected {expected!r}")
    iterators = []
    for file in bag_files(bag):
        it = indexed_messages(file, wanted)
        if it is None:
            return None
        iterators.append(it)
    parts: dict = {c: [] for c in wanted.values()}  # channel -> [(file, position, fields)]
    growing = {c: {name: [np.full(0, np.nan)] for name in names} for c, names in rows.items()}
    try:
        for number, it in enumerate(iterators):
            for m in it:
                channel = wanted[m.topic]
                if channel in SAMPLE_ROWS:  # at least one row: the blocks' lengths
                    chosen = _present(channel, rows.get(channel, ()), m)
                    fields = ("sample_rate", "first_sample_index",
                              *(chosen or SAMPLE_ROWS[channel][:1]))
                else:
                    fields = _SCALARS.get(channel)
                    if fields is None:
                        continue
                out = decode_batch(m.data, m.type_name, m.schema_text, fields)
                if out is None:
                    out = _decode_each(m, fields, channel in SAMPLE_ROWS)
                if channel in SAMPLE_ROWS:
                    out["_end"] = out["first_sample_index"] + _width(out, bag, m.topic)
                    index = out["first_sample_index"].astype(np.int64)
                    for name in chosen:  # into the rows now: no copy held
                        _put(growing[channel][name], index, out.pop(name))
                    for name in set(out) - {"sample_rate", "first_sample_index", "_end"}:
                        del out[name]  # read for the blocks' lengths only
                parts[channel].append((number, m.position, out))
    except IndexedReadError as exc:
        raise BagReadError(f"{exc}; " + RECOVER_HINT.format(bag=bag)) from None
    rates = {float(r) for c in SAMPLE_ROWS for _, _, out in parts.get(c, [])
             for r in np.unique(out["sample_rate"])}
    if len(rates) != 1:
        raise BagReadError(f"{bag}: sample rate must be one value over the flight, got {rates}")
    if not parts.get(ch.DISPLACEMENT):
        raise BagReadError(f"{bag}: no displacement block to read")
    n = max(int(np.max(out["_end"])) for c in SAMPLE_ROWS for _, _, out in parts.get(c, [])
            if len(out["_end"]))
    rate = rates.pop()
    filled = {}
    for channel, names in rows.items():
        filled[channel] = {}
        for name in names:
            target = growing[channel][name]
            _grow(target, n)
            filled[channel][name] = target[0][:n]  # a view: no copy of the rows
    airspeed, density = _held_columns(n, rate, parts.pop(ch.FLIGHT_CONDITION, []),
                                      ("airspeed", "air_density"))
    (applied,) = _held_columns(n, rate, parts.pop(ch.DAMPER_STATE, []), ("applied_damping",))
    return FlightRows(sample_rate=rate, samples=n, airspeed=airspeed, density=density,
                      applied_damping=applied, rows=filled)


def _present(channel, names, m) -> tuple:
    """``names`` without the optional rows (:data:`OPTIONAL_ROWS`) that the bag's schema of
    the message batch ``m`` lacks."""
    optional = [n for n in names if (channel, n) in OPTIONAL_ROWS]
    if not optional:
        return tuple(names)
    fields = _schema_fields(m.type_name, m.schema_text)
    return tuple(n for n in names if n in fields or (channel, n) not in OPTIONAL_ROWS)


@lru_cache(maxsize=32)
def _schema_fields(type_name: str, schema_text: str) -> frozenset:
    """The field names of ``type_name`` as a bag's schema text defines it."""
    full = normalize_type_name(type_name)
    return frozenset(name for name, _ in schema_typestore(full, schema_text).fielddefs[full][1])


def _grow(holder: list, size: int) -> None:
    """Make ``holder[0]`` (a NaN-padded row) hold at least ``size`` samples, by a quarter
    more than needed at a time (each copy is freed at once, so the memory stays about the
    row's size)."""
    row = holder[0]
    if row.size >= size:
        return
    bigger = np.full(max(size, row.size + row.size // 4), np.nan)
    bigger[:row.size] = row
    holder[0] = bigger


def _put(holder: list, index: np.ndarray, values) -> None:
    """Blocks of samples ``values`` at their first sample ``index`` into a growing row."""
    if isinstance(values, list):  # blocks of several lengths, one by one
        _grow(holder, max((i + v.size for i, v in zip(index.tolist(), values)), default=0))
        row = holder[0]
        for i, v in zip(index.tolist(), values):
            row[i:i + v.size] = v
    elif values.size:
        _grow(holder, int(index.max()) + values.shape[1])
        holder[0][index[:, None] + np.arange(values.shape[1])] = values


def _width(out: dict, bag, topic: str) -> np.ndarray:
    """Samples per block of a decoded batch of sample blocks; BagReadError if a block's rows
    differ in length."""
    widths = [np.array([v.size for v in values]) if isinstance(values, list)
              else np.full(len(out["sample_rate"]), values.shape[1])
              for name, values in out.items()
              if name not in ("sample_rate", "first_sample_index")]
    for w in widths[1:]:
        bad = np.flatnonzero(w != widths[0])
        if bad.size:
            raise BagReadError(f"{bag}: a message on {topic} has arrays of different lengths "
                               f"{[int(widths[0][bad[0]]), int(w[bad[0]])]}")
    return widths[0]


def _decode_each(m, fields, sample: bool) -> dict:
    """The fields of a message matrix one message at a time (blocks may differ in length)."""
    msgs = [deserialize(bytes(row), m.type_name, m.schema_text) for row in m.data]
    out = {}
    for f in fields:
        values = []
        for msg in msgs:
            v = msg
            for name in f.split("."):
                v = getattr(v, name)
            values.append(v)
        out[f] = values if sample and f not in ("sample_rate", "first_sample_index") \
            else np.array(values)
    return out


_HOLD_BLOCK = 1 << 20
"""Samples held per pass of :func:`_held_columns` (bounds its temporary arrays)."""


def _held_columns(n: int, rate: float, parts: list, names: tuple) -> list[np.ndarray]:
    """:func:`_held` of decoded batches onto the ``n`` sample times: stamps in file order,
    then sorted (stable)."""
    if not parts:
        return [np.full(n, np.nan) for _ in names]
    parts = sorted(parts, key=lambda p: (p[0], p[1][0]))
    position = np.concatenate([np.c_[np.full(p[1].size, p[0]), p[1]] for p in parts])
    order = np.lexsort((position[:, 1], position[:, 0]))  # file order
    sec = np.concatenate([p[2]["header.stamp.sec"] for p in parts])[order]
    nsec = np.concatenate([p[2]["header.stamp.nanosec"] for p in parts])[order]
    stamps = sec.astype(float) + 1e-9 * nsec.astype(float)
    by_stamp = np.argsort(stamps, kind="stable")
    stamps = stamps[by_stamp]
    values = [np.concatenate([p[2][name] for p in parts])[order][by_stamp].astype(float)
              for name in names]
    out = [np.empty(n) for _ in names]
    for a in range(0, n, _HOLD_BLOCK):
        b = min(a + _HOLD_BLOCK, n)
        index = np.searchsorted(stamps, np.arange(a, b) / rate + 1e-9, side="right") - 1
        before = index < 0
        np.maximum(index, 0, out=index)
        for held, column in zip(out, values):
            np.take(column, index, out=held[a:b])
            held[a:b][before] = np.nan
    return out


def _level(level) -> int:
    # diagnostic_msgs declares ``byte level``; decoders give bytes or int.
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def _held(time: np.ndarray, records: list, width: int) -> list[np.ndarray]:
    """Zero-order hold of stamped records onto ``time`` (NaN before the first record)."""
    if not records:
        return [np.full(time.shape, np.nan) for _ in range(width)]
    records.sort(key=lambda r: r[0])
    stamps = np.array([r[0] for r in records])
    index = np.searchsorted(stamps, time + 1e-9, side="right") - 1
    out = []
    for column in range(1, width + 1):
        values = np.array([r[column] for r in records], dtype=float)
        held = values[np.clip(index, 0, None)]
        held[index < 0] = np.nan
        out.append(held)
    return out
