"""Model order by held-out error with a significance rule.

The smallest held-out error picks among orders whose errors differ by less than their own
scatter, so a change of the data by a small fraction of the noise can swap the choice (5 or 7
modes on two FRF estimates of one test). Here every order is compared with the best one point
by point on the same held-out points: d_j = |r_j(n)|^2 - |r_j(best)|^2. An order is as good as
the best when the mean of d is within ``z`` standard errors of zero (a paired one-standard-
error rule); the smallest such order is chosen. A change of the data by a fraction eps of the
noise moves the mean of d by about eps of its standard error, so the choice moves only when
the evidence sat within that much of the threshold.

A doublet (two modes closer than ``bandwidths`` half-power bandwidths of the wider one) is
kept only when its model beats the next smaller order significantly by the same paired test:
two close modes can trade one broad peak for two narrow ones on almost any noisy data.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OrderChoice", "choose_order", "has_doublet", "paired_excess"]


@dataclass(frozen=True)
class OrderChoice:
    """The chosen order and why.

    Attributes
    ----------
    order : int
    best : int
        The order with the smallest held-out error.
    excess : dict
        Order -> (mean of d, its standard error) against the best (module docstring).
    reason : str
    """

    order: int
    best: int
    excess: dict
    reason: str


def paired_excess(sq: np.ndarray, sq_ref: np.ndarray) -> tuple[float, float]:
    """Mean and standard error of the per-point excess ``sq - sq_ref`` (squared held-out
    residuals of two models on the same points)."""
    d = np.asarray(sq, float) - np.asarray(sq_ref, float)
    if d.size < 2:
        return float(d.mean()) if d.size else 0.0, np.inf
    return float(d.mean()), float(d.std(ddof=1) / np.sqrt(d.size))


def has_doublet(freqs, zetas, bandwidths: float = 3.0) -> bool:
    """Whether two modes are closer than ``bandwidths`` half-power bandwidths (2 zeta f) of
    the wider of the two."""
    f = np.asarray(freqs, float)
    z = np.asarray(zetas, float)
    for i in range(f.size):
        for j in range(i + 1, f.size):
            width = max(2 * z[i] * f[i], 2 * z[j] * f[j])
            if abs(f[i] - f[j]) < bandwidths * width:
                return True
    return False


def choose_order(held_sq: dict, z: float = 2.0, doublets: dict | None = None,
                 preferred=None) -> OrderChoice:
    """The smallest order not significantly worse than the best (module docstring).

    Parameters
    ----------
    held_sq : dict
        Order -> squared held-out residuals (same points, same order, for every model).
    z : float
        Standard errors of the paired mean excess within which an order counts as the best.
    doublets : dict, optional
        Order -> whether that model has a doublet; such an order must beat the next smaller
        order by ``z`` standard errors.
    preferred : callable, optional
        Order -> bool; among the orders as good as the best, the smallest preferred one is
        taken when there is one (e.g. a white residual).
    """
    if not held_sq:
        raise ValueError("held_sq is empty: no order to choose from")
    orders = sorted(held_sq)
    means = {n: float(np.mean(held_sq[n])) for n in orders}
    best = min(orders, key=means.get)
    excess = {n: paired_excess(held_sq[n], held_sq[best]) for n in orders}
    within = [n for n in orders if excess[n][0] <= z * excess[n][1]]
    doublets = doublets or {}
    kept = []
    for n in within:
        smaller = [m for m in orders if m < n]
        if doublets.get(n) and smaller:
            gain, se = paired_excess(held_sq[smaller[-1]], held_sq[n])
            if not gain > z * se:
                continue  # a doublet that does not pay for itself
        kept.append(n)
    if not kept:  # every candidate order was a doublet without significant gain
        kept = [n for n in orders if not doublets.get(n)] or orders
        kept = [min(kept, key=means.get)]
    pick = [n for n in kept if preferred is None or preferred(n)]
    order = (pick or kept)[0]
    reason = (f"smallest order within {z:g} standard errors of the best ({best}) in paired "
              "held-out error" + (", a white residual preferred" if pick and preferred else "")
              + (f"; doublets without significant gain dropped: "
                 f"{sorted(n for n in within if n not in kept)}"
                 if any(n not in kept for n in within) else ""))
    return OrderChoice(order, best, excess, reason)
