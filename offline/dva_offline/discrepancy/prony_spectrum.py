"""A relaxation spectrum that spans many decades: a Prony series with fixed time constants.

E(w) = E_inf + sum_i E_i j w tau_i / (1 + j w tau_i) at the reduced frequency w a_T, with the
tau_i log-spaced (``per_decade`` of them per decade) over the reduced-frequency span the
shifted data need plus a margin. For fixed tau_i and a fixed shift the model is linear in the
moduli, which are solved non-negative (scipy.optimize.nnls): the nonlinear search is over the
shift parameters only (variable projection), as the viscoelastic tools (pyvisco) do. Each
E_i jw tau_i / (1 + jw tau_i) is a Maxwell element with k_i = E_i, c_i = E_i tau_i.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

MAX_SPAN_DECADES = 60.0  # a grid longer than this means a shift running off to a singularity


def relaxation_times(log_f_reduced: np.ndarray, per_decade: float,
                     margin: float = 1.0) -> np.ndarray:
    """Time constants [s], log-spaced with ``per_decade`` per decade from ``margin`` decades
    below to ``margin`` above the span of the reduced frequencies (log10 of Hz), the span
    capped at :data:`MAX_SPAN_DECADES` around its centre."""
    if not per_decade > 0:
        raise ValueError(f"per_decade must be > 0, got {per_decade}")
    lf = np.asarray(log_f_reduced, float)
    lf = lf[np.isfinite(lf)]
    if lf.size == 0:
        raise ValueError("no finite reduced frequency")
    lo, hi = float(lf.min()) - margin, float(lf.max()) + margin
    if hi - lo > MAX_SPAN_DECADES:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - MAX_SPAN_DECADES / 2, mid + MAX_SPAN_DECADES / 2
    n = int(np.ceil((hi - lo) * per_decade)) + 1
    return 1.0 / (2 * np.pi * np.logspace(lo, hi, n))


def prony_columns(w_reduced: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """Complex design matrix (N, 1 + M): the equilibrium column 1 and j w tau / (1 + j w tau)
    per time constant, at reduced angular frequencies [rad/s]."""
    s = 1j * np.asarray(w_reduced, float)[:, None] * np.asarray(taus, float)[None, :]
    return np.column_stack([np.ones(s.shape[0], complex), s / (1.0 + s)])


def nonnegative_moduli(columns: np.ndarray, values: np.ndarray, weights: np.ndarray,
                       points: np.ndarray) -> np.ndarray:
    """Moduli >= 0 minimising sum_j w_j^2 |columns_j x - y_j|^2 over ``points`` (mask).

    Columns are scaled to unit norm first (the moduli span decades)."""
    a = columns[points] * weights[points, None]
    b = values[points] * weights[points]
    m = np.vstack([a.real, a.imag])
    rhs = np.concatenate([b.real, b.imag])
    norm = np.linalg.norm(m, axis=0)
    norm[norm == 0] = 1.0
    try:
        x, _ = nnls(m / norm, rhs, maxiter=50 * m.shape[1])
    except RuntimeError as exc:  # its iteration limit: the candidate fails, the loop goes on
        raise ValueError(f"non-negative least squares of the moduli: {exc}") from None
    return x / norm


def free_shift_values(groups: np.ndarray, reference: int, values: np.ndarray) -> np.ndarray:
    """log10 a_T per point of the per-condition form: one free shift per condition, the
    reference condition's fixed at 0 (``values`` for the others, in condition order)."""
    labels = np.unique(groups)
    full = np.zeros(labels.size)
    full[labels != reference] = values
    return full[np.searchsorted(labels, groups)]


def pairwise_shifts(log_f: np.ndarray, log_mag: np.ndarray, groups: np.ndarray,
                    levels: np.ndarray, reference: int, min_slope: float = 0.01) -> np.ndarray:
    """log10 a_T per condition from shifting each condition onto its neighbour in level, the
    reference condition at 0 (the classical manual construction of a master curve, as
    pyvisco's ``get_aT`` does it: a power law per sweep, matched where the two meet).

    Each sweep's log10 |E| is fitted by a line in log10 f; two neighbours are matched at the
    modulus level halfway between where one ends and the other begins: there, the shift
    moves the second sweep's frequency onto the first's. Slopes are held above ``min_slope``
    (a glassy plateau is nearly flat: its shift is then large and weakly determined; this is
    a start for the fit, not a result).
    """
    labels = np.unique(groups)
    order = labels[np.argsort([levels[groups == g].mean() for g in labels])]
    lines = {}
    for g in labels:
        sel = groups == g
        slope, icpt = np.polyfit(log_f[sel], log_mag[sel], 1)
        lines[g] = (max(float(slope), min_slope), float(icpt), log_mag[sel])
    step = {}
    for a, b in zip(order[:-1], order[1:]):
        (sa, ia, ua), (sb, ib, ub) = lines[a], lines[b]
        level = 0.5 * (min(ua.min(), ub.max()) + max(ua.min(), ub.max()))
        step[(a, b)] = (level - ia) / sa - (level - ib) / sb  # log a_T(b) - log a_T(a)
    shift = {reference: 0.0}
    pos = int(np.flatnonzero(order == reference)[0])
    for i in range(pos + 1, order.size):
        shift[order[i]] = shift[order[i - 1]] + step[(order[i - 1], order[i])]
    for i in range(pos - 1, -1, -1):
        shift[order[i]] = shift[order[i + 1]] - step[(order[i], order[i + 1])]
    return np.array([shift[g] for g in labels])
