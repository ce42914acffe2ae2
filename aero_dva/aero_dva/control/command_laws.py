"""The controllers' command laws without ROS: what c2 a controller node commands for an input.

The ``rbf_controller`` and ``airspeed_controller`` nodes call these for each message, and
``dva replay --offline`` calls them on a recorded bag, so both give the same commands.

- :class:`RBFLaw`: the network's output for a scaled spectrum and the current c2 (eq. 7.4-7.5,
  input as :func:`~aero_dva.control.rbf_network.spectrum_input_vector`), clamped to the damper.
- :class:`ScheduleLaw`: ``c2 = a0 + a1 U`` (eq. 7.1) for a valid airspeed, clamped to the damper,
  at most one command per ``min_period`` of time (stamps of the flight conditions).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.rbf_network import RBFNetwork, spectrum_input_vector

__all__ = ["RBFLaw", "ScheduleCommand", "ScheduleLaw", "clamp"]


def clamp(value: float, low: float, high: float) -> float:
    """``value`` limited to ``[low, high]``."""
    return min(max(value, low), high)


@dataclass(frozen=True)
class RBFLaw:
    """c2 from a scaled spectrum with a trained RBF network, clamped to ``damping_range``."""

    network: RBFNetwork
    damping_range: tuple[float, float]

    def command(self, magnitudes, damping: float) -> tuple[float, float]:
        """Clamped output [N s/m] for ``magnitudes`` (channels, n_freq) and the current c2
        ``damping`` [N s/m], and the largest hidden activation (1.0 for a network of no
        neurons). The output is NaN (not clamped) if the network gives no finite value."""
        x = spectrum_input_vector(np.asarray(magnitudes, dtype=float), damping)
        activation = float(self.network.hidden(x).max()) if self.network.n_neurons else 1.0
        c2 = float(self.network.predict(x))
        if not math.isfinite(c2):
            return c2, activation
        return clamp(c2, *self.damping_range), activation


@dataclass(frozen=True)
class ScheduleCommand:
    """What :meth:`ScheduleLaw.step` did with one flight condition: ``kind`` is "command"
    (``damping`` set), "rejected" (``reason`` says why) or "rate_limited"."""

    kind: str
    damping: float = math.nan
    reason: str = ""


class ScheduleLaw:
    """Commands of the airspeed schedule for a stream of flight conditions.

    Parameters
    ----------
    schedule : AirspeedSchedule
    damping_range : (float, float)
        [N s/m] the damper's range; commands are clamped to it.
    extrapolate : bool
        Continue the schedule's line outside its fitted airspeeds.
    max_airspeed : float
        [m/s] larger airspeeds (and NaN, inf, negative ones) are rejected.
    min_period_ns : int
        [ns] least time between two commands (stamps); 0: one per condition.
    """

    def __init__(self, schedule: AirspeedSchedule, damping_range: tuple[float, float],
                 extrapolate: bool, max_airspeed: float, min_period_ns: int = 0) -> None:
        self.schedule = schedule
        self.damping_range = damping_range
        self.extrapolate = extrapolate
        self.max_airspeed = max_airspeed
        self.min_period_ns = int(min_period_ns)
        self._last_ns: int | None = None

    def command_for(self, airspeed: float) -> float:
        """[N s/m] the clamped eq. 7.1 command at a valid airspeed [m/s]."""
        c2 = self.schedule.evaluate(airspeed, extrapolate=self.extrapolate)
        return clamp(c2, *self.damping_range)

    def step(self, stamp_ns: int, airspeed: float) -> ScheduleCommand:
        """The command for a flight condition stamped ``stamp_ns`` [ns] at ``airspeed``."""
        if not (math.isfinite(airspeed) and 0.0 <= airspeed <= self.max_airspeed):
            return ScheduleCommand("rejected", reason=f"airspeed {airspeed} m/s is not in "
                                   f"[0, {self.max_airspeed:g}] m/s")
        last = self._last_ns
        if last is not None and 0 <= stamp_ns - last < self.min_period_ns:
            return ScheduleCommand("rate_limited")
        self._last_ns = stamp_ns
        return ScheduleCommand("command", self.command_for(airspeed))
