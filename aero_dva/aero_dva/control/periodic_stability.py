"""Stability of the wing under a periodically varying air density (Floquet analysis, eq. 7.2).

The study flies its controllers with rho(t) = rho0 (1 + mu sin(2 pi f t)) (eq. 7.2, f = 1 Hz)
and reads off where the response grows. For a fixed airspeed the linear wing is then a
periodic system ``x' = A(t) x``; its monodromy matrix ``M = Phi(T)`` over one period
``T = 1/f`` decides stability: the largest Floquet multiplier ``max |eig(M)|`` above 1 means
growth at the mean rate ``ln(max |eig M|) / T``. The frozen-density eigenvalues say something
else when the density changes fast against the mode's growth: at 1 Hz the wing responds to the
cycle-averaged dynamics (the boundary barely moves), while near twice a mode's frequency the
modulation pumps it (parametric resonance) and the boundary drops below every frozen one.

``M`` is the product of exact exponentials over ``n`` sub-intervals of length ``h = T/n``
with the density (and c2, which may follow the density: a controller that tracks it) held at
each sub-interval's midpoint value; ``n`` makes ``h`` at most ``max_step`` and at least 200
steps per period. (The simulator holds the density for 10 ms, its parameter hold: flights near
20 Hz see a coarser staircase of the same modulation.)

Pure numerics: :func:`floquet_growth` for many airspeeds at once, :func:`floquet_boundary` for
the lowest airspeed at which it crosses zero.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from aero_dva.flight.discretize import zoh
from aero_dva.wing.checks import positive, real_array

__all__ = ["MIN_STEPS", "floquet_boundary", "floquet_growth", "frozen_boundary"]

MIN_STEPS = 200  # sub-intervals per period at least
_MAX_STEP = 0.01  # [s] sub-interval at most (a 20 s period: 2000 steps)


def _damping_values(damping, airspeed: np.ndarray, density: np.ndarray) -> np.ndarray | None:
    if damping is None:
        return None
    if callable(damping):
        return np.asarray(damping(airspeed, density), dtype=float)
    return np.broadcast_to(np.asarray(damping, dtype=float), np.broadcast_shapes(
        np.shape(airspeed), np.shape(density)))


def floquet_growth(model, airspeed, base_density: float, variation: float, frequency: float,
                   damping=None, *, max_step: float = _MAX_STEP) -> np.ndarray:
    """Mean growth rate [1/s] over one density period at each airspeed.

    Parameters
    ----------
    model : AeroelasticModel
    airspeed : array_like, shape (n_u,)
        [m/s]
    base_density : float
        rho0 [kg/m^3].
    variation : float
        mu of eq. 7.2, in [0, 1).
    frequency : float
        f [Hz] of the density variation.
    damping : float, callable or None
        The damper c2 [N s/m]: a constant, ``damping(airspeed, density) -> c2`` evaluated at
        every sub-interval (broadcast arrays), or None for the absorber's own.
    max_step : float
        [s] longest sub-interval.

    Returns
    -------
    ndarray, shape (n_u,)
        ``ln(max |Floquet multiplier|) / T``: negative where every solution decays.
    """
    u = np.atleast_1d(real_array(airspeed, "airspeed")).astype(float)
    rho0 = positive(base_density, "base_density")
    if not (math.isfinite(variation) and 0 <= variation < 1):
        raise ValueError(f"variation must be in [0, 1), got {variation}")
    period = 1.0 / positive(frequency, "frequency")
    n = max(MIN_STEPS, int(math.ceil(period / positive(max_step, "max_step"))))
    h = period / n
    rho = rho0 * (1.0 + variation * np.sin(2.0 * np.pi * (np.arange(n) + 0.5) * h / period))
    uu, rr = np.meshgrid(u, rho, indexing="ij")  # (n_u, n)
    c2 = _damping_values(damping, uu, rr)
    a, b = model.matrices(uu, rr, c2)
    phi, _ = zoh(a, b, h)  # (n_u, n, k, k)
    m = phi[:, 0]
    log_scale = np.zeros(u.size)  # M = exp(log_scale) m: a fast-growing M would overflow
    for j in range(1, n):
        m = phi[:, j] @ m
        if j % 16 == 0 or j == n - 1:
            norm = np.max(np.abs(m), axis=(-2, -1))
            m = m / norm[:, None, None]
            log_scale += np.log(norm)
    radius = np.max(np.abs(np.linalg.eigvals(m)), axis=-1)
    with np.errstate(divide="ignore"):
        return (log_scale + np.log(radius)) / period


def _first_crossing(growth: Callable[[np.ndarray], np.ndarray], low: float, high: float,
                    n_grid: int, xtol: float) -> float:
    grid = np.linspace(low, high, n_grid)
    g = growth(grid)
    if g[0] >= 0:
        raise ValueError(f"the wing is already unstable at {low:g} m/s")
    above = np.flatnonzero(g >= 0)
    if above.size == 0:
        return math.nan
    k = int(above[0])
    return float(brentq(lambda x: float(growth(np.array([x]))[0]), grid[k - 1], grid[k],
                        xtol=xtol))


def floquet_boundary(model, base_density: float, variation: float, frequency: float,
                     damping=None, airspeed_range: tuple[float, float] = (50.0, 200.0), *,
                     n_grid: int = 61, xtol: float = 1e-3, max_step: float = _MAX_STEP
                     ) -> float:
    """Lowest airspeed [m/s] in ``airspeed_range`` at which :func:`floquet_growth` reaches 0.

    NaN if it stays negative over the range; ValueError if it is not negative at the low end.
    ``xtol`` [m/s] is the bisection tolerance.
    """
    low, high = (float(v) for v in airspeed_range)
    if not 0 < low < high:
        raise ValueError(f"airspeed_range must be 0 < low < high, got {airspeed_range}")
    return _first_crossing(
        lambda u: floquet_growth(model, u, base_density, variation, frequency, damping,
                                 max_step=max_step), low, high, n_grid, xtol)


def frozen_boundary(model, density: float, damping=None,
                    airspeed_range: tuple[float, float] = (50.0, 200.0), *, n_grid: int = 61,
                    xtol: float = 1e-3) -> float:
    """Lowest airspeed [m/s] at which the frozen-density wing's largest eigenvalue real part
    reaches 0, with c2 ``damping`` (constant, ``damping(airspeed, density)`` or None).

    With a constant c2 this is :func:`aero_dva.wing.flutter.flutter_speed`; with a c2 that
    depends on the airspeed (a schedule, c2*(U, rho)) it is the boundary of that control law.
    """
    rho = positive(density, "density")
    low, high = (float(v) for v in airspeed_range)

    def growth(u):
        u = np.atleast_1d(u).astype(float)
        r = np.full(u.shape, rho)
        a, _ = model.matrices(u, r, _damping_values(damping, u, r))
        return np.max(np.linalg.eigvals(a).real, axis=-1)

    return _first_crossing(growth, low, high, n_grid, xtol)
