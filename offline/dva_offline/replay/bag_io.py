"""Bag I/O of ``dva replay``: a recorded flight's controller inputs and outputs read from a bag,
the re-run's spectra and commands written to a new one.

All reading goes through :func:`_messages` (the domain's :func:`aero_dva.bag.reader.
read_messages`, decoded), so a change of bag reader touches one function. The new bag is
written to a hidden directory beside its destination and renamed into place once closed: a
failed run leaves no bag that looks complete.
"""
from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.bag import channels as ch
from aero_dva.bag.reader import BagReadError, bag_topics, read_messages
from aero_dva.bag.writer import BagWriter
from dva_offline.replay.rerun import (
    ACCELERATION_CHANNELS,
    BlockInput,
    CommandRecord,
    SpectrumRecord,
    StateInput,
)

__all__ = ["FlightRecording", "read_outputs", "read_recording", "write_outputs"]

_CHANNELS = (ch.ACCELERATION, ch.DAMPER_STATE, ch.FLIGHT_CONDITION, ch.SPECTRUM,
             ch.DAMPER_COMMAND)
ACCELERATION, DAMPER_STATE, CONDITION, SPECTRUM, COMMAND = (c.absolute() for c in _CHANNELS)
TYPES = {c.absolute(): c.type_name for c in _CHANNELS}
_NS = 1_000_000_000


@dataclass(frozen=True)
class FlightRecording:
    """What a replay needs from a recorded flight.

    Attributes
    ----------
    inputs : list of BlockInput and StateInput
        Acceleration blocks and damper states in the bag's (log-time) order.
    conditions : list of (int, float, float)
        (stamp [ns], airspeed [m/s], air density [kg/m^3]) of the flight conditions in order.
    spectra : list of SpectrumRecord
        The recorded ``dva/spectrum`` (empty if none was recorded).
    commands : list of CommandRecord
        The recorded ``dva/damper_command``.
    duration : float
        [s] log time from the first to the last message read.
    """

    inputs: list
    conditions: list
    spectra: list
    commands: list
    duration: float


def _stamp(msg) -> int:
    return int(msg.header.stamp.sec) * _NS + int(msg.header.stamp.nanosec)


def _messages(bag, topics):
    """(log time [ns], topic, decoded message) of the ``topics`` present in ``bag``."""
    present = bag_topics(bag)
    wanted = [t for t in topics if t in present]
    expected = {t: TYPES[t] for t in wanted}
    for record in read_messages(bag, wanted, expected_types=expected):
        yield record.log_time_ns, record.topic, record.message


def _spectrum(msg) -> SpectrumRecord:
    names = list(msg.channel_names)
    mags = np.asarray(msg.magnitudes, dtype=float).reshape(len(names), -1)
    return SpectrumRecord(_stamp(msg), mags, np.asarray(msg.band_sums, dtype=float),
                          float(msg.damping))


def read_recording(bag) -> FlightRecording:
    """Read a recorded flight's controller inputs and outputs.

    Raises
    ------
    BagReadError
        Unreadable bag, no ``wing/acceleration`` nor ``flight/condition`` in it, or a topic of
        another type.
    """
    present = bag_topics(bag)
    if ACCELERATION not in present and CONDITION not in present:
        raise BagReadError(f"bag {str(bag)!r} has neither {ACCELERATION} nor {CONDITION}: no "
                           f"controller input to replay; its topics: {sorted(present)}")
    inputs, conditions, spectra, commands = [], [], [], []
    first = last = None
    for log_ns, topic, msg in _messages(bag, list(TYPES)):
        first = log_ns if first is None else first
        last = log_ns
        if topic == ACCELERATION:
            samples = np.array([np.asarray(getattr(msg, c), dtype=float)
                                for c in ACCELERATION_CHANNELS])
            inputs.append(BlockInput(_stamp(msg), int(msg.first_sample_index),
                                     float(msg.sample_rate), samples))
        elif topic == DAMPER_STATE:
            inputs.append(StateInput(_stamp(msg), float(msg.applied_damping)))
        elif topic == CONDITION:
            conditions.append((_stamp(msg), float(msg.airspeed), float(msg.air_density)))
        elif topic == SPECTRUM:
            spectra.append(_spectrum(msg))
        else:
            commands.append(CommandRecord(_stamp(msg), float(msg.damping), msg.source))
    duration = 0.0 if first is None else (last - first) / 1e9
    return FlightRecording(inputs, conditions, spectra, commands, duration)


