"""The sample loop of a few whole flights on one held schedule, compiled (numba).

:func:`~aero_dva.flight.batch_simulator.simulate_flights` takes this route for fewer than
:data:`~aero_dva.flight.batch_simulator.BATCH_COLUMNS` flights sharing one schedule: the hold
rule over the flight's hold periods (:func:`hold_rule`, the rule of
:func:`~aero_dva.flight.discrete_model.held_values`), the flight's new conditions discretised
by :func:`expm_stack` (the algorithm of :func:`~aero_dva.flight.discretize.expm_batch`, matrix
by matrix: numpy's batched product has a fixed cost per small matrix that exceeds its
arithmetic), then one pass over the samples (:func:`step_periods`):
``x <- phi[k] x + gamma[k] f`` with ``k`` the held condition of the sample's hold period.
A sample costs one 7 x 7 matrix-vector product and the output rows; in NumPy the same flight
needs a Python loop over samples or the period maps' larger products. Compiled once per
machine (``cache=True``). Pure numerics.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["expm_stack", "hold_rule", "step_periods"]


@njit(cache=True)
def hold_rule(raw, held, quantum, out):
    """Values in force per hold period: ``raw`` (P, k) the inputs at the periods' first samples,
    ``held`` (k,) the values in force before (NaN: none); writes ``out`` (P, k).

    A value is kept while the input stays within ``quantum`` of it (relative), else the input
    is taken; the comparison is written so that a NaN held value is always replaced.
    """
    for j in range(raw.shape[1]):
        cur = held[j]
        for p in range(raw.shape[0]):
            v = raw[p, j]
            if not abs(v - cur) <= quantum * abs(cur):
                cur = v
            out[p, j] = cur
    return out


@njit(cache=True)
def step_periods(phi, gam, cacc, dacc, disp, keys, hold, y, force, out):
    """Step whole hold periods of ``F`` flights from the states ``y`` (F, n).

    ``keys`` (B,) the cached condition of each period; ``phi`` (K, n, n), ``gam`` (K, n),
    ``cacc`` (K, a, n), ``dacc`` (K, a) its one-sample step and acceleration output;
    ``disp`` (d, n) the displacement outputs (the same in every condition; their zero entries
    are skipped); ``force`` (F, B * hold). Writes each sample's displacements, then its
    accelerations, into ``out`` (F, B * hold, d + a); returns the final states (F, n).
    """
    nf, n = y.shape
    na = cacc.shape[1]
    nd = disp.shape[0]
    # the displacement outputs' nonzero entries (a few per row: states picked and combined)
    nnz = 0
    for o in range(nd):
        for i in range(n):
            if disp[o, i] != 0.0:
                nnz += 1
    rows = np.empty(nnz, dtype=np.int64)
    cols = np.empty(nnz, dtype=np.int64)
    vals = np.empty(nnz)
    e = 0
    for o in range(nd):
        for i in range(n):
            if disp[o, i] != 0.0:
                rows[e], cols[e], vals[e] = o, i, disp[o, i]
                e += 1
    end = np.empty((nf, n))
    x = np.empty(n)
    xn = np.empty(n)
    for f in range(nf):
        for i in range(n):
            x[i] = y[f, i]
        t = 0
        for b in range(keys.size):
            k = keys[b]
            for _ in range(hold):
                u = force[f, t]
                for o in range(nd):
                    out[f, t, o] = 0.0
                for e in range(nnz):
                    out[f, t, rows[e]] += vals[e] * x[cols[e]]
                for o in range(na):
                    s = dacc[k, o] * u
                    for i in range(n):
                        s += cacc[k, o, i] * x[i]
                    out[f, t, nd + o] = s
                for r in range(n):
                    s = gam[k, r] * u
                    for i in range(n):
                        s += phi[k, r, i] * x[i]
                    xn[r] = s
                for i in range(n):
                    x[i] = xn[i]
                t += 1
        for i in range(n):
            end[f, i] = x[i]
    return end


@njit(cache=True)
def _product(a, b, out):
    """``out = a @ b`` for small square matrices (``out`` distinct from both)."""
    n = a.shape[0]
    for r in range(n):
        for c in range(n):
            out[r, c] = 0.0
        for j in range(n):
            arj = a[r, j]
            for c in range(n):
                out[r, c] += arj * b[j, c]


@njit(cache=True)
def expm_stack(m, taylor, out):
    """``out[i] = expm(m[i])`` for a stack (K, n, n): each matrix scaled to 1-norm <= 1, the
    degree-18 Taylor polynomial ``taylor`` (19 coefficients) by Paterson-Stockmeyer, then
    squared back, as :func:`~aero_dva.flight.discretize.expm_batch` does."""
    k, n = m.shape[0], m.shape[1]
    x = np.empty((n, n))
    x2 = np.empty((n, n))
    x3 = np.empty((n, n))
    x4 = np.empty((n, n))
    acc = np.empty((n, n))
    tmp = np.empty((n, n))
    for i in range(k):
        norm = 0.0
        for c in range(n):
            col = 0.0
            for r in range(n):
                col += abs(m[i, r, c])
            norm = max(norm, col)
        s = max(0, int(math.ceil(math.log2(max(norm, 1e-300)))))
        scale = 2.0 ** s
        for r in range(n):
            for c in range(n):
                x[r, c] = m[i, r, c] / scale
        _product(x, x, x2)
        _product(x2, x, x3)
        _product(x2, x2, x4)
        for r in range(n):
            for c in range(n):
                acc[r, c] = taylor[17] * x[r, c] + taylor[18] * x2[r, c]
            acc[r, r] += taylor[16]
        for jj in range(4):
            j = 3 - jj
            _product(acc, x4, tmp)
            for r in range(n):
                for c in range(n):
                    acc[r, c] = tmp[r, c] + (taylor[4 * j + 1] * x[r, c]
                                             + taylor[4 * j + 2] * x2[r, c]
                                             + taylor[4 * j + 3] * x3[r, c])
                acc[r, r] += taylor[4 * j]
        for _ in range(s):
            _product(acc, acc, tmp)
            for r in range(n):
                for c in range(n):
                    acc[r, c] = tmp[r, c]
        for r in range(n):
            for c in range(n):
                out[i, r, c] = acc[r, c]
    return out
