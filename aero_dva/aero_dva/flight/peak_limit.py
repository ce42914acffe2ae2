"""The practical divergence boundary of a ramp flight: where the response first exceeds a
peak limit (pure numerics).

A switched damper can burst near its boundary (the amplitude grows 10-100x for a moment, then
decays); :func:`~aero_dva.flight.divergence.divergence_airspeed` ignores bursts that decay, so
it gives the *bounded* boundary. A structure has a peak it must not exceed; the *practical*
boundary is the airspeed of the first sample whose absolute response exceeds ``limit``.
"""
from __future__ import annotations

import numpy as np

from aero_dva.wing.checks import positive

__all__ = ["peak_limit_airspeed"]


def peak_limit_airspeed(airspeed, response, limit: float):
    """Airspeed [m/s] of the first sample with ``|response| > limit`` (NaN if none).

    ``airspeed`` (N,); ``response`` (N,) or (F, N), non-finite samples count as above.
    Returns a float or an (F,) array.
    """
    limit = positive(limit, "limit")
    x = np.asarray(response, dtype=float)
    single = x.ndim == 1
    x = np.atleast_2d(x)
    speed = np.broadcast_to(np.asarray(airspeed, dtype=float), x.shape)
    over = ~(np.abs(x) <= limit)
    first = np.argmax(over, axis=1)
    out = np.where(over.any(axis=1), speed[np.arange(x.shape[0]), first], np.nan)
    return float(out[0]) if single else out
