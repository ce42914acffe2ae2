"""CDR (XCDR1, little endian) encoding of the simulator's messages, one at a time or in batches.

The messages are the ones the simulator node publishes (``dva_msgs`` AccelerationBlock,
DisplacementBlock, ForceBlock, FlightCondition, DamperState, DamperCommand,
``rosgraph_msgs/Clock`` and ``diagnostic_msgs/DiagnosticArray``), with the field values
:mod:`aero_dva_sim.messages` gives them. The bytes are those of a ROS 2 serialized message:

- a 4-byte encapsulation header ``00 01 00 00`` (CDR, little endian, no options);
- primitives aligned to their size, counted from the end of that header;
- ``builtin_interfaces/Time`` = int32 sec, uint32 nanosec; ``std_msgs/Header`` = Time + string;
- string = uint32 length including the terminating NUL, the UTF-8 bytes, the NUL;
- sequence = uint32 element count, then the elements (each aligned as its type);
  an empty sequence is its count alone;
- padding bytes are zero.

A message type with given array lengths and strings has a fixed byte layout
(:class:`CdrLayout`): constant bytes (header, string and sequence lengths, string bytes, zero
padding) with numeric fields at fixed offsets. The ``encode_*`` functions fill one copy of the
layout; :meth:`CdrLayout.batch` (or a larger structured dtype built from
:meth:`CdrLayout.dtype_fields`) fills many at once with numpy, which is how a flight's blocks are
encoded fast. This module is pure: no ROS imports, no file I/O.

Times are given in seconds [s] and rounded to the nearest nanosecond like
:func:`aero_dva_sim.messages.to_time` (``sec = ns // 10**9``, ``nanosec = ns % 10**9``), or as
integer nanoseconds in the batch functions.
"""
from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType

import numpy as np

__all__ = [
    "CDR_HEADER",
    "CLOCK",
    "ACCELERATION_BLOCK",
    "DAMPER_COMMAND",
    "DAMPER_STATE",
    "DIAGNOSTIC_ARRAY",
    "DISPLACEMENT_BLOCK",
    "FLIGHT_CONDITION",
    "FORCE_BLOCK",
    "WING_FRAME",
    "CdrLayout",
    "acceleration_block_layout",
    "clock_layout",
    "damper_command_layout",
    "damper_state_layout",
    "displacement_block_layout",
    "encode_acceleration_block",
    "encode_clock",
    "encode_damper_command",
    "encode_damper_state",
    "encode_diagnostic_array",
    "encode_displacement_block",
    "encode_flight_condition",
    "encode_force_block",
    "flight_condition_layout",
    "force_block_layout",
    "split_stamps",
    "stamp_ns",
    "stamps_from_seconds",
]

#: Encapsulation header of every message: CDR little endian (0x0001), options 0.
CDR_HEADER = b"\x00\x01\x00\x00"

CLOCK = "rosgraph_msgs/msg/Clock"
ACCELERATION_BLOCK = "dva_msgs/msg/AccelerationBlock"
DISPLACEMENT_BLOCK = "dva_msgs/msg/DisplacementBlock"
FORCE_BLOCK = "dva_msgs/msg/ForceBlock"
FLIGHT_CONDITION = "dva_msgs/msg/FlightCondition"
DAMPER_STATE = "dva_msgs/msg/DamperState"
DAMPER_COMMAND = "dva_msgs/msg/DamperCommand"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"

#: frame_id of the sample blocks of the wing (the others leave it empty, as the node does).
WING_FRAME = "wing"

_NS_PER_S = 1_000_000_000
_INT32 = (-(2**31), 2**31 - 1)
# field kind -> (struct code, numpy dtype, size); all little endian
_PRIMITIVES = {
    "u8": ("<B", np.dtype("u1"), 1),
    "i32": ("<i", np.dtype("<i4"), 4),
    "u32": ("<I", np.dtype("<u4"), 4),
    "u64": ("<Q", np.dtype("<u8"), 8),
    "f64": ("<d", np.dtype("<f8"), 8),
}
_RANGES = {"u8": (0, 255), "i32": _INT32, "u32": (0, 2**32 - 1), "u64": (0, 2**64 - 1)}


# --------------------------------------------------------------------------------------------
# Times
# --------------------------------------------------------------------------------------------


