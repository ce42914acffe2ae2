"""Bracketing the first instability by marching on the modes' tangents.

The growth rate ``g(U)`` (largest real part of the non-neutral eigenvalues of ``A(U) = A0 + U A1
+ U^2 A2``) is sampled from the low end of the range upward, one LAPACK ``dgeev`` call per
sample. Its left and right eigenvectors give the slope of every mode, ``dlambda/dU = w^H A'(U)
v / (w^H v)``, so each sample carries the tangent of every mode's real part:

- a step ends where the first rising mode's tangent reaches zero (a little beyond, so that a
  mode that keeps rising is bracketed by the next sample), and never exceeds the largest step;
- a mode that is concave over a step lies below its tangents at both ends, so when the step
  ends stable, the two ends' tangents rule out a crossing inside it unless they overlap above
  zero; such a step is split at the tangents' highest meeting point, and the parts are
  checked again (down to a floor);
- a maximum of the growth rate inside a stable step (its slope positive at the left end,
  negative at the right) is located by Brent's method on the slope, for a hump that is not
  concave over the step (the fixed grid's refinement of local maxima, here found from the
  slopes instead of three samples).

This replaces a fixed grid with samples placed where the modes can reach zero. The first bracket
``(a, b)`` with ``g(a) < 0 < g(b)`` is returned with both samples; the root is then found by
the safeguarded Newton iteration of :mod:`aero_dva.wing.flutter`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dgeev
from scipy.optimize import brentq

__all__ = ["ModeSample", "TangentGrowth", "march_to_instability"]

NEUTRAL = 1e-7
"""[rad/s] Eigenvalues smaller than this are neutral integrators, not instabilities (the same
threshold as :data:`aero_dva.wing.flutter.NEUTRAL`)."""

RISING = 1e-6
"""[1/s per m/s] A real eigenvalue within NEUTRAL of zero that rises faster than this is a mode
diverging through zero, not a neutral integrator: it stays in the growth rate, which so stays
continuous at a divergence point."""

OVERSHOOT = 1.25
"""A step aimed at a mode's predicted zero crossing ends this far beyond it (as a fraction of
the step), so that a mode rising faster than its tangent is still bracketed."""

MIN_STEP_FRACTION = 1.0 / 16.0
"""The shortest step, as a fraction of the largest: a mode just below zero and rising slowly
does not shrink the steps without bound."""

MAX_SPLITS = 48
"""Samples spent at most on splitting steps whose ends' tangents overlap above zero."""


@dataclass(slots=True)
class ModeSample:
    """The modes at one airspeed.

    Attributes
    ----------
    airspeed : float
    growth : float
        Largest real part [1/s] of the non-neutral eigenvalues (``-inf`` if none).
    eigenvalue : complex
        The critical eigenvalue (the one with ``growth`` as real part; upper half plane).
    derivative : complex
        ``dlambda/dU`` of the critical eigenvalue (NaN if it could not be formed).
    real : list of float
        Real parts of the non-neutral modes (one entry per complex pair).
    slope : list of float
        ``d Re(lambda) / dU`` of those modes (NaN where it could not be formed).
    tangents : bool
        Every slope was formed.
    """

    airspeed: float
    growth: float
    eigenvalue: complex
    derivative: complex
    real: list
    slope: list
    tangents: bool = True


