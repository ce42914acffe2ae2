"""ROS time and ``diagnostic_msgs`` values, built one way for every node."""
from __future__ import annotations

import importlib
import math
from collections.abc import Iterable, Mapping

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

#: Diagnostic levels as ints (``DiagnosticStatus`` stores them as one byte).
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVELS = {"ok": OK, "warn": WARN, "error": ERROR, "stale": STALE}

_NS = 1_000_000_000


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (rosidl_runtime_py is not available everywhere).

    Raises ImportError or AttributeError if the type is not installed, ValueError if the name
    is not of that form."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


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


def _text(value) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.9g}"
    return str(value)


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
        values=[KeyValue(key=str(k), value=_text(v)) for k, v in (values or {}).items()])


def diagnostic_array(stamp: Time, statuses: Iterable[DiagnosticStatus]) -> DiagnosticArray:
    """A ``diagnostic_msgs/DiagnosticArray`` stamped ``stamp`` holding ``statuses``."""
    msg = DiagnosticArray()
    msg.header.stamp = stamp
    msg.status = list(statuses)
    return msg
