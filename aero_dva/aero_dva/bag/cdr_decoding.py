"""Fast CDR decoding of the flight-log messages: sample blocks, flight condition, damper state.

A generic ROS 2 decoder (mcap-ros2-support) reads a float64 sequence one element at a time in
Python, about 5 us per sample; a training sweep has 10^7 samples per channel. The messages here
have one fixed shape, ``std_msgs/Header`` then a few primitives and float64 sequences, so each
sequence is one ``np.frombuffer`` view. The rules are those of :mod:`aero_dva.bag.cdr_encoding`
(XCDR1: a 4-byte encapsulation header, primitives aligned to their size counted from the end of
that header, strings and sequences prefixed with a uint32 count). Big-endian data, other
encapsulations and any inconsistency raise :class:`CdrDecodeError` naming what is wrong. Pure: no
ROS imports, no file I/O.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

_CDR_LE = b"\x00\x01"  # the encapsulation ROS 2 writes on little-endian machines
_U32 = struct.Struct("<I")
_I32_U32 = struct.Struct("<iI")
_HEADER = struct.Struct("<iII")  # stamp sec, nanosec, frame_id length
_F64 = struct.Struct("<d")
_F64_U64 = struct.Struct("<dQ")


class CdrDecodeError(ValueError):
    """The bytes are not the expected message in little-endian XCDR1."""


@dataclass(frozen=True)
class SampleBlock:
    """An AccelerationBlock, DisplacementBlock or ForceBlock: one (n,) array per channel."""

    stamp: float  # [s]
    sample_rate: float  # [Hz]
    first_index: int
    channels: tuple[np.ndarray, ...]


class _Reader:
    """Position in one message's body; offsets count from the end of the 4-byte header."""

    def __init__(self, data: bytes, type_name: str):
        if len(data) < 4 or bytes(data[:2]) != _CDR_LE:
            raise CdrDecodeError(f"{type_name}: not little-endian CDR (encapsulation "
                                 f"{bytes(data[:4]).hex() or 'missing'})")
        self.data = memoryview(data)
        self.pos = 4
        self.type_name = type_name

    def _take(self, size: int, align: int) -> int:
        self.pos += -(self.pos - 4) % align
        start = self.pos
        self.pos += size
        if self.pos > len(self.data):
            raise CdrDecodeError(f"{self.type_name}: message ends after {len(self.data)} bytes, "
                                 f"field needs {self.pos}")
        return start

    def header_stamp(self) -> float:
        sec, nanosec = _I32_U32.unpack_from(self.data, self._take(8, 4))
        (length,) = _U32.unpack_from(self.data, self._take(4, 4))  # frame_id
        self._take(length, 1)
        return sec + 1e-9 * nanosec

    def float64(self) -> float:
        return _F64.unpack_from(self.data, self._take(8, 8))[0]


def decode_sample_block(data: bytes, channels: int, type_name: str = "sample block"
                        ) -> SampleBlock:
    """Header, float64 sample_rate, uint64 first_sample_index, ``channels`` float64 sequences of
    one length (AccelerationBlock: 3, DisplacementBlock: 4, ForceBlock: 1).

    Written out rather than with :class:`_Reader`: it runs once per block of a 10^6-block log.
    """
    size = len(data)
    if size < 16 or data[:2] != _CDR_LE:
        raise CdrDecodeError(f"{type_name}: not little-endian CDR, or shorter than a header "
                             f"({size} bytes)")
    sec, nanosec, length = _HEADER.unpack_from(data, 4)
    body = 12 + length  # offsets from the end of the encapsulation header
    body += -body % 8
    if 4 + body + 16 > size:
        raise CdrDecodeError(f"{type_name}: message ends after {size} bytes, inside its header")
    rate, first = _F64_U64.unpack_from(data, 4 + body)
    body += 16
    arrays = []
    for _ in range(channels):
        body += -body % 4
        if 4 + body + 4 > size:
            raise CdrDecodeError(f"{type_name}: message ends after {size} bytes, before "
                                 f"channel {len(arrays)}")
        (count,) = _U32.unpack_from(data, 4 + body)
        body += 4
        body += -body % 8
        if 4 + body + 8 * count > size:
            raise CdrDecodeError(f"{type_name}: channel {len(arrays)} claims {count} samples, "
                                 f"more than the {size} bytes hold")
        arrays.append(np.frombuffer(data, dtype="<f8", count=count, offset=4 + body))
        body += 8 * count
    if len({a.size for a in arrays}) > 1:
        raise CdrDecodeError(f"{type_name}: channels of different lengths "
                             f"{[a.size for a in arrays]}")
    return SampleBlock(sec + 1e-9 * nanosec, rate, first, tuple(arrays))


def decode_flight_condition(data: bytes) -> tuple[float, float, float]:
    """``dva_msgs/FlightCondition``: (stamp [s], airspeed [m/s], air density [kg/m^3])."""
    reader = _Reader(data, "FlightCondition")
    stamp = reader.header_stamp()
    return stamp, reader.float64(), reader.float64()


def decode_damper_state_applied(data: bytes) -> tuple[float, float]:
    """``dva_msgs/DamperState``: (stamp [s], applied c2 [N s/m]); the other fields are skipped."""
    reader = _Reader(data, "DamperState")
    stamp = reader.header_stamp()
    reader.float64()  # commanded_damping, skipped
    return stamp, reader.float64()