class TangentGrowth:
    """The modes of ``A(U) = a0 + U a1 + U^2 a2`` with the slopes of their real parts.

    A sample is one ``dgeev`` call and two 7 x 7 products; the rest works on a handful of
    numbers in plain Python, which is cheaper than numpy calls on arrays this small.
    """

    def __init__(self, a0: np.ndarray, a1: np.ndarray, a2: np.ndarray):
        self.n = n = a0.shape[0]
        # Rows A0, A1, A2 and the identity: one product gives A(U), A'(U) and I.
        self._coefficients = np.concatenate((a0, a1, a2, np.eye(n))).reshape(4, n * n)

    def sample(self, u: float) -> ModeSample:
        n = self.n
        rows = np.array(((1.0, u, u * u, 0.0), (0.0, 1.0, 2.0 * u, 0.0), (0.0, 0.0, 0.0, 1.0)))
        mats = rows @ self._coefficients
        wr, wi, vl, vr, info = dgeev(mats[0].reshape(n, n))
        wr, wi = wr.tolist(), wi.tolist()
        if info == 0:
            # p = vl' A'(U) vr and q = vl' vr, as (2, n, n).
            p, q = (vl.T @ (mats[1:].reshape(2 * n, n) @ vr).reshape(2, n, n)).tolist()
        real, slope, crit, tangents = [], [], None, info == 0
        for j, (x, y) in enumerate(zip(wr, wi)):
            # One entry per mode: real eigenvalues and the upper member of each complex pair
            # (dgeev stores a pair consecutively, the positive imaginary part first).
            neutral = x * x + y * y < NEUTRAL * NEUTRAL
            if y < 0.0 or (neutral and (y > 0.0 or info != 0)):
                continue
            if info != 0:
                d = complex(np.nan)
            elif y > 0.0:
                # A pair's vectors are columns (real part, imaginary part) j, k = j + 1; with
                # v = vr_j + i vr_k, w = vl_j + i vl_k:
                # w^H M v = (vl_j' M vr_j + vl_k' M vr_k) + i (vl_j' M vr_k - vl_k' M vr_j).
                k = j + 1
                num = complex(p[j][j] + p[k][k], p[j][k] - p[k][j])
                den = complex(q[j][j] + q[k][k], q[j][k] - q[k][j])
                d = num / den if den != 0 else complex(np.nan)  # 0: a defective pair
            elif q[j][j] == 0:
                d = complex(np.nan)
            else:
                d = complex(p[j][j] / q[j][j])
            if neutral and not d.real > RISING:
                continue  # an integrator; a real mode rising through zero (divergence) stays
            if d != d:
                tangents = False
            if crit is None or x > real[crit]:
                crit, lam, dlam = len(real), complex(x, y), d
            real.append(x)
            slope.append(d.real)
        if crit is None:
            return ModeSample(u, -np.inf, 0j, complex(np.nan), [], [], False)
        return ModeSample(u, real[crit], lam, dlam, real, slope, tangents)

    def at(self, u: float):
        """Growth rate, critical eigenvalue and its derivative (the Newton iteration's step)."""
        s = self.sample(u)
        return s.growth, s.eigenvalue, s.derivative


class _Unstable(Exception):
    """Raised inside a root search by the first unstable sample, which it carries."""

    def __init__(self, sample: ModeSample):
        super().__init__()
        self.sample = sample


def _tangent_limit(s: ModeSample) -> float:
    """Distance [m/s] to the first zero crossing of a rising mode's tangent (inf if none); 0 if
    a slope is unknown."""
    if not s.tangents:
        return 0.0
    limit = np.inf
    for x, d in zip(s.real, s.slope):
        if d > 0.0 and -x / d < limit:
            limit = -x / d
    return limit


def _overlap_peak(s: ModeSample, t: ModeSample):
    """Highest point of ``min(F, B)`` over ``[s.airspeed, t.airspeed]``, ``F`` and ``B`` the upper
    envelopes of the modes' tangents at the two ends: ``(airspeed, value)``.

    ``F`` and ``B`` are convex, so each is highest at an end of the step, and the minimum is
    highest at an end or where a tangent of one end meets a tangent of the other; every mode
    concave over the step lies below it.
    """
    u, v = s.airspeed, t.airspeed
    if not (s.tangents and t.tangents):
        return 0.5 * (u + v), np.inf  # no tangents: split the step
    h = v - u
    if (max([x + h * d for x, d in zip(s.real, s.slope)]) <= 0.0
            or max([x - h * d for x, d in zip(t.real, t.slope)]) <= 0.0):
        return u, -np.inf  # one envelope stays below zero (the cheap, common case)
    left = list(zip(s.real, s.slope))
    right = list(zip(t.real, t.slope))
    best = (u, -np.inf)
    for xl, dl in left:
        for xr, dr in right:
            if dr == dl:
                continue
            m = v + (xr - (xl + (v - u) * dl)) / (dl - dr)  # where the two tangents meet
            if u < m < v:
                f = max(x + (m - u) * d for x, d in left)
                b = max(x + (m - v) * d for x, d in right)
                if min(f, b) > best[1]:
                    best = (m, min(f, b))
    return best


