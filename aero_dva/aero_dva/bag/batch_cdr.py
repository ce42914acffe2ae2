"""The batch CDR encoder: many messages of one type laid out at once as a numpy structured array.

A message type with given sequence lengths and strings has a fixed byte layout
(:class:`CdrLayout`): constant bytes (encapsulation header, string and sequence lengths, string
bytes, zero padding) with numeric fields at fixed offsets. The layout is generated from the
parsed .msg definition (:func:`aero_dva.bag.schemas.message_fields`) by the XCDR1 rules ROS 2
uses (little endian, ``00 01 00 00`` header, primitives aligned to their size counted from
the end of that header, strings and sequences prefixed with a uint32 count, strings ending in
NUL), so a field added to a .msg file is laid out without touching this module. Filling
``k`` copies of it with numpy encodes ``k`` messages with no Python work per message; this is
what the sweep recording needs (``bench/bench_batch_recording.py`` compares it with rosbags'
per-message serializer). The bytes are rosbags' (tests compare them).

Pure: no ROS imports, no file I/O.
"""
from __future__ import annotations

import math
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType

import numpy as np

from aero_dva.bag.schemas import Nodetype, message_fields, normalize_type_name

__all__ = [
    "CDR_HEADER",
    "CdrLayout",
    "cdr_layout",
    "sample_fields",
    "split_stamps",
    "stamp_ns",
    "stamps_from_seconds",
]

#: Encapsulation header of every message: CDR little endian (0x0001), options 0.
CDR_HEADER = b"\x00\x01\x00\x00"

_NS_PER_S = 1_000_000_000
_INT32 = (-(2**31), 2**31 - 1)
# .msg primitive -> little-endian numpy dtype (its size is its CDR alignment)
_DTYPES = {
    "bool": "u1", "byte": "u1", "char": "u1", "uint8": "u1", "int8": "i1",
    "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4",
    "int64": "<i8", "uint64": "<u8", "float32": "<f4", "float64": "<f8",
}


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
    """Fixed byte layout of one message type for given sequence lengths and strings.

    Attributes
    ----------
    type_name : str
        ``pkg/msg/Type``.
    template : bytes
        The whole serialized message with every numeric field zero: encapsulation header,
        string and sequence lengths, string bytes and (zero) padding.
    fields : mapping of str to (int, numpy.dtype, tuple)
        Numeric field path (``"header.stamp.sec"``, ``"plunge"``) -> (byte offset from the
        start of the message, element dtype, shape: ``()`` for a scalar, ``(n,)`` for the
        elements of a sequence or array, whose length is part of the template).
    """

    type_name: str
    template: bytes
    fields: Mapping[str, tuple[int, np.dtype, tuple]]

    @property
    def size(self) -> int:
        """[bytes] length of the serialized message, header included."""
        return len(self.template)

    def dtype_fields(self, offset: int = 0, prefix: str = "") -> dict[str, tuple]:
        """numpy structured-dtype entries ``{prefix + path: (dtype, offset + byte offset)}``;
        a sequence field has a subarray dtype ``(dtype, (n,))``."""
        out = {}
        for name, (where, dtype, shape) in self.fields.items():
            out[prefix + name] = (np.dtype((dtype, shape)) if shape else dtype, offset + where)
        return out

    def dtype(self) -> np.dtype:
        """Structured dtype of one message (itemsize = :attr:`size`)."""
        return structured_dtype(self.dtype_fields(), self.size)

    def batch(self, count: int) -> np.ndarray:
        """``count`` copies of the template as a structured array to fill field by field;
        ``.tobytes()`` then gives the messages back to back (each :attr:`size` bytes)."""
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise ValueError(f"count must be an integer >= 0, got {count!r}")
        raw = np.tile(np.frombuffer(self.template, dtype=np.uint8), int(count))
        return raw.view(self.dtype())


def structured_dtype(entries: Mapping[str, tuple], itemsize: int) -> np.dtype:
    """A structured dtype from ``{name: (dtype, offset)}`` entries."""
    return np.dtype({"names": list(entries), "formats": [d for d, _ in entries.values()],
                     "offsets": [o for _, o in entries.values()], "itemsize": itemsize})


