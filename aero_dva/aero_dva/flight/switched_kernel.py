"""The per-sample loop of the switched flight, compiled (numba): the law, the damper's lag and
relief valve, the observer and the plant's exact step (pure numerics).

:func:`fly_maps` is what :func:`aero_dva.flight.switched_flight.fly_switched` runs once its
maps are built. A sample costs a few small matrix-vector products and scalar operations, so in
Python the interpreter's overhead per sample decided the flight's speed; the loop is compiled
once per machine (``cache=True``) and runs as machine code.

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
(:func:`aero_dva.flight.smooth_tables.interpolated_maps`), formed when first flown.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["fly_maps"]


@njit(cache=True)
def _form(out, steps, index, weight, k):
    """``out = sum_j weight[j] steps[index[j], k]`` (zero weights skipped)."""
    out[:] = 0.0
    for j in range(index.size):
        w = weight[j]
        if w != 0.0:
            src = steps[index[j], k]
            for s in range(out.size):
                out[s] += w * src[s]


@njit(cache=True)
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
    """
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
        gs = g_state[q]
        gi = g_in[q]
        eq = est[q]
        for f in range(nf):
            x = z[f]
            u = inputs[f, i]
            if first + i > 0 and (first + i) % every == 0:
                target_hi[f] = prev_fh[f] > 0.0  # the decision of sample i-1 acts from i on
            fv = 0.0
            hv = 0.0
            for j in range(nm):
                fv += gs[0, j] * x[j]
                hv += gs[1, j] * x[j]
            for j in range(nv):
                fv += gi[0, j] * u[j]
                hv += gi[1, j] * u[j]
            prev_fh[f] = fv * hv
            if tau > 0.0:
                target = c_hi if target_hi[f] else c_lo
                mean = target + (c[f] - target) * mean_factor
                c[f] = target + (c[f] - target) * decay
                k = int((math.log(mean) - log_lo) / per_level + 0.5)
            else:
                k = 1 if target_hi[f] else 0
            if relief and abs(x[d_col]) * k2 > force_limit:
                k = 0
            if not formed[k]:
                _form(cur[k], steps, index[q], weight[q], k)
                formed[k] = True
            level[f, i] = k
            targets[f, i] = target_hi[f]
            for j in range(n):
                states[f, i, j] = x[j]
            step = cur[k]
            if m > 0:
                for r in range(m):
                    s = 0.0
                    for j in range(nm):
                        s += eq[r, j] * x[j]
                    for j in range(nv):
                        s += eq[r, nm + j] * u[j]
                    e[r] = s
                base = n * (n + 1) if own_observer else 0
                width = m if own_observer else n + 1
                for r in range(m):
                    s = 0.0
                    for j in range(m):
                        s += step[base + r * width + j] * e[j]
                    x[n + r] = s  # p: written after its last read (est above)
            plant = step
            offset = 0.0
            if yield_force > 0.0:
                force = k2 * x[d_col]
                if abs(force) <= yield_force:
                    plant = locked[q]
                else:
                    offset = yield_force / table[k] * (1.0 if force > 0.0 else -1.0)
            for r in range(n):
                s = plant[r * (n + 1) + n] * u[0] + offset * step[g_at + r]
                for j in range(n):
                    s += plant[r * (n + 1) + j] * x[j]
                xn[r] = s
            for r in range(n):
                x[r] = xn[r]
    return states, level, targets
