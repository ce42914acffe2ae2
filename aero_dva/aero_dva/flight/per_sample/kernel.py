"""The per-sample loop of the switched flight, compiled (numba): the law, the damper's lag and
relief valve, the observer and the plant's exact step (pure numerics).

:func:`fly_maps` is what :func:`aero_dva.flight.per_sample.flight.fly_switched` runs once its
maps are built. A sample costs a few small matrix-vector products and scalar operations, so in
Python the interpreter's overhead per sample decided the flight's speed; the loop is compiled
once per machine (``cache=True``) and runs as machine code. The wing with its Maxwell DVA
(7 states, an observer of 7 or none) takes a copy of the loop written for those sizes
(:func:`_fly_fixed`, equal to the bit), others the general one (:func:`_fly_general`).

Per flight and sample ``i``, with ``x`` the plant's state, ``p`` the observer's prediction,
``u = [f; noise]`` and ``q`` the held condition, in this order:

1. every ``every`` samples, the decision of sample i-1 becomes the target;
2. ``(F, h) = g_state[q] @ [x; p] + g_in[q] @ u``; ``F h > 0`` is this sample's decision;
3. the damper's lag over the sample: its mean c2 selects the table level (nearest in log c2),
   ``c`` is the lag's state at the sample's end; the relief valve forces level 0 while the
   true force ``|k2 delta|`` exceeds the limit;
4. ``p <- Ao[level] @ (est[q] @ [x; p; u])`` (the filtered estimate, predicted) and
   ``x <- Ad[level] @ x + Bd[level] f``.

The steps of condition q at a level are ``sum_j weight[q, j] steps[index[q, j], level]``
(:func:`aero_dva.flight.per_sample.smooth_tables.interpolated_maps`), formed when first flown,
or all at once by :func:`fixed_maps` for a flight that keeps them.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["FixedMaps", "fixed_maps", "fly_fixed", "fly_maps"]


@njit(cache=True)
def _form(cur, steps, index, weight, q, k):
    """``cur[k] = sum_j weight[q, j] steps[index[q, j], k]`` (zero weights skipped; indexed
    directly, without views)."""
    size = cur.shape[1]
    for s in range(size):
        cur[k, s] = 0.0
    for j in range(index.shape[1]):
        w = weight[q, j]
        if w != 0.0:
            b = index[q, j]
            for s in range(size):
                cur[k, s] += w * steps[b, k, s]


@njit(cache=True)
def _damper_level(hi, c, f, tau, decay, mean_factor, c_lo, c_hi, log_lo, per_level, relief,
                  spring_force, force_limit):
    """The table level flown over a sample with the target ``hi`` (True: c_hi): the level
    nearest in log c2 to the lag's mean over the sample (``c[f]`` becomes the lag's c2 at its
    end), the target itself without lag, the lowest while the relief valve is open."""
    if tau > 0.0:
        target = c_hi if hi else c_lo
        mean = target + (c[f] - target) * mean_factor
        c[f] = target + (c[f] - target) * decay
        k = int((math.log(mean) - log_lo) / per_level + 0.5)
    else:
        k = 1 if hi else 0
    if relief and spring_force > force_limit:
        k = 0
    return k


def fly_maps(steps, index, weight, est, g_in, g_state, sample_map, inputs, n, tau, decay,
             mean_factor, c_lo, c_hi, per_level, force_limit, k2, d_col, every, first, z, c,
             target_hi, prev_fh, yield_force, locked, table):
    """Fly ``inputs`` (F, N, v) with the law (module docstring).

    ``steps`` (B, L, S) holds per base condition and level the plant's ``[Ad | Bd]`` (n, n+1)
    flattened, then the observer's ``Ao`` (m, m) if its model is another (else Ao = Ad), then
    the plant's column ``g`` (n) of a unit deflection rate. A Bingham damper
    (``yield_force`` > 0 [N]): on a sample whose spring force ``|k2 delta|`` is at most the
    yield force the damper is locked and the plant takes ``locked[q]`` (``[Ad | Bd]`` at
    c2 = inf); above it the damper flows with the force ``c2 v + yield sign(delta)``, i.e.
    the level's step plus ``(k2 / c2) (yield / k2) sign(delta) g`` (the sign and the
    lock held over the sample; ``table`` the levels' c2). The observer's model stays linear.
    ``est`` (K, m, n+m+v); ``g_in`` (K, 2, v); ``g_state`` (K, 2, n+m); ``sample_map`` (N,)
    the held condition of each sample. ``first`` is the flight's index of the first sample
    (decisions act every ``every`` samples of the flight). The loop's state, per flight, is
    updated in place to carry a flight across calls: ``z`` (F, n+m) plant state and
    prediction, ``c`` (F,) the lag's c2, ``target_hi`` (F,) and ``prev_fh`` (F,) the target in
    force and the last sample's F h. Returns the plant's states (F, N, n) at each sample's
    start, the levels flown (F, N) and the targets (F, N; True: c_hi).

    A plant of :data:`FIXED_STATES` states with the four measured signals (the wing with its
    Maxwell DVA and quasi-steady aerodynamics) flies :func:`_fly_fixed`: the same arithmetic
    in the same order (equal to the bit), on transposed maps whose products the compiler
    vectorises across rows. Other sizes fly :func:`_fly_general`.
    """
    fixed = fixed_maps(steps, index, weight, est, g_in, g_state, n, inputs.shape[2],
                       whole=False)
    if fixed is None:
        return _fly_general(steps, index, weight, est, g_in, g_state, sample_map, inputs, n,
                            tau, decay, mean_factor, c_lo, c_hi, per_level, force_limit, k2,
                            d_col, every, first, z, c, target_hi, prev_fh, yield_force,
                            locked, table)
    return fly_fixed(fixed, sample_map, inputs, tau, decay, mean_factor, c_lo, c_hi,
                     per_level, force_limit, k2, d_col, every, first, z, c, target_hi,
                     prev_fh, yield_force, locked, table)


class FixedMaps(NamedTuple):
    """The maps of :func:`_fly_fixed` (:func:`fixed_maps`)."""

    steps: np.ndarray  # (B, L, S) the interpolation's base maps, column-major
    index: np.ndarray
    weight: np.ndarray
    whole: np.ndarray  # (K, L, S) every condition's maps at every level, or (0, L, S)
    reads: np.ndarray  # (K, n + m + v, 16)
    observe: bool
    obs_base: int
    plant: np.ndarray  # the entries of [Ad | Bd] in the column-major layout (-1: padding)


def fixed_maps(steps, index, weight, est, g_in, g_state, n, nv, whole=True):
    """The maps of :func:`fly_fixed` from those of :func:`fly_maps`, or None if the sizes
    are not :func:`_fly_fixed`'s. ``whole``: form every condition's maps at every level now
    (kept with a flight's maps, a repeated flight forms none), else as flown."""
    m = est.shape[1]
    if n != FIXED_STATES or nv != FIXED_INPUTS or m not in (0, n):
        return None
    own_observer = steps.shape[2] > n * (n + 1) + n
    order = _fixed_layout(n, own_observer)
    steps_t = np.ascontiguousarray(steps[..., order])
    steps_t[..., order < 0] = 0.0  # padding rows
    # the rows read from [x; p; u] at a sample's start: the estimate (m), then F and h
    reads = np.zeros((est.shape[0], n + m + nv, 16))
    reads[:, :, :m] = est.transpose(0, 2, 1)
    reads[:, :, 7:9] = np.concatenate([g_state, g_in], axis=2).transpose(0, 2, 1)
    formed = np.empty((0,) + steps_t.shape[1:])  # none: the loop forms levels as flown
    if whole:
        formed = _form_all(np.empty((est.shape[0],) + steps_t.shape[1:]), steps_t, index,
                           weight)
    return FixedMaps(steps_t, index, weight, formed, reads, m > 0,
                     8 * (n + 1) if own_observer else 0, order[:8 * (n + 1)])


def fly_fixed(fixed: FixedMaps, sample_map, inputs, tau, decay, mean_factor, c_lo, c_hi,
              per_level, force_limit, k2, d_col, every, first, z, c, target_hi, prev_fh,
              yield_force, locked, table):
    """:func:`fly_maps` on maps from :func:`fixed_maps` (``locked`` as for fly_maps)."""
    plant = fixed.plant
    locked_t = np.zeros((1, plant.size))
    if yield_force > 0.0:
        locked_t = np.ascontiguousarray(locked[:, plant])
        locked_t[:, plant < 0] = 0.0
    return _fly_fixed(fixed.steps, fixed.index, fixed.weight, fixed.whole, fixed.reads,
                      sample_map, inputs, fixed.observe, fixed.obs_base, tau, decay,
                      mean_factor, c_lo, c_hi, per_level, force_limit, k2, d_col, every,
                      first, z, c, target_hi, prev_fh, yield_force, locked_t, table)


@njit(cache=True)
def _form_all(out, steps, index, weight):
    """``out[q]`` the maps of condition q at every level (:func:`_form`), for q < len(out)."""
    for q in range(out.shape[0]):
        for k in range(out.shape[1]):
            _form(out[q], steps, index, weight, q, k)
    return out


FIXED_STATES = 7
"""Plant states of :func:`_fly_fixed` (its observer has as many, or none)."""
FIXED_INPUTS = 5
"""Inputs of :func:`_fly_fixed`: the force and the noise of the four measured signals."""


def _fixed_layout(n, own_observer):
    """Source entry of each entry of :func:`_fly_fixed`'s flattened maps (-1: padding).

    The maps of :func:`_fly_general` hold ``[Ad | Bd]`` row by row, then (own observer) ``Ao``
    row by row, then the column ``g``; :func:`_fly_fixed` takes each matrix column by
    column, every column padded to 8 rows: ``[Ad | Bd]`` as 8 (n + 1) entries, ``Ao`` as
    8 n, ``g`` as 8."""
    rows = np.arange(8)
    valid = rows < n

    def columns(start, width, count):
        idx = start + rows[None, :] * width + np.arange(count)[:, None]  # [column, row]
        return np.where(valid[None, :], idx, -1).ravel()

    parts = [columns(0, n + 1, n + 1)]
    g_at = n * (n + 1)
    if own_observer:
        parts.append(columns(g_at, n, n))
        g_at += n * n
    parts.append(np.where(valid, g_at + rows, -1))
    return np.concatenate(parts)


@njit(cache=True)
def _fly_general(steps, index, weight, est, g_in, g_state, sample_map, inputs, n, tau, decay,
                 mean_factor, c_lo, c_hi, per_level, force_limit, k2, d_col, every, first, z,
                 c, target_hi, prev_fh, yield_force, locked, table):
    """:func:`fly_maps` with loops of the model's sizes."""
    nf, nsamp, nv = inputs.shape
    m = est.shape[1]
    nm = n + m
    own_observer = steps.shape[2] > n * (n + 1) + n
    g_at = steps.shape[2] - n
    states = np.empty((nf, nsamp, n))
    level = np.empty((nf, nsamp), np.int64)
    targets = np.empty((nf, nsamp), np.bool_)
    relief = force_limit < math.inf
    log_lo = math.log(c_lo)
    e = np.empty(m)
    xn = np.empty(n)
    cur = np.empty(steps.shape[1:])
    formed = np.zeros(steps.shape[1], np.bool_)
    q_prev = -1
    for i in range(nsamp):
        q = sample_map[i]
        if q != q_prev:
            formed[:] = False
            q_prev = q
        # Arrays are indexed directly, not through per-sample views: a view costs reference
        # counting, which here cost more than the arithmetic.
        for f in range(nf):
            if first + i > 0 and (first + i) % every == 0:
                target_hi[f] = prev_fh[f] > 0.0  # the decision of sample i-1 acts from i on
            fv = 0.0
            hv = 0.0
            for j in range(nm):
                fv += g_state[q, 0, j] * z[f, j]
                hv += g_state[q, 1, j] * z[f, j]
            for j in range(nv):
                fv += g_in[q, 0, j] * inputs[f, i, j]
                hv += g_in[q, 1, j] * inputs[f, i, j]
            prev_fh[f] = fv * hv
            k = _damper_level(target_hi[f], c, f, tau, decay, mean_factor, c_lo, c_hi, log_lo,
                              per_level, relief, abs(z[f, d_col]) * k2, force_limit)
            if not formed[k]:
                _form(cur, steps, index, weight, q, k)
                formed[k] = True
            level[f, i] = k
            targets[f, i] = target_hi[f]
            for j in range(n):
                states[f, i, j] = z[f, j]
            if m > 0:
                for r in range(m):
                    s = 0.0
                    for j in range(nm):
                        s += est[q, r, j] * z[f, j]
                    for j in range(nv):
                        s += est[q, r, nm + j] * inputs[f, i, j]
                    e[r] = s
                base = n * (n + 1) if own_observer else 0
                width = m if own_observer else n + 1
                for r in range(m):
                    s = 0.0
                    for j in range(m):
                        s += cur[k, base + r * width + j] * e[j]
                    z[f, n + r] = s  # p: written after its last read (est above)
            u0 = inputs[f, i, 0]
            if yield_force > 0.0 and abs(k2 * z[f, d_col]) <= yield_force:
                for r in range(n):  # locked
                    s = locked[q, r * (n + 1) + n] * u0
                    for j in range(n):
                        s += locked[q, r * (n + 1) + j] * z[f, j]
                    xn[r] = s
            else:
                offset = 0.0
                if yield_force > 0.0:
                    offset = yield_force / table[k] * (1.0 if k2 * z[f, d_col] > 0.0 else -1.0)
                for r in range(n):
                    s = cur[k, r * (n + 1) + n] * u0 + offset * cur[k, g_at + r]
                    for j in range(n):
                        s += cur[k, r * (n + 1) + j] * z[f, j]
                    xn[r] = s
            for r in range(n):
                z[f, r] = xn[r]
    return states, level, targets


@njit(cache=True)
def _fly_fixed(steps, index, weight, whole, reads, sample_map, inputs, observe, obs_base, tau,
               decay, mean_factor, c_lo, c_hi, per_level, force_limit, k2, d_col, every,
               first, z, c, target_hi, prev_fh, yield_force, locked, table):
    """:func:`_fly_general` for 7 plant states, 5 inputs and an observer of 7 states
    (``observe``) or none, on the column-major maps of :func:`_fixed_layout` (``steps``,
    ``locked``) and ``reads`` (K, 19 or 12, 16): column j of the rows read from
    ``[x; p; u]``, the estimate's 7 (``est``) then F and h (``g_state``, ``g_in``), zero
    padded to 16 rows, so that the compiler vectorises the product across them; ``whole``
    (K, L, S) every condition's maps formed at every level, or (0, L, S): formed as flown.
    Each sum runs over its terms in the order of :func:`_fly_general` (from 0.0, state
    before input), so the result is the same to the bit."""
    nf, nsamp = inputs.shape[0], inputs.shape[1]
    n = 7
    g_at = obs_base + 8 * n if obs_base else 8 * (n + 1)
    states = np.empty((nf, nsamp, n))
    level = np.empty((nf, nsamp), np.int64)
    targets = np.empty((nf, nsamp), np.bool_)
    relief = force_limit < math.inf
    log_lo = math.log(c_lo)
    e = np.empty(16)
    pn = np.empty(8)
    xn = np.empty(8)
    cur = np.empty(steps.shape[1:])
    formed = np.zeros(steps.shape[1], np.bool_)
    q_prev = -1
    for i in range(nsamp):
        q = sample_map[i]
        if q != q_prev:
            if whole.shape[0]:  # every level formed already
                cur = whole[q]
                formed[:] = True
            else:
                formed[:] = False
            q_prev = q
        for f in range(nf):
            if first + i > 0 and (first + i) % every == 0:
                target_hi[f] = prev_fh[f] > 0.0
            x0, x1, x2, x3, x4, x5, x6 = (z[f, 0], z[f, 1], z[f, 2], z[f, 3], z[f, 4],
                                          z[f, 5], z[f, 6])
            u0, u1, u2, u3, u4 = (inputs[f, i, 0], inputs[f, i, 1], inputs[f, i, 2],
                                  inputs[f, i, 3], inputs[f, i, 4])
            if observe:
                p0, p1, p2, p3, p4, p5, p6 = (z[f, 7], z[f, 8], z[f, 9], z[f, 10], z[f, 11],
                                              z[f, 12], z[f, 13])
                for r in range(16):
                    e[r] = (((((((((((((((((((0.0 + reads[q, 0, r] * x0)
                                              + reads[q, 1, r] * x1) + reads[q, 2, r] * x2)
                                            + reads[q, 3, r] * x3) + reads[q, 4, r] * x4)
                                          + reads[q, 5, r] * x5) + reads[q, 6, r] * x6)
                                        + reads[q, 7, r] * p0) + reads[q, 8, r] * p1)
                                      + reads[q, 9, r] * p2) + reads[q, 10, r] * p3)
                                    + reads[q, 11, r] * p4) + reads[q, 12, r] * p5)
                                  + reads[q, 13, r] * p6) + reads[q, 14, r] * u0)
                                + reads[q, 15, r] * u1) + reads[q, 16, r] * u2)
                              + reads[q, 17, r] * u3) + reads[q, 18, r] * u4)
            else:
                for r in range(16):
                    e[r] = ((((((((((((0.0 + reads[q, 0, r] * x0) + reads[q, 1, r] * x1)
                                      + reads[q, 2, r] * x2) + reads[q, 3, r] * x3)
                                    + reads[q, 4, r] * x4) + reads[q, 5, r] * x5)
                                  + reads[q, 6, r] * x6) + reads[q, 7, r] * u0)
                                + reads[q, 8, r] * u1) + reads[q, 9, r] * u2)
                              + reads[q, 10, r] * u3) + reads[q, 11, r] * u4)
            prev_fh[f] = e[7] * e[8]
            k = _damper_level(target_hi[f], c, f, tau, decay, mean_factor, c_lo, c_hi, log_lo,
                              per_level, relief, abs(z[f, d_col]) * k2, force_limit)
            if not formed[k]:
                _form(cur, steps, index, weight, q, k)
                formed[k] = True
            level[f, i] = k
            targets[f, i] = target_hi[f]
            for j in range(n):
                states[f, i, j] = z[f, j]
            if observe:
                e0, e1, e2, e3, e4, e5, e6 = e[0], e[1], e[2], e[3], e[4], e[5], e[6]
                b = obs_base
                for r in range(8):
                    pn[r] = (((((((0.0 + cur[k, b + r] * e0) + cur[k, b + 8 + r] * e1)
                                 + cur[k, b + 16 + r] * e2) + cur[k, b + 24 + r] * e3)
                               + cur[k, b + 32 + r] * e4) + cur[k, b + 40 + r] * e5)
                             + cur[k, b + 48 + r] * e6)
                for r in range(n):
                    z[f, n + r] = pn[r]
            if yield_force > 0.0 and abs(k2 * z[f, d_col]) <= yield_force:
                for r in range(8):  # locked
                    xn[r] = (((((((locked[q, 56 + r] * u0 + locked[q, r] * x0)
                                  + locked[q, 8 + r] * x1) + locked[q, 16 + r] * x2)
                                + locked[q, 24 + r] * x3) + locked[q, 32 + r] * x4)
                              + locked[q, 40 + r] * x5) + locked[q, 48 + r] * x6)
            else:
                offset = 0.0
                if yield_force > 0.0:
                    offset = yield_force / table[k] * (1.0 if k2 * z[f, d_col] > 0.0 else -1.0)
                for r in range(8):
                    xn[r] = ((((((((cur[k, 56 + r] * u0 + offset * cur[k, g_at + r])
                                   + cur[k, r] * x0) + cur[k, 8 + r] * x1)
                                 + cur[k, 16 + r] * x2) + cur[k, 24 + r] * x3)
                               + cur[k, 32 + r] * x4) + cur[k, 40 + r] * x5)
                             + cur[k, 48 + r] * x6)
            for r in range(n):
                z[f, r] = xn[r]
    return states, level, targets