def stamp_ns(seconds: float, name: str = "seconds") -> int:
    """[s] -> integer nanoseconds, rounded half to even like ``int(round(seconds * 1e9))``.

    Raises
    ------
    ValueError
        If ``seconds`` is not finite or its whole seconds do not fit an int32.
    """
    value = float(seconds)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite time in seconds, got {value}")
    ns = int(round(value * 1e9))
    if not _INT32[0] <= ns // _NS_PER_S <= _INT32[1]:
        raise ValueError(f"{name} = {value} s does not fit a ROS time (int32 seconds)")
    return ns


def split_stamps(ns, name: str = "stamps") -> tuple[np.ndarray, np.ndarray]:
    """Integer nanoseconds (array) -> (sec int32, nanosec uint32) as ``builtin_interfaces/Time``.

    Raises
    ------
    ValueError
        If a stamp's whole seconds do not fit an int32.
    """
    ns = np.asarray(ns, dtype=np.int64)
    sec, nanosec = np.divmod(ns, _NS_PER_S)
    if sec.size and (sec.min() < _INT32[0] or sec.max() > _INT32[1]):
        raise ValueError(f"{name} do not fit a ROS time (int32 seconds)")
    return sec.astype("<i4"), nanosec.astype("<u4")


def stamps_from_seconds(seconds, name: str = "seconds") -> np.ndarray:
    """[s] (array) -> int64 nanoseconds, rounded half to even (as :func:`stamp_ns`).

    Raises
    ------
    ValueError
        If a time is not finite.
    """
    t = np.asarray(seconds, dtype=np.float64)
    if not np.all(np.isfinite(t)):
        raise ValueError(f"{name} must be finite times in seconds")
    return np.rint(t * 1e9).astype(np.int64)


# --------------------------------------------------------------------------------------------
# Layouts
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CdrLayout:
    """Fixed byte layout of one message type for given array lengths and strings.

    Attributes
    ----------
    type_name : str
        ``pkg/msg/Type``.
    template : bytes
        The whole serialized message with every numeric field zero: encapsulation header,
        string and sequence lengths, string bytes and (zero) padding.
    fields : mapping of str to (int, str, int)
        Field name -> (byte offset from the start of the message, kind, element count);
        kind is one of ``u8``, ``i32``, ``u32``, ``u64``, ``f64`` (count 1), or ``f64[]``: the
        n elements of a float64 sequence (its length is part of the template).
    """

    type_name: str
    template: bytes
    fields: Mapping[str, tuple[int, str, int]]

    @property
    def size(self) -> int:
        """[bytes] length of the serialized message, header included."""
        return len(self.template)

    def dtype_fields(self, offset: int = 0, prefix: str = "") -> dict[str, tuple]:
        """numpy structured-dtype entries of the fields, shifted by ``offset`` bytes.

        Returns ``{prefix + name: (dtype, offset)}`` (the ``fields`` form accepted by
        ``numpy.dtype`` when combined with ``names``/``formats``/``offsets``); a sequence field
        has a subarray dtype ``("<f8", (n,))``.
        """
        out = {}
        for name, (where, kind, count) in self.fields.items():
            base = _PRIMITIVES[kind.removesuffix("[]")][1]
            dtype = np.dtype((base, (count,))) if kind.endswith("[]") else base
            out[prefix + name] = (dtype, offset + where)
        return out

    def dtype(self) -> np.dtype:
        """Structured dtype of one message (itemsize = :attr:`size`)."""
        entries = self.dtype_fields()
        return np.dtype({
            "names": list(entries),
            "formats": [d for d, _ in entries.values()],
            "offsets": [o for _, o in entries.values()],
            "itemsize": self.size,
        })

    def encode(self, values: Mapping[str, object]) -> bytes:
        """Serialize one message: ``values`` gives every field of :attr:`fields`.

        Raises
        ------
        ValueError
            A field missing or unknown, an integer out of range, an array of the wrong length.
        """
        out = bytearray(self.template)
        try:
            for name, (where, kind, count) in self.fields.items():
                value = values[name]
                if kind != "f64[]":
                    _pack_scalar(out, where, kind, value, name)
                    continue
                data = np.ascontiguousarray(value, dtype="<f8")
                if data.shape != (count,):
                    raise ValueError(f"{name} must have shape ({count},), got {data.shape}")
                out[where:where + 8 * count] = memoryview(data).cast("B")
        except KeyError:
            pass
        else:
            if len(values) == len(self.fields):
                return bytes(out)
        missing = self.fields.keys() - values.keys()
        extra = values.keys() - self.fields.keys()
        raise ValueError(f"{self.type_name}: fields missing {sorted(missing)}, "
                         f"unknown {sorted(extra)}")

    def batch(self, count: int) -> np.ndarray:
        """``count`` copies of the template as a structured array to fill field by field.

        ``batch(k)["plunge"][:] = values`` etc.; ``.tobytes()`` then gives the k messages back to
        back (each :attr:`size` bytes).
        """
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise ValueError(f"count must be an integer >= 0, got {count!r}")
        raw = np.tile(np.frombuffer(self.template, dtype=np.uint8), int(count))
        return raw.view(self.dtype())


