"""The wing simulated along a logged flight whose c2 changes every sample: the discrepancy
loop's simulator of a per-sample law's flight (a linear time-varying system).

A per-sample law sets c2 every sample, so no two neighbouring samples need share a model. c2
enters the model only through the Maxwell relaxation rate r = k2 / c2, one entry of the state
matrix (the deflection's own rate): ``A(r) = A_0 - r e_d e_d^T``, with ``A_0`` the model at
c2 = inf. Each sample ``i`` is the exact zero-order-hold step of the model at its block's
condition ``k`` and its own rate ``r_i``::

    x[i+1] = Ad(k, r_i) x[i] + Bd(k, r_i) u[i],   y[i] = C_k x[i] + D_k u[i]

(``u`` the inputs, e.g. the aileron force; the accelerations do not depend on c2). Every entry
of a step is an entire function of r and of the airspeed (the model is affine in r and
polynomial in U), so, as for the switched flight's tables
(:mod:`aero_dva.flight.per_sample.smooth_tables`), the steps are interpolated: in r from
:data:`RATE_NODES` Chebyshev nodes over the flight's range of r, and, within a family of
conditions that differ only in airspeed, in U from :data:`SPEED_NODES` nodes (a ramp's hundreds
of block airspeeds cost 8 x 8 matrix exponentials). A test holds the result to a plain
sample-by-sample ``expm`` loop. The loop over samples is compiled
(:mod:`aero_dva.flight.varying_kernel`). Pure numerics.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from aero_dva.flight.discretize import zoh
from aero_dva.flight.per_sample.smooth_tables import chebyshev_nodes, lagrange_weights

__all__ = ["RATE_NODES", "SPEED_NODES", "VaryingSteps", "simulate_varying", "transitions"]

RATE_NODES = 8
"""Chebyshev nodes in r = k2 / c2 (error ~ (half range x dt)^n / n!: about 1e-12 relative for
c2 of 100-2500 N s/m with k2 = 70 kN/m at 1 kHz, a test holds it below 1e-10)."""
SPEED_NODES = 8
"""Chebyshev nodes in airspeed within a family of conditions (the model is quadratic in U)."""


class VaryingSteps:
    """The steps of K conditions at the rate nodes, and each sample's weights over them.

    Parameters
    ----------
    build : callable
        ``build(rows)`` for condition rows (J, c) (column 0 the airspeed, the others the
        rest of a condition, e.g. density) returns ``a0`` (J, n, n) the state matrix at
        c2 = inf, ``b`` (J, n, m) the input columns, ``c`` (J, p, n) and ``d`` (J, p, m) the
        outputs (which must not depend on c2).
    conditions : (K, c) array
        The distinct conditions of the flight's blocks.
    rate_range : (float, float)
        [1/s] the least and largest r = k2 / c2 the samples will have.
    dt : float
        [s] sample interval.
    deflection : int
        State index of the Maxwell deflection (whose own rate is -r).
    expm : callable, optional
        Matrix exponential of a stack (as for :func:`~aero_dva.flight.discretize.zoh`).
    """

    def __init__(self, build: Callable, conditions, rate_range, dt: float, deflection: int,
                 expm=None):
        conditions = np.atleast_2d(np.asarray(conditions, dtype=float))
        lo, hi = (float(v) for v in rate_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi):
            raise ValueError(f"rate_range must be finite with 0 <= lo <= hi, got {rate_range}")
        self.rate_nodes = (np.array([lo]) if hi - lo <= 1e-12 * max(hi, 1.0)
                           else chebyshev_nodes(lo, hi, RATE_NODES))
        # barycentric weights of the nodes (a sample's rate weights: the kernel's)
        diff = self.rate_nodes[:, None] - self.rate_nodes[None, :]
        np.fill_diagonal(diff, 1.0)
        self.bary = 1.0 / diff.prod(axis=1)
        at, weight = _speed_nodes(conditions)
        a0, b, c, d = build(at)
        if b.ndim == 2:
            b = b[..., None]
            d = d[..., None]
        j, n = a0.shape[0], a0.shape[-1]
        nr = self.rate_nodes.size
        a = np.repeat(a0[:, None], nr, axis=1)
        a[:, :, deflection, deflection] -= self.rate_nodes
        ad, bd = zoh(a.reshape(j * nr, n, n), np.repeat(b, nr, axis=0), dt, expm)
        steps = np.concatenate([ad, bd], axis=-1).reshape(j, nr, n, n + b.shape[-1])
        # each condition's steps (K, R, n, n + m) and outputs from its nodes' (exact at nodes)
        self.steps = np.ascontiguousarray(np.einsum("kj,jrab->krab", weight, steps))
        self.c = np.ascontiguousarray(np.einsum("kj,jab->kab", weight, c))
        self.d = np.ascontiguousarray(np.einsum("kj,jab->kab", weight, d))
        self.n_inputs = b.shape[-1]
        self.range = (lo, hi)

    def checked_rates(self, rates) -> np.ndarray:
        """``rates`` as a contiguous float array; ValueError if one leaves the range."""
        rates = np.ascontiguousarray(rates, dtype=float)
        lo, hi = self.range
        slack = 1e-9 * max(hi, 1.0)
        if rates.size and not (rates.min() >= lo - slack and rates.max() <= hi + slack):
            raise ValueError(f"rates {rates.min():g}..{rates.max():g} leave the range "
                             f"{lo:g}..{hi:g} 1/s the steps were built for")
        return rates


def _speed_nodes(conditions: np.ndarray):
    """The rows to build (airspeed nodes per family of conditions that differ only in
    airspeed, or the conditions themselves) and each condition's weights over them."""
    k = conditions.shape[0]
    rest = conditions[:, 1:]
    families = np.unique(rest, axis=0, return_inverse=True)[1].reshape(-1)
    rows = []
    start = 0
    weight_parts = []
    for fam in np.unique(families):
        members = np.flatnonzero(families == fam)
        speeds = conditions[members, 0]
        if np.unique(speeds).size > SPEED_NODES:
            nodes = chebyshev_nodes(speeds.min(), speeds.max(), SPEED_NODES)
            at = np.column_stack([nodes, np.repeat(rest[members[:1]], nodes.size, axis=0)])
            w = lagrange_weights(nodes, speeds)
        else:
            at = conditions[members]
            w = np.eye(members.size)
        rows.append(at)
        weight_parts.append((members, start, w))
        start += at.shape[0]
    weight = np.zeros((k, start))
    for members, first, w in weight_parts:
        weight[members, first:first + w.shape[1]] = w
    return np.concatenate(rows), weight