def march_to_instability(growth: TangentGrowth, low: float, high: float, max_step, first: bool,
                         split_floor: float):
    """The first bracket of a zero crossing of the growth rate in ``[low, high]``.

    Parameters
    ----------
    growth : TangentGrowth
    low, high : float
        [m/s] The searched range.
    max_step : callable
        ``max_step(U)`` [m/s], the largest step from airspeed ``U``.
    first : bool
        The range starts the search: an instability at ``low`` is an error.
    split_floor : float
        [m/s] Steps shorter than this are not split further.

    Returns
    -------
    (ModeSample, ModeSample) or None
        The samples at the ends of the bracket (``g(a) < 0 < g(b)``); ``None`` if the range
        holds no crossing.

    Raises
    ------
    ValueError
        The model is unstable at ``low`` (``first``), or goes unstable right above it.
    """
    s = growth.sample(low)
    # Zero structural damping leaves the wind-off modes exactly neutral: allow round-off.
    scale = [max(abs(s.eigenvalue), 1.0)]
    if first and s.growth > 1e-9 * scale[0]:
        raise ValueError(
            f"the model is already unstable at the low end of airspeed_range ({low:g} m/s)"
        )
    splits = [0]

    def unstable(b: ModeSample) -> bool:
        scale[0] = max(scale[0], abs(b.eigenvalue))
        return b.growth > 1e-9 * scale[0]

    def bracket(a: ModeSample, b: ModeSample):
        """``(a, b)`` with ``b`` unstable, moved off a neutral ``a`` (growth 0 to round-off:
        undamped wind-off modes) by bisection."""
        while a.growth >= 0:
            if b.airspeed - a.airspeed <= shortest:
                raise ValueError("the model goes unstable right above the low end of "
                                 "airspeed_range; start the range higher")
            m = growth.sample(0.5 * (a.airspeed + b.airspeed))
            if unstable(m):
                b = m
            else:
                a = m
        return a, b

    def hidden(a: ModeSample, b: ModeSample):
        """A bracket inside the stable step ``(a, b)``, by splitting where the tangents say a
        mode might cross zero; None if none is found."""
        x, peak = _overlap_peak(a, b)
        if peak <= 0.0 or splits[0] >= MAX_SPLITS or b.airspeed - a.airspeed <= split_floor:
            return None
        x = min(max(x, a.airspeed + 0.05 * (b.airspeed - a.airspeed)),
                b.airspeed - 0.05 * (b.airspeed - a.airspeed))
        splits[0] += 1
        m = growth.sample(x)
        if unstable(m):
            return bracket(a, m)
        return hidden(a, m) or hidden(m, b)

    def summit(a: ModeSample, b: ModeSample):
        """A bracket at a maximum of the growth rate inside the stable step ``(a, b)`` (its
        slope positive at ``a``, negative at ``b``): a hump the tangents cannot see (not
        concave over the step) may still reach above zero there. The slope's root is found
        by Brent's method; the first unstable sample ends the search. None if none."""
        if not a.derivative.real > 0.0 > b.derivative.real:
            return None

        def slope(x):
            m = growth.sample(x)
            if unstable(m):
                raise _Unstable(m)
            return m.derivative.real if np.isfinite(m.derivative.real) else 0.0

        try:
            brentq(slope, a.airspeed, b.airspeed, xtol=split_floor, maxiter=MAX_SPLITS)
        except _Unstable as found:
            return bracket(a, found.sample)
        except RuntimeError:  # not converged in MAX_SPLITS samples: as the grid search, give up
            pass
        return None

    shortest = MIN_STEP_FRACTION * max_step(low)
    while s.airspeed < high:
        u = s.airspeed
        longest = max_step(u)
        h = min(longest, OVERSHOOT * _tangent_limit(s))
        h = min(max(h, MIN_STEP_FRACTION * longest), high - u)
        t = growth.sample(u + h if u + h < high else high)
        if unstable(t):
            return bracket(s, t)
        inside = hidden(s, t) or summit(s, t)
        if inside is not None:
            return inside
        s = t
    return None