_STRUCTS = {kind: struct.Struct(code) for kind, (code, _, _) in _PRIMITIVES.items()}
_REALS = (int, float, np.integer, np.floating)
_BOOLS = (bool, np.bool_)


def _pack_scalar(out: bytearray, where: int, kind: str, value, name: str) -> None:
    if kind == "f64":
        if type(value) is not float:
            if isinstance(value, _BOOLS) or not isinstance(value, _REALS):
                raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
            value = float(value)
        _STRUCTS["f64"].pack_into(out, where, value)
        return
    if type(value) is not int:
        if isinstance(value, _BOOLS) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
        value = int(value)
    low, high = _RANGES[kind]
    if not low <= value <= high:
        raise ValueError(f"{name} = {value} is out of range [{low}, {high}]")
    _STRUCTS[kind].pack_into(out, where, value)


class _LayoutBuilder:
    """Walk a message's fields in order, applying the CDR alignment rules."""

    def __init__(self, type_name: str):
        self.type_name = type_name
        self.buf = bytearray(CDR_HEADER)
        self.fields: dict[str, tuple[int, str, int]] = {}

    def _align(self, size: int) -> None:
        pad = -(len(self.buf) - len(CDR_HEADER)) % size
        self.buf += b"\0" * pad

    def _const_u32(self, value: int) -> None:
        self._align(4)
        self.buf += struct.pack("<I", value)

    def prim(self, name: str, kind: str) -> None:
        size = _PRIMITIVES[kind][2]
        self._align(size)
        self.fields[name] = (len(self.buf), kind, 1)
        self.buf += b"\0" * size

    def const_u8(self, value: int) -> None:
        self.buf.append(value)

    def string(self, text: str, name: str = "string") -> None:
        if not isinstance(text, str):
            raise TypeError(f"{name} must be a string, got {type(text).__name__}")
        data = text.encode("utf-8")
        if b"\0" in data:
            raise ValueError(f"{name} must not contain NUL characters: {text!r}")
        self._const_u32(len(data) + 1)
        self.buf += data + b"\0"

    def sequence_length(self, count: int) -> None:
        self._const_u32(count)

    def f64_sequence(self, name: str, count: int) -> None:
        self._const_u32(count)
        if count:
            self._align(8)
        self.fields[name] = (len(self.buf), "f64[]", count)
        self.buf += b"\0" * (8 * count)

    def header(self, frame_id: str) -> None:
        self.prim("stamp_sec", "i32")
        self.prim("stamp_nanosec", "u32")
        self.string(frame_id, "frame_id")

    def build(self) -> CdrLayout:
        return CdrLayout(self.type_name, bytes(self.buf), MappingProxyType(dict(self.fields)))


_ACC_CHANNELS = ("plunge", "pitch", "leading_edge")
_DISP_CHANNELS = ("plunge", "pitch", "leading_edge", "absorber_stroke")


def _check_count(n, name: str = "n") -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"{name} must be an integer >= 0, got {n!r}")
    return int(n)


@lru_cache(maxsize=64)
def _sample_block_layout(type_name: str, channels: tuple[str, ...], n: int,
                         frame_id: str) -> CdrLayout:
    builder = _LayoutBuilder(type_name)
    builder.header(frame_id)
    builder.prim("sample_rate", "f64")
    builder.prim("first_sample_index", "u64")
    for channel in channels:
        builder.f64_sequence(channel, n)
    return builder.build()


def acceleration_block_layout(n: int, frame_id: str = WING_FRAME) -> CdrLayout:
    """Layout of ``dva_msgs/AccelerationBlock`` with ``n`` samples per channel.

    Fields: stamp_sec, stamp_nanosec, sample_rate [Hz], first_sample_index, plunge [m/s^2],
    pitch [rad/s^2], leading_edge [m/s^2] (each (n,)).
    """
    return _sample_block_layout(ACCELERATION_BLOCK, _ACC_CHANNELS, _check_count(n), frame_id)


