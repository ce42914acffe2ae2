"""Starting values for FRF-domain fits that do not depend on a start: global searches.

:func:`maxwell_from_stiffness` fits the general Maxwell model over a grid of element corner
frequencies (linear least squares per combination); :func:`modal_term_scan` finds a single
modal term (a foundation mode) in a compliance over a grid of frequencies and damping ratios.
Both solve many small linear problems at once through one Gram matrix
(:func:`batched_least_squares`).
"""
from __future__ import annotations

import itertools

import numpy as np


def residual_peaks(f, residual, groups, count: int) -> list[float]:
    """Frequencies [Hz] of the ``count`` largest local maxima of the residual power
    (3-point moving average within each condition)."""
    found = []
    for g in np.unique(groups):
        sel = groups == g
        p = np.convolve(np.abs(residual[sel]) ** 2, np.ones(3) / 3, mode="same")
        inner = np.nonzero((p[1:-1] >= p[:-2]) & (p[1:-1] >= p[2:]))[0] + 1
        found += [(p[i], f[sel][i]) for i in inner]
    found.sort(reverse=True)
    return [freq for _, freq in found[:count]]


def positive(x, floor):
    return max(float(x), floor)


def batched_least_squares(columns, rhs, subsets):
    """Weighted linear least squares for many column subsets at once.

    ``columns`` (M, P) real, ``rhs`` (M,), ``subsets`` (S, Q) column indices. Normal equations
    on unit-norm columns (one Gram matrix for all subsets). Returns solutions (S, Q) and
    residual sums of squares (S,); singular subsets get NaN.
    """
    norm = np.linalg.norm(columns, axis=0)
    norm[norm == 0] = 1.0
    a = columns / norm
    gram, proj = a.T @ a, a.T @ rhs
    g = gram[subsets[:, :, None], subsets[:, None, :]]
    r = proj[subsets]
    x = np.full(r.shape, np.nan)
    ok = np.linalg.cond(g) < 1e12
    if np.any(ok):
        x[ok] = np.linalg.solve(g[ok], r[ok][..., None])[..., 0]
    rss = float(rhs @ rhs) - np.einsum("sq,sq->s", x, r)
    return x / norm[subsets], rss


def maxwell_from_stiffness(omega, stiffness, weights, n, k_fixed=None, corners_hz=None):
    """Maxwell model of order n closest to a complex stiffness, over a grid of time constants.

    For fixed relaxation times tau_i, K(w) = k + j w c + sum_i k_i j w tau_i / (1 + j w tau_i)
    is linear in (k, c, k_i): every combination of n grid values is solved by weighted linear
    least squares (weights u_j on |K_model - K_j|) and the best one with all k_i > 0 wins. A
    global search over the element corners, so it does not depend on a start (the nonlinear
    fit that follows only polishes).

    Parameters
    ----------
    omega : numpy.ndarray
        Shape (N,) [rad/s].
    stiffness : numpy.ndarray
        Target K(w_j), shape (N,), complex [N/m].
    weights : numpy.ndarray
        u_j >= 0, shape (N,).
    n : int
        Number of Maxwell elements (>= 0).
    k_fixed : float, optional
        Static stiffness [N/m] (fitted when omitted).
    corners_hz : numpy.ndarray, optional
        Grid of element corner frequencies 1/(2 pi tau) [Hz]; default 16 log-spaced values
        from a third of the lowest to three times the highest frequency.

    Returns
    -------
    (k, c, k_i, c_i, cost) or None when no combination gives positive k_i.
    """
    w = np.asarray(omega, float)
    target = np.asarray(stiffness, complex)
    u = np.asarray(weights, float)
    if w.ndim != 1 or target.shape != w.shape or u.shape != w.shape:
        raise ValueError(f"omega, stiffness and weights must have one shape (N,), got "
                         f"{w.shape}, {target.shape}, {u.shape}")
    if not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"n must be an integer >= 0, got {n!r}")
    if corners_hz is None:
        f = w / (2 * np.pi)
        corners_hz = np.geomspace(f.min() / 3, f.max() * 3, 16)
    taus = 1.0 / (2 * np.pi * np.asarray(corners_hz, float))
    s = 1j * w[:, None]
    head = [s[:, 0]] if k_fixed is not None else [np.ones_like(target), s[:, 0]]
    cols = np.column_stack(head + list((s * taus / (1.0 + s * taus)).T)) * u[:, None]
    rhs = u * (target - (k_fixed or 0.0))
    nh = len(head)
    combos = list(itertools.combinations(range(taus.size), n))
    combos = np.array(combos, dtype=int).reshape(len(combos), n)
    subsets = np.column_stack([np.tile(np.arange(nh), (combos.shape[0], 1)), combos + nh])
    x, rss = batched_least_squares(np.vstack([cols.real, cols.imag]),
                                    np.concatenate([rhs.real, rhs.imag]), subsets)
    good = np.all(x[:, nh:] > 0, axis=1) & np.all(np.isfinite(x), axis=1)
    if not np.any(good):
        return None
    i = int(np.flatnonzero(good)[np.argmin(rss[good])])
    ks = x[i, nh:]
    k = float(k_fixed) if k_fixed is not None else float(x[i, 0])
    return k, float(x[i, nh - 1]), ks, ks * taus[combos[i]], float(max(rss[i], 0.0))


def modal_term_scan(omega, compliance, weights, f_grid_hz, zetas, background=0):
    """Best single-mode compliance a / (w_f^2 - w^2 + 2 j z w_f w) for each grid (f_f, z).

    A foundation on its spring is such a term in the compliance of the mount path. For each
    (f_f, z) the modal constant a (real) and, with ``background`` = B > 0, a smooth complex
    polynomial of degree B - 1 in ln(w) (it absorbs what a mis-fitted mount model leaves,
    like the residual terms of modal analysis) are fitted by weighted linear least squares.

    Returns rows (cost, f_f, z, a) with a > 0, sorted by cost.
    """
    w = np.asarray(omega, float)
    u = np.asarray(weights, float)
    d = np.asarray(compliance, complex)
    if w.ndim != 1 or d.shape != w.shape or u.shape != w.shape:
        raise ValueError(f"omega, compliance and weights must have one shape (N,), got "
                         f"{w.shape}, {d.shape}, {u.shape}")
    x = np.log(w / np.sqrt(w.min() * w.max()))
    smooth = [u * x**i for i in range(background)]
    # background columns: real and imaginary coefficients of each polynomial term
    cols = [*smooth, *(1j * t for t in smooth)]
    pairs = [(float(ff), float(z)) for ff in np.asarray(f_grid_hz, float) for z in zetas]
    for ff, z in pairs:
        wf = 2 * np.pi * ff
        cols.append(u / (wf**2 - w**2 + 2j * z * wf * w))
    cols = np.column_stack(cols)
    nb = 2 * background
    subsets = np.column_stack([np.arange(len(pairs)) + nb,
                               np.tile(np.arange(nb), (len(pairs), 1))]).astype(int)
    sol, rss = batched_least_squares(np.vstack([cols.real, cols.imag]),
                                      np.concatenate([(u * d).real, (u * d).imag]), subsets)
    rows = [(float(rss[i]), ff, z, float(sol[i, 0])) for i, (ff, z) in enumerate(pairs)
            if sol[i, 0] > 0]
    return sorted(rows)
