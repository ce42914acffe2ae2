"""The modal recursion of :mod:`aero_dva.flight.modal_simulator`, compiled (numba).

One pass over the samples: ``y[:, t] = Re(cm[k] z) + d[k] f[t]``, ``z <- lam[k] z + g[k] f[t]``
with ``k`` the condition of the sample's block; where the condition changes, the state goes
through physical coordinates into the new condition's modes (``x = Re(v_out[k'] z)``,
``z = vinv[k] x``). The vectorised NumPy form of the same recursion (kept in the simulator as
the reference) pays for three sweeps over every block and a batched product; here a sample
costs a few complex multiply-adds. Pure numerics.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["run_modal"]


@njit(cache=True)
def run_modal(lam, g, cm, d, vinv, v_out, condition, force, block, out):
    """Fill ``out`` (p, n) with the outputs from rest (shapes: :class:`ModalBlocks`)."""
    m = lam.shape[1]
    p = cm.shape[1]
    nx = v_out.shape[1]
    n = force.size
    zr = np.zeros(m)
    zi = np.zeros(m)
    x = np.zeros(nx)
    prev = condition[0]
    for ib in range(condition.size):
        k = condition[ib]
        if k != prev:
            for r in range(nx):
                s = 0.0
                for j in range(m):
                    w = v_out[prev, r, j]
                    s += w.real * zr[j] - w.imag * zi[j]
                x[r] = s
            for j in range(m):
                sr = 0.0
                si = 0.0
                for r in range(nx):
                    w = vinv[k, j, r]
                    sr += w.real * x[r]
                    si += w.imag * x[r]
                zr[j] = sr
                zi[j] = si
            prev = k
        stop = min((ib + 1) * block, n)
        for t in range(ib * block, stop):
            f = force[t]
            for q in range(p):
                s = 0.0
                for j in range(m):
                    w = cm[k, q, j]
                    s += w.real * zr[j] - w.imag * zi[j]
                out[q, t] = s + d[k, q] * f
            for j in range(m):
                a = lam[k, j]
                b = g[k, j]
                re = a.real * zr[j] - a.imag * zi[j] + b.real * f
                zi[j] = a.real * zi[j] + a.imag * zr[j] + b.imag * f
                zr[j] = re
    return out
