"""What a flight log says in a few numbers: divergence airspeed, RMS response, c2 used: what
``run_flight`` prints and ``dva report`` tabulates, with the detector and the RMS range of
``dva evaluate``."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from aero_dva.bag.flight_log_io import FlightLog
from aero_dva.flight.divergence import STOP_PREFIX, WINDOW, divergence_airspeed
from aero_dva.flight.range_rms import RMS_RANGE, range_mean, range_rms
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
        [m/s] the project's one detector,
        :func:`~aero_dva.flight.divergence.divergence_airspeed`; NaN if none.
    divergence_ratio : float
        divergence_airspeed / critical_airspeed.
    leading_edge_rms : float
        [m] RMS of the leading-edge displacement over ``rms_range`` (U/U_cr, after the first
        2 s: :mod:`aero_dva.flight.range_rms`, the range ``dva evaluate`` compares controllers
        over); NaN when the flight did not pass the range's top or U_cr is unknown.
    mean_damping : float
        [N s/m] mean c2 that acted over the same samples (a per-sample law's, sample by
        sample, where it flew).
    rms_range : (float, float)
        [U/U_cr] the range of the two above.
    leading_edge_rms_before_divergence : float
        [m] RMS over whatever the flight flew before its divergence (the whole flight if none):
        not comparable between flights that diverge at different airspeeds.
    stopped_by_simulator : bool
        The simulator reported that it stopped the flight (the leading edge beyond its limit).
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
    rms_range: tuple[float, float]
    leading_edge_rms_before_divergence: float
    stopped_by_simulator: bool
    missing_samples: int

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and math.isnan(v) else
                    list(v) if isinstance(v, tuple) else v)
                for k, v in asdict(self).items()}


def _critical_airspeed(log: FlightLog) -> float:
    for status in reversed(log.diagnostics):
        value = status["values"].get("critical_airspeed_no_dva")
        if value is not None:
            return float(value)
    return math.nan


#: [s] longest block whose airspeeds :func:`sample_airspeed` reads as a ramp (the graph's are
#: 0.05 s; a stepped sweep holds each airspeed for seconds).
RAMP_BLOCK = 0.25


def sample_airspeed(log: FlightLog) -> np.ndarray:
    """[m/s] the airspeed of each sample of ``log``. A bag holds it once per block
    (``flight/condition``); when it changes with every block (runs of one length, at most
    :data:`RAMP_BLOCK` seconds) and the blocks' airspeeds lie on one straight line (a ramp),
    each sample's is read off that line, as the simulator flew it and the in-process evaluation
    measures it (a block's value would shift the RMS range's ends and the divergence reading by
    up to a block); otherwise (constant, steps) each sample keeps its block's value."""
    u = log.airspeed
    finite = np.isfinite(u)
    changed = np.ones(u.size, dtype=bool)
    changed[1:] = u[1:] != u[:-1]
    starts = np.flatnonzero(finite & changed)
    if starts.size < 3:
        return u
    runs = np.diff(starts)
    if np.any(runs != runs[0]) or runs[0] > RAMP_BLOCK * log.sample_rate:
        return u
    slope = np.diff(u[starts]) / runs
    if not np.allclose(slope, slope[0], rtol=1e-6, atol=0.0):
        return u
    line = np.polynomial.Polynomial.fit(starts, u[starts], 1)(np.arange(u.size))
    return np.where(finite, line, np.nan)


def summarize(log: FlightLog, rms_range: tuple[float, float] = RMS_RANGE) -> FlightSummary:
    """Summarise ``log``; ``rms_range`` [U/U_cr] of the RMS that compares flights."""
    edge = log.displacements[LEADING_EDGE]
    speeds_logged = sample_airspeed(log)
    valid = ~np.isnan(edge) & ~np.isnan(speeds_logged)
    response = edge[valid]
    airspeed = speeds_logged[valid]
    u_div = math.nan
    if response.size >= 3 * WINDOW * log.sample_rate:
        u_div = divergence_airspeed(airspeed, response, log.sample_rate)
    stable = airspeed < u_div if not math.isnan(u_div) else np.ones(response.size, bool)
    u_cr = _critical_airspeed(log)
    speeds = (rms_range[0] * u_cr, rms_range[1] * u_cr)
    known = u_cr > 0
    return FlightSummary(
        duration=float(log.time[-1] + 1.0 / log.sample_rate) if log.time.size else 0.0,
        airspeed_start=float(airspeed[0]) if airspeed.size else math.nan,
        airspeed_end=float(airspeed[-1]) if airspeed.size else math.nan,
        critical_airspeed=u_cr,
        divergence_airspeed=float(u_div),
        divergence_ratio=float(u_div / u_cr) if known else math.nan,
        leading_edge_rms=range_rms(speeds_logged, edge, log.sample_rate, speeds) if known
        else math.nan,
        mean_damping=range_mean(speeds_logged, log.damping, log.sample_rate, speeds)
        if known else math.nan,
        rms_range=(float(rms_range[0]), float(rms_range[1])),
        leading_edge_rms_before_divergence=float(np.sqrt(np.mean(response[stable] ** 2)))
        if stable.any() else math.nan,
        stopped_by_simulator=any(s["message"].startswith(STOP_PREFIX)
                                 or "diverged" in s["message"]  # bags of earlier versions
                                 for s in log.diagnostics if s["name"].startswith("simulator")),
        missing_samples=log.missing_samples,
    )
