"""Airspeed schedule of the tunable damper, ``c2 = a0 + a1 U`` (Zhang (2006) eq. 7.1).

The study fits eq. 7.1 by least squares to the optimal c2 of fig. 7.4 over the airspeeds where
that curve is almost linear (U = 115 to 120 m/s) and flies the schedule over the whole ramp
(0.8 to 1.2 Ucr). Evaluation therefore extrapolates the line outside the fitted airspeed range
by default (``extrapolate=False`` holds the end values instead), and always clamps the result
to the damper's range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aero_dva.input_ranges import MAX_AIRSPEED

__all__ = ["MAX_AIRSPEED", "AirspeedSchedule", "ScheduleFit", "fit_airspeed_schedule"]


def _real(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def _range(pair, name: str, lower: float) -> tuple[float, float]:
    try:
        lo, hi = pair
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a (min, max) pair") from None
    lo, hi = _real(lo, f"{name}[0]"), _real(hi, f"{name}[1]")
    if lo < lower or hi <= lo:
        raise ValueError(f"{name} must satisfy {lower} <= min < max, got ({lo}, {hi})")
    return lo, hi


@dataclass(frozen=True)
class AirspeedSchedule:
    """Linear damper schedule ``c2 = a0 + a1 U`` (eq. 7.1) with its limits.

    Attributes
    ----------
    a0 : float
        [N s/m] intercept.
    a1 : float
        [N s^2/m^2] slope.
    airspeed_range : tuple of float
        [m/s] (min, max) airspeeds of the data the line was fitted to.
    damping_range : tuple of float
        [N s/m] (min, max) range of the damper; outputs are clamped to it.
    """

    a0: float
    a1: float
    airspeed_range: tuple[float, float]
    damping_range: tuple[float, float]

    def __post_init__(self):
        object.__setattr__(self, "a0", _real(self.a0, "a0"))
        object.__setattr__(self, "a1", _real(self.a1, "a1"))
        object.__setattr__(
            self, "airspeed_range", _range(self.airspeed_range, "airspeed_range", 0.0)
        )
        object.__setattr__(self, "damping_range", _range(self.damping_range, "damping_range", 0.0))

    def evaluate(self, airspeed, extrapolate: bool = True):
        """Commanded c2 at an airspeed.

        Parameters
        ----------
        airspeed : float or array_like
            [m/s] true airspeed U, finite and >= 0.
        extrapolate : bool
            If True (the study's use) the line continues outside ``airspeed_range``; if False
            the airspeed is first clamped to ``airspeed_range``.

        Returns
        -------
        float or ndarray
            [N s/m] c2, clamped to ``damping_range``; same shape as ``airspeed``.
        """
        u = np.asarray(airspeed, dtype=float)
        if not np.all(np.isfinite(u)) or np.any(u < 0.0):
            raise ValueError("airspeed must be finite and >= 0 m/s")
        if not extrapolate:
            u = np.clip(u, *self.airspeed_range)
        c2 = np.clip(self.a0 + self.a1 * u, *self.damping_range)
        return float(c2) if c2.ndim == 0 else c2

    def in_range(self, airspeed) -> bool:
        """Whether an airspeed [m/s] lies inside the fitted range."""
        lo, hi = self.airspeed_range
        return bool(lo <= float(airspeed) <= hi)


@dataclass(frozen=True)
class ScheduleFit:
    """Outcome of :func:`fit_airspeed_schedule`.

    Attributes
    ----------
    schedule : AirspeedSchedule
        The fitted schedule.
    n_points : int
        Points used (inside the airspeed range).
    rmse : float
        [N s/m] root mean square residual of the unclamped line on those points.
    max_abs_error : float
        [N s/m] largest absolute residual.
    r_squared : float
        Coefficient of determination (NaN if the optimal c2 is constant).
    """

    schedule: AirspeedSchedule
    n_points: int
    rmse: float
    max_abs_error: float
    r_squared: float


def fit_airspeed_schedule(
    airspeeds, optimal_damping, damping_range, airspeed_range=None
) -> ScheduleFit:
    """Least-squares fit of eq. 7.1 to optimal c2 values.

    Parameters
    ----------
    airspeeds : array_like, shape (n,)
        [m/s] airspeeds U, finite and >= 0.
    optimal_damping : array_like, shape (n,)
        [N s/m] optimal c2 at each airspeed, finite.
    damping_range : (float, float)
        [N s/m] the damper's (min, max).
    airspeed_range : (float, float), optional
        [m/s] use only points with ``min <= U <= max`` (the seed: 115 to 120 m/s); default all.

    Returns
    -------
    ScheduleFit

    Raises
    ------
    ValueError
        If fewer than two distinct airspeeds fall in the range, or inputs are not finite.
    """
    u = np.asarray(airspeeds, dtype=float)
    c = np.asarray(optimal_damping, dtype=float)
    if u.ndim != 1:
        raise ValueError(f"airspeeds must be 1-D, got shape {u.shape}")
    if c.shape != u.shape:
        raise ValueError(f"optimal_damping must have shape {u.shape}, got {c.shape}")
    if not np.all(np.isfinite(u)) or np.any(u < 0.0):
        raise ValueError("airspeeds must be finite and >= 0 m/s")
    if not np.all(np.isfinite(c)):
        raise ValueError("optimal_damping must be finite")
    damping_range = _range(damping_range, "damping_range", 0.0)
    if airspeed_range is None:
        if u.size == 0:
            raise ValueError("airspeeds is empty")
        airspeed_range = (float(u.min()), float(u.max()))
        if airspeed_range[1] <= airspeed_range[0]:
            raise ValueError("airspeeds must contain at least two distinct values")
    airspeed_range = _range(airspeed_range, "airspeed_range", 0.0)
    inside = (u >= airspeed_range[0]) & (u <= airspeed_range[1])
    u, c = u[inside], c[inside]
    if np.unique(u).size < 2:
        raise ValueError(
            f"need at least two distinct airspeeds in airspeed_range {airspeed_range}, "
            f"got {np.unique(u).size}"
        )
    design = np.column_stack([np.ones_like(u), u])
    (a0, a1), *_ = np.linalg.lstsq(design, c, rcond=None)
    residual = c - (a0 + a1 * u)
    ss_tot = float(np.sum((c - c.mean()) ** 2))
    r2 = 1.0 - float(residual @ residual) / ss_tot if ss_tot > 0 else float("nan")
    return ScheduleFit(
        schedule=AirspeedSchedule(float(a0), float(a1), airspeed_range, damping_range),
        n_points=int(u.size),
        rmse=float(np.sqrt(np.mean(residual**2))),
        max_abs_error=float(np.max(np.abs(residual))),
        r_squared=r2,
    )
