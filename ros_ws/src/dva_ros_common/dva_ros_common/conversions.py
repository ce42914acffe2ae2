"""Conversions between ROS messages (rclpy classes) and plain values, one way for every node.

The only module of the ROS packages that builds or reads message fields, so the nodes stay
thin and the numerics stay ROS-free. Sample rows map onto message fields by the wing model's
names (``aero_dva.wing.model``), as the batch recorder maps them; topic names and types come
from ``aero_dva.bag.channels``. Times are integer nanoseconds where they must not drift
(``time_to_ns`` / ``ns_to_time``); a stamp argument may be a ``builtin_interfaces/Time`` or
seconds [s].
"""
from __future__ import annotations

import importlib
from array import array
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rosgraph_msgs.msg import Clock

from aero_dva.bag.channels import DIAGNOSTIC_LEVELS, WING_FRAME, diagnostic_text
from aero_dva.control.controllers import SpectrumInput
from aero_dva.control.spectrum import ScaledSpectrum as SpectrumResult
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES
from dva_msgs.msg import (
    AccelerationBlock,
    DamperBlock,
    DamperCommand,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
    ScaledSpectrum,
)

#: Diagnostic levels as ints (``DiagnosticStatus`` stores them as one byte).
OK, WARN, ERROR, STALE = (DIAGNOSTIC_LEVELS[k] for k in ("ok", "warn", "error", "stale"))
LEVELS = DIAGNOSTIC_LEVELS
#: Channels of ``dva_msgs/AccelerationBlock``, by field name (the wing model's order).
ACCELERATION_CHANNELS = ACCELERATION_NAMES

_NS = 1_000_000_000


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (rosidl_runtime_py is not available everywhere).

    Raises ImportError or AttributeError if the type is not installed, ValueError if the name
    is not of that form."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


# --------------------------------------------------------------------------------------------
# Times
# --------------------------------------------------------------------------------------------