def displacement_block_layout(n: int, frame_id: str = WING_FRAME) -> CdrLayout:
    """Layout of ``dva_msgs/DisplacementBlock`` with ``n`` samples per channel.

    Fields: stamp_sec, stamp_nanosec, sample_rate [Hz], first_sample_index, plunge [m],
    pitch [rad], leading_edge [m], absorber_stroke [m] (each (n,)).
    """
    return _sample_block_layout(DISPLACEMENT_BLOCK, _DISP_CHANNELS, _check_count(n), frame_id)


def force_block_layout(n: int, frame_id: str = "") -> CdrLayout:
    """Layout of ``dva_msgs/ForceBlock`` with ``n`` samples.

    Fields: stamp_sec, stamp_nanosec, sample_rate [Hz], first_sample_index, aileron_force [N]
    ((n,)).
    """
    return _sample_block_layout(FORCE_BLOCK, ("aileron_force",), _check_count(n), frame_id)


@lru_cache(maxsize=8)
def flight_condition_layout(frame_id: str = "") -> CdrLayout:
    """Layout of ``dva_msgs/FlightCondition``: stamp, airspeed [m/s], air_density [kg/m^3]."""
    builder = _LayoutBuilder(FLIGHT_CONDITION)
    builder.header(frame_id)
    builder.prim("airspeed", "f64")
    builder.prim("air_density", "f64")
    return builder.build()


@lru_cache(maxsize=64)
def damper_state_layout(source: str, frame_id: str = "") -> CdrLayout:
    """Layout of ``dva_msgs/DamperState`` with a given ``source`` string.

    Fields: stamp_sec, stamp_nanosec, commanded_damping, applied_damping, min_damping,
    max_damping [N s/m], command_age [s], status (uint8).
    """
    builder = _LayoutBuilder(DAMPER_STATE)
    builder.header(frame_id)
    for name in ("commanded_damping", "applied_damping", "min_damping", "max_damping",
                 "command_age"):
        builder.prim(name, "f64")
    builder.prim("status", "u8")
    builder.string(source, "source")
    return builder.build()


@lru_cache(maxsize=64)
def damper_command_layout(source: str, frame_id: str = "") -> CdrLayout:
    """Layout of ``dva_msgs/DamperCommand``: stamp, damping [N s/m], given ``source``."""
    builder = _LayoutBuilder(DAMPER_COMMAND)
    builder.header(frame_id)
    builder.prim("damping", "f64")
    builder.string(source, "source")
    return builder.build()


@lru_cache(maxsize=1)
def clock_layout() -> CdrLayout:
    """Layout of ``rosgraph_msgs/Clock``: stamp_sec, stamp_nanosec."""
    builder = _LayoutBuilder(CLOCK)
    builder.prim("stamp_sec", "i32")
    builder.prim("stamp_nanosec", "u32")
    return builder.build()


# --------------------------------------------------------------------------------------------
# One message at a time (signatures as in aero_dva_sim.messages)
# --------------------------------------------------------------------------------------------


def _stamp_values(seconds: float, name: str) -> dict:
    sec, nanosec = divmod(stamp_ns(seconds, name), _NS_PER_S)
    return {"stamp_sec": sec, "stamp_nanosec": nanosec}


def _block(layout_fn, channels, t0, sample_rate, first_index, samples, name, frame_id) -> bytes:
    data = np.asarray(samples, dtype=np.float64)
    if data.ndim != 2 or data.shape[0] != len(channels):
        raise ValueError(f"{name} must have shape ({len(channels)}, n), got {data.shape}")
    layout = layout_fn(data.shape[1], frame_id)
    values = _stamp_values(t0, "t0")
    values.update(sample_rate=float(sample_rate), first_sample_index=_index(first_index))
    values.update(zip(channels, data))
    return layout.encode(values)


def _index(first_index) -> int:
    if isinstance(first_index, (bool, np.bool_)) or not isinstance(
            first_index, (int, np.integer)):
        raise TypeError(f"first_index must be an integer, got {type(first_index).__name__}")
    return int(first_index)


def encode_clock(seconds: float) -> bytes:
    """``rosgraph_msgs/Clock`` at sim time ``seconds`` [s]."""
    return clock_layout().encode(_stamp_values(seconds, "seconds"))


