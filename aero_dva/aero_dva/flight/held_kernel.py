"""The sample loop of whole flights on one held schedule, compiled (numba).

:func:`~aero_dva.flight.batch_simulator.simulate_flights` takes this route for flights sharing
one schedule: the hold rule over the flight's hold periods (:func:`hold_rule`, the rule of
:func:`~aero_dva.flight.discrete_model.held_values`), the flight's new conditions discretised
by :func:`expm_stack` (the algorithm of :func:`~aero_dva.flight.discretize.expm_batch`, matrix
by matrix: numpy's batched product has a fixed cost per small matrix that exceeds its
arithmetic), then one pass over the samples, flight after flight:
``x <- phi[k] x + gamma[k] f`` with ``k`` the held condition of the sample's hold period.
In NumPy the same flight needs a Python loop over samples or the period maps' larger products.

Models of at most :data:`STACK_STATES` states (every wing without the finite-state Wagner lag)
take :func:`step_stacked`: a sample is one product of a fixed (16, 8) matrix, the outputs and
the next state stacked over ``[x; f]`` (:func:`stack_maps`), with the state in scalars, so the
compiler unrolls it and uses vector instructions. Larger models take :func:`step_periods`, the
same recurrence with loops of the model's size. Compiled once per machine (``cache=True``).
Pure numerics.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from aero_dva.flight.discretize import TAYLOR

__all__ = ["STACK_ROWS", "STACK_STATES", "compiled_expm", "expm_stack", "hold_rule", "stack_maps",
           "step_periods", "step_stacked"]

STACK_STATES = 7
"""States of the largest model :func:`step_stacked` takes (smaller ones are padded)."""
STACK_ROWS = 16
"""Rows of a stacked map: the outputs, then the next state, then zero padding."""


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


def stack_maps(phi, gam, cacc, dacc, disp):
    """The stacked maps (K, 8, 16) of :func:`step_stacked`, transposed: column ``i`` of
    ``[[disp, 0], [cacc, dacc], [phi, gam]]`` (outputs, then next state; zero-padded) times
    ``[x; f]`` is row ``i``; ``phi`` (K, n, n), ``gam`` (K, n), ``cacc`` (K, a, n), ``dacc``
    (K, a), ``disp`` (d, n) with ``n <= STACK_STATES`` and ``d + a + STACK_STATES <= 16``."""
    k, n = gam.shape
    nd, na = disp.shape[0], dacc.shape[1]
    no = nd + na
    if n > STACK_STATES or no + STACK_STATES > STACK_ROWS:
        raise ValueError(f"{n} states and {no} outputs do not fit a stacked map")
    m = np.zeros((k, STACK_STATES + 1, STACK_ROWS))
    m[:, :n, :nd] = disp.T
    m[:, :n, nd:no] = cacc.transpose(0, 2, 1)
    m[:, STACK_STATES, nd:no] = dacc
    m[:, :n, no:no + n] = phi.transpose(0, 2, 1)
    m[:, STACK_STATES, no:no + n] = gam
    return m


@njit(cache=True, fastmath={"contract"})
def step_stacked(m, keys, hold, y, force, out):
    """:func:`step_periods` with the stacked maps ``m`` (K, 8, 16) of :func:`stack_maps`:
    ``y`` (F, 7) the start states (padded with zeros), ``force`` (F, B * hold); writes the
    ``p`` outputs of each sample into ``out`` (F, B * hold, p); returns the final states
    (F, 7).

    The sums are taken as a tree (a shorter chain from one sample's state to the next), and
    a product and a sum may be fused (``contract``; no other reordering): the result differs
    from :func:`step_periods` by rounding only."""
    nf, no = y.shape[0], out.shape[2]
    end = np.empty((nf, STACK_STATES))
    z = np.empty(STACK_ROWS)
    for f in range(nf):
        x0, x1, x2, x3 = y[f, 0], y[f, 1], y[f, 2], y[f, 3]
        x4, x5, x6 = y[f, 4], y[f, 5], y[f, 6]
        t = 0
        for b in range(keys.size):
            mk = m[keys[b]]
            for _ in range(hold):
                u = force[f, t]
                for r in range(STACK_ROWS):  # fixed trip counts: unrolled, vectorised
                    z[r] = (((mk[0, r] * x0 + mk[1, r] * x1) + (mk[2, r] * x2 + mk[3, r] * x3))
                            + ((mk[4, r] * x4 + mk[5, r] * x5) + (mk[6, r] * x6 + mk[7, r] * u)))
                for o in range(no):
                    out[f, t, o] = z[o]
                x0, x1, x2, x3 = z[no], z[no + 1], z[no + 2], z[no + 3]
                x4, x5, x6 = z[no + 4], z[no + 5], z[no + 6]
                t += 1
        end[f, 0], end[f, 1], end[f, 2], end[f, 3] = x0, x1, x2, x3
        end[f, 4], end[f, 5], end[f, 6] = x4, x5, x6
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


@njit(cache=True, fastmath={"contract"})
def _product8(a, b, out):
    """:func:`_product` for 8 x 8 matrices: a row of ``a`` in scalars and the sums as a tree,
    so the compiler vectorises over the columns (about twice as fast; rounding differs)."""
    for r in range(8):
        a0, a1, a2, a3 = a[r, 0], a[r, 1], a[r, 2], a[r, 3]
        a4, a5, a6, a7 = a[r, 4], a[r, 5], a[r, 6], a[r, 7]
        for c in range(8):
            out[r, c] = (((a0 * b[0, c] + a1 * b[1, c]) + (a2 * b[2, c] + a3 * b[3, c]))
                         + ((a4 * b[4, c] + a5 * b[5, c]) + (a6 * b[6, c] + a7 * b[7, c])))


@njit(cache=True)
def _multiply(a, b, out):
    if a.shape[0] == 8:
        _product8(a, b, out)
    else:
        _product(a, b, out)


@njit(cache=True)
def _balance(x, d):
    """Balance ``x`` in place by a diagonal similarity of powers of two (the Parlett-Reinsch
    iteration of LAPACK's dgebal, without permutations): ``x <- D^-1 x D``, ``d`` the diagonal.
    Each row and column of the result have about equal off-diagonal 1-norms; the scaling is
    exact in binary, so ``expm(x0) = D expm(x) D^-1`` loses nothing to it."""
    n = x.shape[0]
    for i in range(n):
        d[i] = 1.0
    for _ in range(32):  # converges in a few sweeps; bounded for safety
        done = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(x[j, i])
                    r += abs(x[i, j])
            if c == 0.0 or r == 0.0:
                continue
            s = c + r
            f = 1.0
            g = r / 2.0
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c > g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * s and 2.0 ** -60 <= d[i] * f <= 2.0 ** 60:
                done = False
                d[i] *= f
                for j in range(n):
                    x[i, j] /= f
                    x[j, i] *= f
        if done:
            break


@njit(cache=True)
def expm_stack(m, taylor, out):
    """``out[i] = expm(m[i])`` for a stack (K, n, n): each matrix balanced by one diagonal
    similarity of powers of two (:func:`_balance` of the stack's largest magnitudes: the
    matrices of one wing share their scales), scaled to 1-norm <= 1, the degree-18 Taylor
    polynomial ``taylor`` (19 coefficients) by Paterson-Stockmeyer, squared back and
    unbalanced: the algorithm of :func:`~aero_dva.flight.discretize.expm_batch` after an exact
    balancing step. A wing's augmented ZOH matrix has a 1-norm near 12 at 1 kHz (the stroke's
    and the pitch's scales differ) but about 0.5 balanced, which saves four squarings."""
    k, n = m.shape[0], m.shape[1]
    x = np.empty((n, n))
    x2 = np.empty((n, n))
    x3 = np.empty((n, n))
    x4 = np.empty((n, n))
    acc = np.empty((n, n))
    tmp = np.empty((n, n))
    d = np.empty(n)
    for r in range(n):
        for c in range(n):
            x[r, c] = 0.0
    for i in range(k):
        for r in range(n):
            for c in range(n):
                x[r, c] = max(x[r, c], abs(m[i, r, c]))
    _balance(x, d)
    into = np.empty((n, n))  # m -> D^-1 m D and back, by exact powers of two
    back = np.empty((n, n))
    for r in range(n):
        for c in range(n):
            into[r, c] = d[c] / d[r]
            back[r, c] = d[r] / d[c]
    for i in range(k):
        for r in range(n):
            for c in range(n):
                x[r, c] = m[i, r, c] * into[r, c]
        norm = 0.0
        for c in range(n):
            col = 0.0
            for r in range(n):
                col += abs(x[r, c])
            norm = max(norm, col)
        s = max(0, int(math.ceil(math.log2(max(norm, 1e-300)))))
        scale = 2.0 ** s
        for r in range(n):
            for c in range(n):
                x[r, c] /= scale
        _multiply(x, x, x2)
        _multiply(x2, x, x3)
        _multiply(x2, x2, x4)
        for r in range(n):
            for c in range(n):
                acc[r, c] = taylor[17] * x[r, c] + taylor[18] * x2[r, c]
            acc[r, r] += taylor[16]
        for jj in range(4):
            j = 3 - jj
            _multiply(acc, x4, tmp)
            for r in range(n):
                for c in range(n):
                    acc[r, c] = tmp[r, c] + (taylor[4 * j + 1] * x[r, c]
                                             + taylor[4 * j + 2] * x2[r, c]
                                             + taylor[4 * j + 3] * x3[r, c])
                acc[r, r] += taylor[4 * j]
        for _ in range(s):
            _multiply(acc, acc, tmp)
            for r in range(n):
                for c in range(n):
                    acc[r, c] = tmp[r, c]
        for r in range(n):
            for c in range(n):
                out[i, r, c] = acc[r, c] * back[r, c]
    return out


def compiled_expm(m: np.ndarray) -> np.ndarray:
    """:func:`~aero_dva.flight.discretize.expm_batch` of a stack (K, n, n), by
    :func:`expm_stack` (an ``expm`` for :func:`~aero_dva.flight.discretize.zoh`)."""
    m = np.ascontiguousarray(m, dtype=float)
    return expm_stack(m, TAYLOR, np.empty_like(m))