def simulate_varying(steps: VaryingSteps, condition, rates, inputs) -> np.ndarray:
    """Outputs (p, N) from rest: sample ``i`` at condition ``condition[i]`` (indices into
    the K conditions of ``steps``) and rate ``rates[i]`` [1/s], driven by ``inputs`` (N,) or
    (N, m).

    One compiled pass over the samples (:func:`aero_dva.flight.varying_kernel.run_varying`).
    """
    from aero_dva.flight.varying_kernel import run_varying

    inputs = np.asarray(inputs, dtype=float)
    if inputs.ndim == 1:
        inputs = inputs[:, None]
    condition = np.ascontiguousarray(condition, dtype=np.int64)
    n = inputs.shape[0]
    if condition.shape != (n,) or inputs.shape[1] != steps.n_inputs:
        raise ValueError(f"condition must be ({n},) and inputs ({n}, {steps.n_inputs}), got "
                         f"{condition.shape} and {inputs.shape}")
    if n and not (condition.min() >= 0 and condition.max() < steps.steps.shape[0]):
        raise ValueError("condition indices must lie in 0..K-1")
    rates = steps.checked_rates(rates)
    if rates.shape != (n,):
        raise ValueError(f"rates must be ({n},), got {rates.shape}")
    out = np.empty((steps.c.shape[1], n))
    return run_varying(steps.steps, steps.rate_nodes, steps.bary, rates, condition,
                       np.ascontiguousarray(inputs), steps.c, steps.d, out)


def transitions(steps: VaryingSteps, condition, rates, starts, length: int) -> np.ndarray:
    """(W, n, n) the state transition over ``length`` samples from each sample of
    ``starts`` (how the flight's own dynamics carry a state, or a model error, along)."""
    from aero_dva.flight.varying_kernel import run_transitions

    condition = np.ascontiguousarray(condition, dtype=np.int64)
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if starts.size and not (starts.min() >= 0 and starts.max() + length <= condition.size):
        raise ValueError("every transition must lie within the samples")
    rates = steps.checked_rates(rates)
    n = steps.steps.shape[2]
    return run_transitions(steps.steps, steps.rate_nodes, steps.bary, rates, condition, starts,
                           int(length), np.empty((starts.size, n, n)))