def time_to_ns(stamp: Time) -> int:
    """Nanoseconds since the epoch of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * _NS + int(stamp.nanosec)


def ns_to_time(ns: int) -> Time:
    """``builtin_interfaces/Time`` of ``ns`` nanoseconds (>= 0)."""
    ns = int(ns)
    if ns < 0:
        raise ValueError(f"a ROS time must be >= 0 ns, got {ns}")
    return Time(sec=ns // _NS, nanosec=ns % _NS)


def seconds_to_time(seconds: float) -> Time:
    """ROS time of ``seconds`` [s] (sim time since the start of the flight), rounded to 1 ns."""
    return ns_to_time(int(round(seconds * 1e9)))


def time_to_seconds(stamp: Time) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def _stamp(stamp: Time | float) -> Time:
    return stamp if isinstance(stamp, Time) else seconds_to_time(float(stamp))


# --------------------------------------------------------------------------------------------
# What the simulator publishes
# --------------------------------------------------------------------------------------------


def _doubles(values) -> array:
    # array.array is the fast path of the generated setters (no per-element checks).
    out = array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def _sample_block(msg, stamp, sample_rate, first_index, rows, names, frame_id):
    rows = np.asarray(rows, dtype=np.float64)
    if rows.ndim != 2 or rows.shape[0] != len(names):
        raise ValueError(f"{type(msg).__name__} needs ({len(names)}, n) samples, "
                         f"got shape {rows.shape}")
    msg.header.stamp = _stamp(stamp)
    msg.header.frame_id = frame_id
    msg.sample_rate = float(sample_rate)
    msg.first_sample_index = int(first_index)
    for name, row in zip(names, rows):
        setattr(msg, name, _doubles(row))
    return msg


def clock(stamp: Time | float) -> Clock:
    return Clock(clock=_stamp(stamp))


def acceleration_block(stamp: Time | float, sample_rate: float, first_index: int,
                       accelerations, frame_id: str = WING_FRAME) -> AccelerationBlock:
    """``accelerations`` (3, n): plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2]."""
    return _sample_block(AccelerationBlock(), stamp, sample_rate, first_index, accelerations,
                         ACCELERATION_NAMES, frame_id)


def displacement_block(stamp: Time | float, sample_rate: float, first_index: int,
                       displacements, frame_id: str = WING_FRAME) -> DisplacementBlock:
    """``displacements`` (4, n): plunge [m], pitch [rad], leading edge [m], DVA stroke [m]."""
    return _sample_block(DisplacementBlock(), stamp, sample_rate, first_index, displacements,
                         DISPLACEMENT_NAMES, frame_id)


def force_block(stamp: Time | float, sample_rate: float, first_index: int,
                force) -> ForceBlock:
    """``force`` (n,): aileron force [N] (no frame)."""
    return _sample_block(ForceBlock(), stamp, sample_rate, first_index,
                         np.asarray(force, dtype=np.float64)[None, :], ("aileron_force",), "")


def damper_block(stamp: Time | float, sample_rate: float, first_index: int, source: str,
                 commanded, damping, force) -> DamperBlock:
    """A per-sample law's damper over a block: ``commanded`` (n,) [N s/m] the c2 the law
    commanded for each sample, ``damping`` (n,) [N s/m] the c2 acting over each sample (the
    damper's lag followed), ``force`` (n,) [N] the damper force at each."""
    rows = np.stack([np.asarray(commanded, float), np.asarray(damping, float),
                     np.asarray(force, float)])
    msg = _sample_block(DamperBlock(), stamp, sample_rate, first_index, rows,
                        ("commanded_damping", "damping", "force"), WING_FRAME)
    msg.source = str(source)
    return msg


def flight_condition(stamp: Time | float, airspeed: float,
                     air_density: float = 1.2) -> FlightCondition:
    """A ``dva_msgs/FlightCondition`` (airspeed [m/s], air density [kg/m^3])."""
    msg = FlightCondition(airspeed=float(airspeed), air_density=float(air_density))
    msg.header.stamp = _stamp(stamp)
    return msg


def damper_state(snapshot) -> DamperState:
    """A ``dva_msgs/DamperState`` of an ``aero_dva.flight.damper.DamperSnapshot``."""
    msg = DamperState(
        commanded_damping=float(snapshot.commanded_damping),
        applied_damping=float(snapshot.applied_damping),
        min_damping=float(snapshot.min_damping),
        max_damping=float(snapshot.max_damping),
        command_age=float(snapshot.command_age),
        status=int(snapshot.status),
        source=snapshot.source,
        mode=int(snapshot.mode),
        switching_rate=float(snapshot.switching_rate),
    )
    msg.header.stamp = _stamp(snapshot.time)
    return msg


# --------------------------------------------------------------------------------------------
# Diagnostics
# --------------------------------------------------------------------------------------------


def diagnostic_status(level: int, name: str, message: str,
                      values: Mapping[str, object] | None = None,
                      hardware_id: str = "") -> DiagnosticStatus:
    """One ``diagnostic_msgs/DiagnosticStatus``; ``values`` are converted to text.

    Parameters
    ----------
    level : int
        One of ``OK``, ``WARN``, ``ERROR``, ``STALE`` (0..3).
    name : str
        Status name, by convention ``"<node>: <what>"``.
    """
    if level not in (OK, WARN, ERROR, STALE):
        raise ValueError(f"level must be 0..3, got {level}")
    return DiagnosticStatus(
        level=bytes([level]), name=name, message=message, hardware_id=hardware_id,
        values=[KeyValue(key=str(k), value=diagnostic_text(v))
                for k, v in (values or {}).items()])


def diagnostic_array(stamp: Time | float,
                     statuses: Iterable[DiagnosticStatus]) -> DiagnosticArray:
    """A ``diagnostic_msgs/DiagnosticArray`` stamped ``stamp`` holding ``statuses``."""
    msg = DiagnosticArray()
    msg.header.stamp = _stamp(stamp)
    msg.status = list(statuses)
    return msg


def diagnostics(stamp: Time | float, name: str, hardware_id: str,
                statuses: list[tuple[str, str, dict]]) -> DiagnosticArray:
    """A DiagnosticArray; ``statuses`` = [(level name, message, values), ...]."""
    return diagnostic_array(stamp, [
        diagnostic_status(LEVELS[level], name, text, values, hardware_id)
        for level, text, values in statuses])


# --------------------------------------------------------------------------------------------
# What the controllers read and publish
# --------------------------------------------------------------------------------------------


def damper_command(stamp: Time | float, damping: float, source: str) -> DamperCommand:
    """A ``dva_msgs/DamperCommand`` for c2 = ``damping`` [N s/m] from controller ``source``."""
    msg = DamperCommand()
    msg.header.stamp = _stamp(stamp)
    msg.damping = float(damping)
    msg.source = source
    return msg


@dataclass(frozen=True)
class AccelerationSamples:
    """The content of one ``dva_msgs/AccelerationBlock`` for the chosen channels.

    Attributes
    ----------
    stamp_ns : int
        [ns] time of the first sample (header stamp).
    frame_id : str
        Header frame.
    sample_rate : float
        [Hz] as sent (not validated here).
    first_sample_index : int
        Stream index of the first sample.
    samples : ndarray, shape (channels, n)
        Samples of the requested channels, in the requested order (m/s^2 or rad/s^2).
    """

    stamp_ns: int
    frame_id: str
    sample_rate: float
    first_sample_index: int
    samples: np.ndarray

    def sample_time_ns(self, index: int) -> int:
        """[ns] time of stream sample ``index`` (``header.stamp + (index - first) / rate``)."""
        return self.stamp_ns + round((index - self.first_sample_index) * _NS / self.sample_rate)


def acceleration_samples(msg: AccelerationBlock, channels: Sequence[str]) -> AccelerationSamples:
    """Read the ``channels`` of an acceleration block into an array.

    Raises
    ------
    ValueError
        If a channel is unknown or the block's arrays differ in length.
    """
    for name in channels:
        if name not in ACCELERATION_CHANNELS:
            raise ValueError(f"unknown acceleration channel {name!r}")
    lengths = {name: len(getattr(msg, name)) for name in ACCELERATION_CHANNELS}
    if len(set(lengths.values())) != 1:
        raise ValueError(f"the block's arrays differ in length {lengths}")
    n = lengths[ACCELERATION_CHANNELS[0]]
    samples = np.empty((len(channels), n))
    for row, name in enumerate(channels):
        samples[row] = np.asarray(getattr(msg, name), dtype=float)
    return AccelerationSamples(
        stamp_ns=time_to_ns(msg.header.stamp),
        frame_id=msg.header.frame_id,
        sample_rate=float(msg.sample_rate),
        first_sample_index=int(msg.first_sample_index),
        samples=samples,
    )


def scaled_spectrum_message(
    stamp: Time | float,
    frame_id: str,
    channel_names: Sequence[str],
    spectrum: SpectrumResult,
    hop: float,
    damping: float,
) -> ScaledSpectrum:
    """A ``dva_msgs/ScaledSpectrum`` from an eq. 7.3 spectrum (magnitudes channel-major).

    Parameters
    ----------
    stamp : builtin_interfaces/Time or float
        Time of the last sample in the window.
    frame_id : str
        Frame of the acceleration blocks.
    channel_names : sequence of str
        One name per row of ``spectrum.magnitudes``.
    spectrum : aero_dva.control.spectrum.ScaledSpectrum
        The window's spectrum.
    hop : float
        [s] time between consecutive window starts.
    damping : float
        [N s/m] c2 applied during the window (NaN if unknown).
    """
    if len(channel_names) != spectrum.magnitudes.shape[0]:
        raise ValueError(
            f"{len(channel_names)} channel names for {spectrum.magnitudes.shape[0]} channels"
        )
    msg = ScaledSpectrum()
    msg.header.stamp = _stamp(stamp)
    msg.header.frame_id = frame_id
    msg.frequencies = spectrum.frequencies.tolist()
    msg.channel_names = list(channel_names)
    msg.magnitudes = spectrum.magnitudes.ravel().tolist()
    msg.band_sums = spectrum.band_sums.tolist()
    msg.window_duration = float(spectrum.window_duration)
    msg.hop = float(hop)
    msg.window_function = spectrum.window_function
    msg.scaling = ScaledSpectrum.SCALING_BAND_SUM
    msg.damping = float(damping)
    return msg


def spectrum_input(msg: ScaledSpectrum) -> SpectrumInput:
    """Read a ``dva_msgs/ScaledSpectrum``.

    Raises
    ------
    ValueError
        If ``magnitudes`` does not hold ``len(channel_names) * len(frequencies)`` values.
    """
    names = tuple(msg.channel_names)
    freqs = np.asarray(msg.frequencies, dtype=float)
    mags = np.asarray(msg.magnitudes, dtype=float)
    if mags.size != len(names) * freqs.size:
        raise ValueError(
            f"magnitudes has {mags.size} values, expected {len(names)} channels x "
            f"{freqs.size} frequencies = {len(names) * freqs.size}"
        )
    return SpectrumInput(
        stamp_ns=time_to_ns(msg.header.stamp),
        channel_names=names,
        frequencies=freqs,
        magnitudes=mags.reshape(len(names), freqs.size),
        window_duration=float(msg.window_duration),
        window_function=msg.window_function,
        scaling=msg.scaling,
        damping=float(msg.damping),
    )


@dataclass(frozen=True)
class FlightConditionValues:
    """The content of one ``dva_msgs/FlightCondition`` (SI units, not validated)."""

    stamp_ns: int
    airspeed: float
    air_density: float


def flight_condition_values(msg: FlightCondition) -> FlightConditionValues:
    """Read a ``dva_msgs/FlightCondition``."""
    return FlightConditionValues(
        time_to_ns(msg.header.stamp), float(msg.airspeed), float(msg.air_density)
    )


def applied_damping(msg: DamperState) -> float:
    """[N s/m] c2 acting in the model according to a ``dva_msgs/DamperState`` (may be NaN)."""
    return float(msg.applied_damping)