def encode_acceleration_block(t0: float, sample_rate: float, first_index: int,
                              accelerations, frame_id: str = WING_FRAME) -> bytes:
    """``dva_msgs/AccelerationBlock``: stamp ``t0`` [s], ``sample_rate`` [Hz], ``first_index``.

    ``accelerations`` (3, n): plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2].
    """
    return _block(acceleration_block_layout, _ACC_CHANNELS, t0, sample_rate, first_index,
                  accelerations, "accelerations", frame_id)


def encode_displacement_block(t0: float, sample_rate: float, first_index: int,
                              displacements, frame_id: str = WING_FRAME) -> bytes:
    """``dva_msgs/DisplacementBlock``; ``displacements`` (4, n): plunge [m], pitch [rad],
    leading edge [m], DVA stroke [m]."""
    return _block(displacement_block_layout, _DISP_CHANNELS, t0, sample_rate, first_index,
                  displacements, "displacements", frame_id)


def encode_force_block(t0: float, sample_rate: float, first_index: int, force,
                       frame_id: str = "") -> bytes:
    """``dva_msgs/ForceBlock``; ``force`` (n,) aileron force [N]."""
    data = np.asarray(force, dtype=np.float64)
    if data.ndim != 1:
        raise ValueError(f"force must have shape (n,), got {data.shape}")
    return _block(force_block_layout, ("aileron_force",), t0, sample_rate, first_index,
                  data[None, :], "force", frame_id)


def encode_flight_condition(t: float, airspeed: float, density: float,
                            frame_id: str = "") -> bytes:
    """``dva_msgs/FlightCondition`` at ``t`` [s]: airspeed [m/s], air density [kg/m^3]."""
    values = _stamp_values(t, "t")
    values.update(airspeed=airspeed, air_density=density)
    return flight_condition_layout(frame_id).encode(values)


def encode_damper_state(snapshot, frame_id: str = "") -> bytes:
    """``dva_msgs/DamperState`` of a :class:`~aero_dva.flight.damper.DamperSnapshot` (stamp =
    ``snapshot.time``; any object with the snapshot's attributes will do)."""
    values = _stamp_values(snapshot.time, "snapshot.time")
    values.update(
        commanded_damping=float(snapshot.commanded_damping),
        applied_damping=float(snapshot.applied_damping),
        min_damping=float(snapshot.min_damping),
        max_damping=float(snapshot.max_damping),
        command_age=float(snapshot.command_age),
        status=int(snapshot.status),
    )
    return damper_state_layout(snapshot.source, frame_id).encode(values)


def encode_damper_command(t: float, damping: float, source: str, frame_id: str = "") -> bytes:
    """``dva_msgs/DamperCommand`` at ``t`` [s]: ``damping`` c2 [N s/m] from ``source``."""
    values = _stamp_values(t, "t")
    values["damping"] = damping
    return damper_command_layout(source, frame_id).encode(values)


def encode_diagnostic_array(
    t: float,
    statuses: Sequence[tuple[int, str, str, str, Sequence[tuple[str, str]]]],
    frame_id: str = "",
) -> bytes:
    """``diagnostic_msgs/DiagnosticArray`` at ``t`` [s].

    Parameters
    ----------
    t : float
        [s] header stamp.
    statuses : sequence of (level, name, message, hardware_id, values)
        ``level`` 0..3 (OK, WARN, ERROR, STALE); ``values`` a sequence of (key, value) strings.
    frame_id : str
    """
    builder = _LayoutBuilder(DIAGNOSTIC_ARRAY)
    builder.header(frame_id)
    statuses = list(statuses)
    builder.sequence_length(len(statuses))
    for i, status in enumerate(statuses):
        try:
            level, name, message, hardware_id, values = status
        except (TypeError, ValueError):
            raise ValueError(f"statuses[{i}] must be (level, name, message, hardware_id, "
                             f"values), got {status!r}") from None
        if isinstance(level, bool) or not isinstance(level, (int, np.integer)) \
                or not 0 <= level <= 255:
            raise ValueError(f"statuses[{i}] level must be an integer in 0..255, got {level!r}")
        builder.const_u8(int(level))
        builder.string(name, f"statuses[{i}] name")
        builder.string(message, f"statuses[{i}] message")
        builder.string(hardware_id, f"statuses[{i}] hardware_id")
        pairs = list(values)
        builder.sequence_length(len(pairs))
        for key, value in pairs:
            builder.string(key, f"statuses[{i}] key")
            builder.string(value, f"statuses[{i}] value of {key!r}")
    return builder.build().encode(_stamp_values(t, "t"))

