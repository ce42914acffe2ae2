"""JSON file of the airspeed schedule (Zhang (2006) eq. 7.1), read by the airspeed controller.

Example (SI units; the units object is checked on load so a file written in the study's
N-s/mm is refused rather than misread; the damping range must lie inside the damper's,
:data:`~aero_dva.flight.damper.DAMPER_RANGE`, or the file is neither written nor read)::

    {
      "format": "dva_airspeed_schedule",
      "version": 1,
      "equation": "c2 = a0 + a1 * U  (Zhang 2006, eq. 7.1)",
      "a0": -2150.0,
      "a1": 31.5,
      "airspeed_min": 115.0,
      "airspeed_max": 120.0,
      "damping_min": 0.0,
      "damping_max": 2500.0,
      "units": {"a0": "N s/m", "a1": "N s^2/m^2", "airspeed": "m/s", "damping": "N s/m"},
      "description": "free text, e.g. how the fit was made and its residual"
    }
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from aero_dva import input_ranges as ranges
from aero_dva.atomic_io import atomic_output
from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.flight.damper import damping_problem
from aero_dva.safe_files import check_file_header, parse_json
from aero_dva.text_input import read_text_input

__all__ = [
    "FILE_FORMAT",
    "FILE_VERSION",
    "UNITS",
    "ScheduleFileError",
    "load_schedule",
    "save_schedule",
    "schedule_from_dict",
    "schedule_to_dict",
]

FILE_FORMAT = "dva_airspeed_schedule"
FILE_VERSION = 1
UNITS = {"a0": "N s/m", "a1": "N s^2/m^2", "airspeed": "m/s", "damping": "N s/m"}
_NUMBERS = ("a0", "a1", "airspeed_min", "airspeed_max", "damping_min", "damping_max")


class ScheduleFileError(ValueError):
    """An airspeed schedule file is missing, unreadable or invalid."""


def schedule_to_dict(schedule: AirspeedSchedule, description: str = "") -> dict:
    """The JSON object for a schedule (see the module docstring)."""
    if not isinstance(schedule, AirspeedSchedule):
        raise TypeError(f"schedule must be an AirspeedSchedule, got {type(schedule).__name__}")
    if not isinstance(description, str):
        raise TypeError("description must be a string")
    problem = damping_problem(schedule.damping_range, "airspeed schedule damping range")
    if problem is not None:
        raise ScheduleFileError(problem)
    return {
        "format": FILE_FORMAT,
        "version": FILE_VERSION,
        "equation": "c2 = a0 + a1 * U  (Zhang 2006, eq. 7.1)",
        "a0": schedule.a0,
        "a1": schedule.a1,
        "airspeed_min": schedule.airspeed_range[0],
        "airspeed_max": schedule.airspeed_range[1],
        "damping_min": schedule.damping_range[0],
        "damping_max": schedule.damping_range[1],
        "units": dict(UNITS),
        "description": description,
    }


def schedule_from_dict(data: dict, source: str = "<dict>") -> AirspeedSchedule:
    """Validate a JSON object and build the schedule; errors name ``source`` and the field."""

    def fail(what: str) -> ScheduleFileError:
        return ScheduleFileError(f"airspeed schedule {source}: {what}")

    check_file_header(data, fail, FILE_FORMAT, FILE_VERSION, UNITS)
    values = {}
    for key in _NUMBERS:
        if key not in data:
            raise fail(f"field {key!r} is missing")
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise fail(f"field {key!r} must be a number, got {type(value).__name__}")
        if not math.isfinite(value):
            raise fail(f"field {key!r} must be finite, got {value}")
        values[key] = float(value)
    try:
        ranges.check_fields(values, ranges.SCHEDULE)
    except ValueError as exc:
        raise fail(str(exc)) from None
    problem = damping_problem((values["damping_min"], values["damping_max"]),
                              "fields 'damping_min' and 'damping_max'")
    if problem is not None:
        raise fail(problem)
    try:
        return AirspeedSchedule(
            a0=values["a0"],
            a1=values["a1"],
            airspeed_range=(values["airspeed_min"], values["airspeed_max"]),
            damping_range=(values["damping_min"], values["damping_max"]),
        )
    except (TypeError, ValueError) as exc:
        raise fail(str(exc)) from None


def save_schedule(schedule: AirspeedSchedule, path, description: str = "") -> Path:
    """Write a schedule as JSON, atomically (temporary file + rename). Returns the path."""
    text = json.dumps(schedule_to_dict(schedule, description), indent=2, allow_nan=False)
    path = Path(path)
    with atomic_output(path) as stream:
        stream.write(text + "\n")
    return path


def load_schedule(path) -> AirspeedSchedule:
    """Read and validate a schedule file.

    Raises
    ------
    ScheduleFileError
        If the file is missing, not JSON, or a field is missing, mistyped, in other units or
        out of range.
    """
    path = Path(path)
    text = read_text_input(path, "airspeed schedule", error=ScheduleFileError)
    data = parse_json(text, f"airspeed schedule {str(path)!r}", ScheduleFileError,
                      nonfinite=True)  # each field is checked finite by name
    return schedule_from_dict(data, repr(str(path)))
