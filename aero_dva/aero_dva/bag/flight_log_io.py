"""Read a recorded flight (rosbag2 MCAP bag) back into arrays, for analysis and training.

The sample blocks are concatenated by ``first_sample_index``, so a sample's place in the flight
is exact; blocks missing from the log leave NaN where they were (and are counted). Per-block
quantities (flight condition, damper state) are held over their block's samples.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.bag import channels as ch
from aero_dva.bag.reader import BagReadError, bag_topics, read_messages
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES

#: Topics a flight log reads, relative to the simulator's namespace (``/diagnostics`` global).
FLIGHT_TOPICS = (ch.DISPLACEMENT, ch.ACCELERATION, ch.EXCITATION, ch.FLIGHT_CONDITION,
                 ch.DAMPER_STATE)
REQUIRED = (ch.DISPLACEMENT, ch.FLIGHT_CONDITION)
# Sample topics -> the message fields that make the rows of their FlightLog array.
SAMPLE_ROWS = {ch.DISPLACEMENT: DISPLACEMENT_NAMES, ch.ACCELERATION: ACCELERATION_NAMES,
               ch.EXCITATION: ("aileron_force",)}


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
    applied_damping : (n,) [N s/m] c2 acting (NaN if the damper state was not recorded)
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


def _fill(target: np.ndarray, blocks: list[tuple[int, list[np.ndarray]]]) -> None:
    """Put each block's rows at its first sample index."""
    for index, channels in blocks:
        for row, values in zip(target, channels):
            row[index:index + values.size] = values


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def load_flight_log(bag: str | Path, namespace: str = "", *,
                    allow_truncated: bool = False) -> FlightLog:
    """Read the flight topics of ``bag`` (optionally under ``namespace``).

    ``allow_truncated`` reads what a cut, unclosed or damaged bag still holds (with a
    RuntimeWarning); otherwise such a bag is refused with a message naming ``dva bag recover``.

    Raises
    ------
    BagReadError
        Unreadable bag, a required topic (displacement, flight condition) missing, a topic of
        the wrong type, or a sample rate that changes within the flight.
    """
    topics = {c.absolute(namespace): c for c in FLIGHT_TOPICS}
    present = bag_topics(bag, allow_truncated=allow_truncated)
    for channel in REQUIRED:
        if channel.absolute(namespace) not in present:
            raise BagReadError(f"{bag}: no topic {channel.absolute(namespace)} (the flight's "
                               f"{channel.name.rsplit('/', 1)[-1]}); topics: {sorted(present)}")
    wanted = {name: c for name, c in topics.items() if name in present}
    blocks: dict = {c: [] for c in SAMPLE_ROWS}  # sample topic -> [(first index, rows)]
    rates = set()
    conditions, damper, diagnostics = [], [], []
    for record in read_messages(bag, wanted, log_time_order=False,
                                allow_truncated=allow_truncated,
                                expected_types={t: c.type_name for t, c in wanted.items()}):
        channel, msg = wanted[record.topic], record.message
        if channel in SAMPLE_ROWS:
            rows = [getattr(msg, field) for field in SAMPLE_ROWS[channel]]
            if len({row.size for row in rows}) > 1:
                raise BagReadError(f"{bag}: a message on {record.topic} has arrays of "
                                   f"different lengths {[row.size for row in rows]}")
            rates.add(float(msg.sample_rate))
            blocks[channel].append((int(msg.first_sample_index), rows))
        elif channel == ch.FLIGHT_CONDITION:
            conditions.append((_stamp(msg), msg.airspeed, msg.air_density))
        elif channel == ch.DAMPER_STATE:
            damper.append((_stamp(msg), msg.applied_damping))
    if ch.DIAGNOSTICS.name in present:  # global name, shared by every node
        for record in read_messages(bag, [ch.DIAGNOSTICS.name], allow_truncated=allow_truncated,
                                    expected_types={ch.DIAGNOSTICS.name:
                                                    ch.DIAGNOSTICS.type_name}):
            diagnostics.extend(
                {"name": st.name, "message": st.message, "level": _level(st.level),
                 "values": {kv.key: kv.value for kv in st.values}}
                for st in record.message.status)
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
        diagnostics=tuple(diagnostics),
    )


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