def read_outputs(bag) -> tuple[list[SpectrumRecord], list[CommandRecord]]:
    """The ``dva/spectrum`` and ``dva/damper_command`` messages of a (replay) bag."""
    spectra, commands = [], []
    for _, topic, msg in _messages(bag, [SPECTRUM, COMMAND]):
        if topic == SPECTRUM:
            spectra.append(_spectrum(msg))
        else:
            commands.append(CommandRecord(_stamp(msg), float(msg.damping), msg.source))
    return spectra, commands


def write_outputs(out, spectra, commands, channels, frequencies, window_duration: float,
                  hop: float, window: str) -> Path:
    """Write the re-run's spectra and commands as a new bag ``out`` (must not exist).

    Log times are the messages' stamps (the recording's sim time)."""
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"output {str(out)!r} exists; choose another --out")
    out.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    staged = work / out.name  # the MCAP file is named after its directory
    try:
        with BagWriter(staged) as writer:
            writer.add_topic(SPECTRUM, TYPES[SPECTRUM])
            writer.add_topic(COMMAND, TYPES[COMMAND])
            for s in spectra:
                sec, nsec = divmod(s.stamp_ns, _NS)
                writer.write(SPECTRUM, {
                    "header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "wing"},
                    "frequencies": np.asarray(frequencies, dtype=float),
                    "channel_names": list(channels),
                    "magnitudes": np.ravel(s.magnitudes), "band_sums": s.band_sums,
                    "window_duration": float(window_duration), "hop": float(hop),
                    "window_function": window, "scaling": "band_sum",
                    "damping": float(s.damping)}, s.stamp_ns)
            for c in commands:
                sec, nsec = divmod(c.stamp_ns, _NS)
                writer.write(COMMAND, {"header": {"stamp": {"sec": sec, "nanosec": nsec},
                                                  "frame_id": ""},
                                       "damping": c.damping, "source": c.source}, c.stamp_ns)
        staged.rename(out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return out


def write_flight(out, flight, block_size: int) -> Path:
    """Write a flight flown again (FlightSamples of one flight) as a new bag ``out`` (must not
    exist), a flight log :func:`aero_dva.bag.flight_log_io.load_flight_log` reads: its
    ``wing/acceleration``, ``wing/displacement`` and ``wing/excitation`` blocks of
    ``block_size`` samples and each block's ``flight/condition``, stamped and logged at the
    block's first sample."""
    from aero_dva.wing.model import DISPLACEMENT_NAMES

    out = Path(out)
    if out.exists():
        raise FileExistsError(f"output {str(out)!r} exists; choose another --out")
    out.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    staged = work / out.name
    rows = {ch.ACCELERATION: (ACCELERATION_CHANNELS, flight.accelerations),
            ch.DISPLACEMENT: (DISPLACEMENT_NAMES, flight.displacements),
            ch.EXCITATION: (("aileron_force",), flight.force[None, :])}
    try:
        with BagWriter(staged) as writer:
            for channel in (*rows, ch.FLIGHT_CONDITION):
                writer.add_topic(channel.absolute(), channel.type_name)
            for a in range(0, flight.n, block_size):
                stamp_ns = round((flight.first_index + a) / flight.sample_rate * _NS)
                sec, nsec = divmod(stamp_ns, _NS)
                header = {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": ""}
                for channel, (names, values) in rows.items():
                    message = {"header": {**header, "frame_id": "" if channel == ch.EXCITATION
                                          else ch.WING_FRAME},
                               "sample_rate": float(flight.sample_rate),
                               "first_sample_index": flight.first_index + a}
                    message.update({name: np.ascontiguousarray(values[k, a:a + block_size])
                                    for k, name in enumerate(names)})
                    writer.write(channel.absolute(), message, stamp_ns)
                writer.write(ch.FLIGHT_CONDITION.absolute(), {
                    "header": header, "airspeed": float(flight.airspeed[a]),
                    "air_density": float(flight.density[a])}, stamp_ns)
        staged.rename(out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return out
