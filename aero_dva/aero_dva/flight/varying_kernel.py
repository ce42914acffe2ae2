"""The sample loop of :mod:`aero_dva.flight.varying_simulator`, compiled (numba).

Per sample ``i`` of condition ``k``: ``y[:, i] = C_k x + D_k u_i``, then
``x <- sum_r w[i, r] [Ad | Bd](k, r) [x; u_i]`` over the rate nodes ``r`` (the step at the
sample's c2, interpolated). A sample costs R n (n + m) multiply-adds. Pure numerics.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["run_varying"]


@njit(cache=True)
def _rate_weights(nodes, bary, r, w):
    """``w`` the barycentric Lagrange weights of rate ``r`` over ``nodes`` (exact at a node)."""
    total = 0.0
    for j in range(nodes.size):
        d = r - nodes[j]
        if d == 0.0:
            for q in range(nodes.size):
                w[q] = 0.0
            w[j] = 1.0
            return
        w[j] = bary[j] / d
        total += w[j]
    for j in range(nodes.size):
        w[j] /= total


@njit(cache=True)
def run_varying(steps, nodes, bary, rates, condition, inputs, c, d, out):
    """Fill ``out`` (p, N) with the outputs from rest (shapes: :class:`VaryingSteps`)."""
    nr, n, width = steps.shape[1], steps.shape[2], steps.shape[3]
    m = width - n
    p = c.shape[1]
    x = np.zeros(n)
    xn = np.empty(n)
    v = np.empty(width)
    w = np.ones(nr)
    for i in range(condition.size):
        k = condition[i]
        if nr > 1:
            _rate_weights(nodes, bary, rates[i], w)
        for j in range(n):
            v[j] = x[j]
        for j in range(m):
            v[n + j] = inputs[i, j]
        for q in range(p):
            s = 0.0
            for j in range(n):
                s += c[k, q, j] * x[j]
            for j in range(m):
                s += d[k, q, j] * inputs[i, j]
            out[q, i] = s
        for r in range(n):
            xn[r] = 0.0
        for node in range(nr):
            wt = w[node]
            if wt == 0.0:
                continue
            for r in range(n):
                s = 0.0
                for j in range(width):
                    s += steps[k, node, r, j] * v[j]
                xn[r] += wt * s
        for r in range(n):
            x[r] = xn[r]
    return out


@njit(cache=True)
def run_transitions(steps, nodes, bary, rates, condition, starts, length, out):
    """Fill ``out`` (W, n, n) with the state transition over ``length`` samples from each
    of ``starts`` (W,): the product of the samples' interpolated ``Ad``, latest on the left."""
    nr, n = steps.shape[1], steps.shape[2]
    phi = np.empty((n, n))
    tmp = np.empty((n, n))
    ad = np.empty((n, n))
    weights = np.ones(nr)
    for w in range(starts.size):
        for r in range(n):
            for j in range(n):
                phi[r, j] = 1.0 if r == j else 0.0
        for i in range(starts[w], starts[w] + length):
            k = condition[i]
            if nr > 1:
                _rate_weights(nodes, bary, rates[i], weights)
            for r in range(n):
                for j in range(n):
                    ad[r, j] = 0.0
            for node in range(nr):
                wt = weights[node]
                if wt == 0.0:
                    continue
                for r in range(n):
                    for j in range(n):
                        ad[r, j] += wt * steps[k, node, r, j]
            for r in range(n):
                for j in range(n):
                    s = 0.0
                    for q in range(n):
                        s += ad[r, q] * phi[q, j]
                    tmp[r, j] = s
            for r in range(n):
                for j in range(n):
                    phi[r, j] = tmp[r, j]
        for r in range(n):
            for j in range(n):
                out[w, r, j] = phi[r, j]
    return out
