"""Read a recorded flight (rosbag2 MCAP bag) back into arrays, for analysis and training.

The sample blocks are concatenated by ``first_sample_index``, so a sample's place in the flight
is exact; blocks missing from the log leave NaN where they were (and are counted). Per-block
quantities (flight condition, damper state) are held over their block's samples.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.bag.cdr_decoding import (
    CdrDecodeError,
    decode_damper_state_applied,
    decode_flight_condition,
    decode_sample_block,
)
from aero_dva.bag.mcap_io import BagReadError, bag_topics, read_messages

TOPIC_TYPES = {
    "/wing/acceleration": "dva_msgs/msg/AccelerationBlock",
    "/wing/displacement": "dva_msgs/msg/DisplacementBlock",
    "/wing/excitation": "dva_msgs/msg/ForceBlock",
    "/flight/condition": "dva_msgs/msg/FlightCondition",
    "/dva/damper_state": "dva_msgs/msg/DamperState",
}
REQUIRED = ("/wing/displacement", "/flight/condition")
SAMPLE_CHANNELS = {"/wing/acceleration": 3, "/wing/displacement": 4, "/wing/excitation": 1}


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


def _fill(target: np.ndarray, blocks: list[tuple[int, tuple[np.ndarray, ...]]]) -> None:
    for index, channels in blocks:
        for row, values in zip(target, channels):
            row[index:index + values.size] = values


def load_flight_log(bag: str | Path, namespace: str = "") -> FlightLog:
    """Read the flight topics of ``bag`` (optionally under ``namespace``).

    Raises
    ------
    BagReadError
        Unreadable bag, a required topic (displacement, flight condition) missing, a topic of
        the wrong type, or a sample rate that changes within the flight.
    """
    prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
    topics = {prefix + name: kind for name, kind in TOPIC_TYPES.items()}
    present = bag_topics(bag)
    for name in REQUIRED:
        if prefix + name not in present:
            raise BagReadError(f"{bag}: no topic {prefix + name} (the flight's "
                               f"{name.rsplit('/', 1)[-1]}); topics: {sorted(present)}")
    if "/diagnostics" in present:  # global name, shared by every node
        topics["/diagnostics"] = "diagnostic_msgs/msg/DiagnosticArray"
    wanted = [t for t in topics if t in present]
    blocks: dict[str, list] = {t: [] for t in topics}  # sample topics -> [(index, values)]
    rates = set()
    conditions, damper, diagnostics = [], [], []
    flight_topics = [t for t in wanted if t != "/diagnostics"]
    # The flight topics are decoded here (cdr_decoding: numpy views of the sample arrays, ~50x
    # faster than the generic decoder on a sweep's 10^6 blocks); /diagnostics generically.
    for record in read_messages(bag, flight_topics, decode=False, log_time_order=False,
                                expected_types={t: topics[t] for t in flight_topics}):
        name = record.topic[len(prefix):] if record.topic.startswith(prefix) else record.topic
        try:
            if name in SAMPLE_CHANNELS:
                block = decode_sample_block(record.message, SAMPLE_CHANNELS[name],
                                            record.type_name)
                rates.add(block.sample_rate)
                blocks[record.topic].append((block.first_index, block.channels))
            elif name == "/flight/condition":
                conditions.append(decode_flight_condition(record.message))
            elif name == "/dva/damper_state":
                damper.append(decode_damper_state_applied(record.message))
        except CdrDecodeError as exc:
            raise BagReadError(f"{bag}: a message on {record.topic} does not decode: "
                               f"{exc}") from None
    if "/diagnostics" in wanted:
        for record in read_messages(bag, ["/diagnostics"],
                                    expected_types={"/diagnostics": topics["/diagnostics"]}):
            diagnostics.extend(
                {"name": st.name, "message": st.message, "level": _level(st.level),
                 "values": {kv.key: kv.value for kv in st.values}}
                for st in record.message.status)
    if len(rates) != 1:
        raise BagReadError(f"{bag}: sample rate must be one value over the flight, got {rates}")
    rate = rates.pop()
    disp_blocks = blocks[prefix + "/wing/displacement"]
    n = max(i + v[0].size for i, v in disp_blocks)
    displacements = np.full((4, n), np.nan)
    _fill(displacements, disp_blocks)
    accelerations = np.full((3, n), np.nan)
    _fill(accelerations, blocks[prefix + "/wing/acceleration"])
    force = np.full((1, n), np.nan)
    _fill(force, blocks[prefix + "/wing/excitation"])
    time = np.arange(n) / rate
    airspeed, density = _held(time, conditions, 2)
    (applied,) = _held(time, damper, 1)
    return FlightLog(
        sample_rate=rate, time=time, airspeed=airspeed, density=density,
        displacements=displacements, accelerations=accelerations, force=force[0],
        applied_damping=applied,
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
