"""The stated range of every number an input file of the project holds, checked on load.

A number outside its range (zero where a mass belongs, 1e300, a subnormal, NaN, infinity) is
an input error: one line naming the file, the field, the range and the value (exit code 2),
never an overflow or a division by zero deep in the numerics. The ranges are wide: they bound
what this model of a wing section, its absorber and its flights can mean, not what is usual.
docs/reliability.md lists every table. Pure data and checks (no numerics imports).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["AIR_DENSITY", "ABSORBER", "AIRSPEED", "GAINS", "GAIN_ROWS", "MAX_AIRSPEED",
           "MAX_DAMPING", "NETWORK", "PLAN", "Range", "SAMPLE_RATE", "SCHEDULE", "SECTION", "WING",
           "check_fields", "check_number", "check_numbers"]


#: [m/s] a subsonic wing: an airspeed above this, in a file, a scenario or measured in flight,
#: is a unit or sensor error (the airspeed controller ignores it).
MAX_AIRSPEED = 400.0
#: [N s/m] far above any damper of this size class: a larger c2, in a file or a parameter, is a
#: unit error.
MAX_DAMPING = 1.0e6


@dataclass(frozen=True)
class Range:
    """Closed interval ``[low, high]`` of a number in ``unit``; ``inf_means``: +inf is allowed
    too and means this (a locked damper)."""

    low: float
    high: float
    unit: str = ""
    inf_means: str = ""

    def text(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        extra = f", or inf ({self.inf_means})" if self.inf_means else ""
        return f"[{self.low:g}, {self.high:g}]{unit}{extra}"

    def holds(self, value: float) -> bool:
        return self.low <= value <= self.high or (bool(self.inf_means) and value == math.inf)


def check_number(value, name: str, rng: Range) -> float:
    """``value`` as a float if it is a real number inside ``rng``; else ValueError naming
    ``name`` and the range."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} must be a number, got {type(value).__name__}")
    number = float(value)
    if not rng.holds(number):
        raise ValueError(f"{name} must be in {rng.text()}, got {number:g}")
    return number


def check_numbers(values, name: str, rng: Range) -> None:
    """Every number of a (nested) list inside ``rng`` (the first one outside is named)."""
    if isinstance(values, (list, tuple)):
        for index, value in enumerate(values):
            check_numbers(value, f"{name}[{index}]", rng)
    else:
        check_number(values, name, rng)


def check_fields(data: Mapping, table: Mapping[str, Range], where: str = "") -> None:
    """Every field of ``table`` that ``data`` holds inside its range (ValueError naming
    ``where`` and the field)."""
    prefix = f"{where}: " if where else ""
    for name, rng in table.items():
        if name in data:
            try:
                check_number(data[name], name, rng)
            except ValueError as exc:
                raise ValueError(f"{prefix}{exc}") from None


#: [kg/m^3] air from 40 km altitude (0.004) to a cold sea-level day and beyond.
AIR_DENSITY = Range(1e-3, 2.0, "kg/m^3")

#: The ``wing`` section of a wing file (WingParameters); positions are also checked against
#: the chord.
WING = {
    "mass": Range(1e-3, 1e7, "kg"),
    "inertia": Range(1e-6, 1e8, "kg m^2"),
    "plunge_stiffness": Range(1e-3, 1e12, "N/m"),
    "pitch_stiffness": Range(1e-3, 1e12, "N m/rad"),
    "damping_factor": Range(0.0, 1.0, "s"),
    "chord": Range(1e-3, 100.0, "m"),
    "gravity_centre": Range(0.0, 100.0, "m"),
    "elastic_axis": Range(-100.0, 100.0, "m"),
    "aileron_position": Range(-100.0, 100.0, "m"),
    "lift_slope": Range(0.01, 20.0, "1/rad"),
    "span": Range(1e-3, 1e4, "m"),
}

#: The ``absorber`` section of a wing file (passive or Maxwell).
ABSORBER = {
    "mass": Range(1e-6, 1e6, "kg"),
    "stiffness": Range(0.0, 1e12, "N/m"),
    "series_stiffness": Range(1.0, 1e12, "N/m"),
    "damping": Range(0.0, MAX_DAMPING, "N s/m", inf_means="a locked damper"),
    "position": Range(-100.0, 100.0, "m"),
}

#: A typical-section file (nondimensional textbook parameters).
SECTION = {
    "semichord": Range(1e-3, 50.0, "m"),
    "mass_ratio": Range(0.1, 1e4),
    "radius_of_gyration_sq": Range(1e-4, 10.0),
    "frequency_ratio": Range(1e-3, 100.0),
    "static_unbalance": Range(-2.0, 2.0),
    "elastic_axis": Range(-1.0, 1.0),
    "pitch_frequency": Range(1e-3, 1e4, "rad/s"),
    "air_density": AIR_DENSITY,
}

#: An airspeed schedule file (eq. 7.1), besides its damping range (the damper's).
SCHEDULE = {
    "a0": Range(-1e6, 1e6, "N s/m"),
    "a1": Range(-1e5, 1e5, "N s^2/m^2"),
    "airspeed_min": Range(0.0, MAX_AIRSPEED, "m/s"),
    "airspeed_max": Range(0.0, MAX_AIRSPEED, "m/s"),
}

#: [m/s] an airspeed of this subsonic model (the scenarios' bound).
AIRSPEED = Range(0.0, MAX_AIRSPEED, "m/s")
#: [Hz] a flight's sample rate (aero_dva.flight.flight_limits.SAMPLE_RATE_RANGE).
SAMPLE_RATE = Range(100.0, 20_000.0, "Hz")

#: A switching-gains file's numbers (its c2 levels are the damper's range).
GAINS = {
    "design_airspeed": Range(1.0, MAX_AIRSPEED, "m/s"),
    "density": AIR_DENSITY,
    "time_constant": Range(0.0, 10.0, "s"),
    "sample_rate": SAMPLE_RATE,
    "effort": Range(1e-9, 1e12),
    "lead": Range(0.0, 0.1, "s"),
}
#: Entries of a gains file's arrays: ``gain`` is scaled to at most 1 in magnitude by the
#: design, the observer's entries are fractions of the measured outputs' innovation, the
#: force rows are k2 [N/m] times a transition matrix; ``airspeeds`` [m/s] of a schedule.
GAIN_ROWS = {
    "gain": Range(-1e6, 1e6),
    "observer": Range(-1e6, 1e6),
    "force_gain": Range(-1e12, 1e12),
    "airspeeds": Range(1.0, MAX_AIRSPEED, "m/s"),
}

#: A training plan's own numbers besides its settings (PlanSettings checks those) and c2.
PLAN = {
    "critical_airspeed": Range(1.0, MAX_AIRSPEED, "m/s"),
    "base_density": AIR_DENSITY,
}

#: An RBF network file's header numbers (its spread has its own bounds, rbf_io).
NETWORK = {
    "output_bias": Range(-1e6, 1e6, "N s/m"),
    "offset": Range(-1e12, 1e12),
    "scale": Range(1e-12, 1e12),
}
