"""The leading-edge RMS that ranks controllers: over one stated airspeed range of a ramp flight.

Every flight of a comparison is measured over the same airspeeds, :data:`RMS_RANGE` (0.8 to
1.05 U_cr by default, below every controller's divergence, where the optimal c2 moves from 679
to 502 N s/m: docs/evaluation.md), leaving out the first :data:`SKIP` seconds (the spectrum
controller has no window yet). A flight that ends before the range's top has no such RMS
(NaN): it diverged inside the range, and an RMS over what it survived would reward a worse
controller with a shorter, quieter stretch. ``run_flight``'s summary and ``dva evaluate``
both call :func:`range_rms`, so they rank controllers alike. Pure numerics.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["RMS_RANGE", "SKIP", "range_mask", "range_mean", "range_rms"]

RMS_RANGE = (0.8, 1.05)  # [U/U_cr]
SKIP = 2.0  # [s] left out at the start


def range_mask(airspeed, sample_rate: float, airspeeds: tuple[float, float],
               skip: float = SKIP) -> np.ndarray:
    """The samples inside ``airspeeds`` (low, high) [m/s] after the first ``skip`` seconds
    (sample i at time i / sample_rate; a NaN airspeed, a sample missing from a log, is out)."""
    u = np.asarray(airspeed, dtype=float)
    low, high = airspeeds
    return (u >= low) & (u <= high) & (np.arange(u.size) >= skip * sample_rate)


def range_rms(airspeed, response, sample_rate: float, airspeeds: tuple[float, float],
              skip: float = SKIP) -> float:
    """RMS of ``response`` over the range (module docstring; samples without a response left
    out); NaN when the flight did not go past its top or has no sample in it."""
    u = np.asarray(airspeed, dtype=float)
    x = np.asarray(response, dtype=float)
    inside = range_mask(u, sample_rate, airspeeds, skip) & np.isfinite(x)
    complete = bool(np.any(u > airspeeds[1]))
    if not (complete and inside.any()):
        return math.nan
    return math.sqrt(_exact_mean(x[inside] ** 2))


def range_mean(airspeed, values, sample_rate: float, airspeeds: tuple[float, float],
               skip: float = SKIP) -> float:
    """Mean of ``values`` (the applied c2) over the range's samples the flight flew (NaN: none;
    non-finite values left out)."""
    inside = range_mask(airspeed, sample_rate, airspeeds, skip)
    x = np.asarray(values, dtype=float)[inside]
    x = x[np.isfinite(x)]
    return _exact_mean(x) if x.size else math.nan


def _exact_mean(x) -> float:
    # Correctly rounded: numpy's SIMD sums depend on where the array sits in memory, which
    # differs between processes, and the records must be the same on every route.
    return math.fsum(x) / len(x)
