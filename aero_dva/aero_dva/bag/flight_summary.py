"""What a flight log says in a few numbers: divergence airspeed, RMS response, c2 used."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from aero_dva.bag.flight_log_io import FlightLog
from aero_dva.flight.divergence import divergence_airspeed
from aero_dva.wing.model import LEADING_EDGE


@dataclass(frozen=True)
class FlightSummary:
    """Headline numbers of one flight (SI units; ratios are U / U_cr of the wing without DVA).

    Attributes
    ----------
    duration : float
        [s] flown (shorter than the scenario when the flight was stopped at divergence).
    airspeed_start, airspeed_end : float
        [m/s]
    critical_airspeed : float
        [m/s] U_cr of the wing without DVA (NaN if the log does not say).
    divergence_airspeed : float
        [m/s] per :func:`~aero_dva.flight.divergence.divergence_airspeed`; NaN if none.
    divergence_ratio : float
        divergence_airspeed / critical_airspeed.
    leading_edge_rms : float
        [m] RMS of the leading-edge displacement before divergence (whole flight if none).
    mean_damping : float
        [N s/m] mean applied c2 before divergence.
    stopped_by_simulator : bool
        The simulator reported divergence and stopped the flight.
    missing_samples : int
        Samples with no data in the log.
    """

    duration: float
    airspeed_start: float
    airspeed_end: float
    critical_airspeed: float
    divergence_airspeed: float
    divergence_ratio: float
    leading_edge_rms: float
    mean_damping: float
    stopped_by_simulator: bool
    missing_samples: int

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v)
                for k, v in asdict(self).items()}


def _critical_airspeed(log: FlightLog) -> float:
    for status in reversed(log.diagnostics):
        value = status["values"].get("critical_airspeed_no_dva")
        if value is not None:
            return float(value)
    return math.nan


def summarize(log: FlightLog, window: float = 1.0) -> FlightSummary:
    """Summarise ``log``; ``window`` [s] is the RMS window of the divergence test."""
    valid = ~np.isnan(log.displacements[LEADING_EDGE]) & ~np.isnan(log.airspeed)
    response = log.displacements[LEADING_EDGE][valid]
    airspeed = log.airspeed[valid]
    u_div = math.nan
    if response.size >= 3 * window * log.sample_rate:
        u_div = divergence_airspeed(airspeed, response, log.sample_rate, window=window)
    stable = airspeed < u_div if not math.isnan(u_div) else np.ones(response.size, bool)
    damping = log.applied_damping[valid][stable]
    u_cr = _critical_airspeed(log)
    return FlightSummary(
        duration=float(log.time[-1] + 1.0 / log.sample_rate) if log.time.size else 0.0,
        airspeed_start=float(airspeed[0]) if airspeed.size else math.nan,
        airspeed_end=float(airspeed[-1]) if airspeed.size else math.nan,
        critical_airspeed=u_cr,
        divergence_airspeed=float(u_div),
        divergence_ratio=float(u_div / u_cr) if u_cr > 0 else math.nan,
        leading_edge_rms=float(np.sqrt(np.mean(response[stable] ** 2))) if stable.any()
        else math.nan,
        mean_damping=float(np.nanmean(damping)) if np.isfinite(damping).any() else math.nan,
        stopped_by_simulator=any("diverged" in s["message"] for s in log.diagnostics
                                 if s["name"].startswith("simulator")),
        missing_samples=log.missing_samples,
    )