class _Builder:
    """Walk a message's parsed fields in order, applying the CDR alignment rules."""

    def __init__(self, type_name: str, lengths: Mapping[str, int], strings: Mapping[str, str]):
        self.type_name = type_name
        self.lengths, self.strings = lengths, strings
        self.used: set[str] = set()
        self.buf = bytearray(CDR_HEADER)
        self.fields: dict[str, tuple[int, np.dtype, tuple]] = {}

    def align(self, size: int) -> None:
        self.buf += b"\0" * (-(len(self.buf) - len(CDR_HEADER)) % size)

    def u32(self, value: int) -> None:
        self.align(4)
        self.buf += struct.pack("<I", value)

    def primitive(self, path: str, name: str, count: int | None = None) -> None:
        """A scalar (``count`` None) or ``count`` elements of an array or sequence."""
        dtype = np.dtype(_DTYPES[name])
        if count != 0:
            self.align(dtype.itemsize)
        self.fields[path] = (len(self.buf), dtype, () if count is None else (count,))
        self.buf += b"\0" * (dtype.itemsize * (1 if count is None else count))

    def string(self, path: str) -> None:
        self.used.add(path)
        text = self.strings.get(path, "")
        if not isinstance(text, str):
            raise TypeError(f"{self.type_name}.{path} must be a string, got "
                            f"{type(text).__name__}")
        data = text.encode("utf-8")
        if b"\0" in data:
            raise ValueError(f"{self.type_name}.{path} must not contain NUL: {text!r}")
        self.u32(len(data) + 1)
        self.buf += data + b"\0"

    def length(self, path: str) -> int:
        self.used.add(path)
        if path not in self.lengths:
            raise ValueError(f"{self.type_name}.{path} is a sequence: its length must be given")
        n = self.lengths[path]
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise ValueError(f"{self.type_name}.{path} length must be an integer >= 0, "
                             f"got {n!r}")
        return int(n)

    def message(self, type_name: str, prefix: str, depth: int = 0) -> None:
        if depth > 20:
            raise ValueError(f"{self.type_name}: nested types too deep at {prefix!r}")
        for name, (kind, args) in message_fields(type_name):
            path = prefix + name
            if kind == Nodetype.BASE:
                self.scalar(args[0], path, depth)
            elif kind == Nodetype.NAME:
                self.message(args, path + ".", depth + 1)
            else:  # ARRAY (fixed length) or SEQUENCE (uint32 count first)
                (item_kind, item), bound = args
                count = bound if kind == Nodetype.ARRAY else self.length(path)
                if kind == Nodetype.SEQUENCE:
                    if bound and count > bound:
                        raise ValueError(f"{self.type_name}.{path}: {count} elements, "
                                         f"at most {bound}")
                    self.u32(count)
                if item_kind == Nodetype.BASE and item[0] in _DTYPES:
                    self.primitive(path, item[0], count)
                elif count:
                    raise ValueError(f"{self.type_name}.{path}: a batch layout holds only "
                                     "empty sequences of strings or messages")

    def scalar(self, name: str, path: str, depth: int) -> None:
        if name in _DTYPES:
            self.primitive(path, name)
        elif name == "string":
            self.string(path)
        else:
            raise ValueError(f"{self.type_name}.{path}: {name} has no batch layout")

    def build(self) -> CdrLayout:
        unknown = (set(self.lengths) | set(self.strings)) - self.used
        if unknown:
            raise ValueError(f"{self.type_name} has no string or sequence fields "
                             f"{sorted(unknown)}")
        return CdrLayout(self.type_name, bytes(self.buf), MappingProxyType(dict(self.fields)))


@lru_cache(maxsize=128)
def _cached_layout(type_name: str, lengths: tuple, strings: tuple) -> CdrLayout:
    builder = _Builder(type_name, dict(lengths), dict(strings))
    builder.message(type_name, "")
    return builder.build()


def cdr_layout(type_name: str, lengths: Mapping[str, int] | None = None,
               strings: Mapping[str, str] | None = None) -> CdrLayout:
    """The byte layout of ``type_name`` from its parsed .msg definition.

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type`` or ``pkg/Type``.
    lengths : mapping of str to int
        Field path -> element count of every sequence field (``{"plunge": 50, ...}``);
        sequences of strings or messages can only be empty here.
    strings : mapping of str to str
        Field path -> value of string fields (``{"header.frame_id": "wing"}``; default "").

    Raises
    ------
    ValueError
        A sequence without length, an unknown field path, a NUL in a string.
    """
    full = normalize_type_name(type_name)
    return _cached_layout(full, tuple(sorted((lengths or {}).items())),
                          tuple(sorted((strings or {}).items())))


def sample_fields(type_name: str) -> tuple[str, ...]:
    """The ``float64[]`` fields of a sample-block message, in .msg order."""
    return tuple(name for name, (kind, args) in message_fields(type_name)
                 if kind == Nodetype.SEQUENCE and args[0] == (Nodetype.BASE, ("float64", 0)))
