"""Exact stationary RMS over an (airspeed, c2) grid, one Lyapunov solve per airspeed.

The continuous-limit stationary covariance (``method="continuous"`` of
:mod:`aero_dva.control.stationary_rms`) solves ``A P + P A^T + q b b^T = 0`` with
``q = sigma^2 dt``. With a Maxwell absorber the tunable damper enters ``A`` through one entry:
the relaxation rate ``r = k2 / c2`` of the massless k2-c2 node is ``-A[d, d]`` (``d`` the node's
state), so ``A(r) = A_ref - (r - r_ref) e_d e_d^T``. On the symmetric unknowns of ``P`` the
Lyapunov operator then changes by a rank-``n`` term (``P -> e_d p^T + p e_d^T``, ``p = P e_d``),
and the Sherman-Morrison-Woodbury identity gives every ``c2`` of the grid from one solve at
``r_ref`` per airspeed::

    p(r) = p0 + delta X (I - delta H)^-1 W^T p0,    delta = r - r_ref,

with ``p0`` the solution at ``r_ref``, ``X = L_ref^-1 U``, ``H = W^T X`` (``n x n``). With
``H = S diag(eta) S^-1`` (one eigenproblem per airspeed) every output variance is a rational
function of ``delta``, ``v0 + delta sum_j a_j b_j / (1 - delta eta_j)``, evaluated for all ``c2``
at once (where ``S`` is ill-conditioned the ``n x n`` system is solved per pair instead).
Stability comes from the Routh-Hurwitz test of ``det(sI - A(r)) = chi_ref(s) + delta chi_d(s)``
(``chi_d`` the characteristic polynomial of ``A_ref`` without row and column ``d``), also
affine in ``delta``.

Columns where the damper is not a Maxwell element in the model (``c2 = 0`` and the plain-damper
limit, ``c2 = inf``) and airspeeds where ``A_ref`` has a pair of eigenvalues summing to nearly
zero (the operator is near singular there) are computed by
:func:`~aero_dva.control.stationary_rms.stationary_rms` instead. The sampled (``"discrete"``)
setting has no such structure (``Phi = exp(A dt)`` is not affine in ``r``) and keeps that route.
"""

from __future__ import annotations

import numpy as np

from aero_dva.control.stationary_rms import (
    CONDITION_LIMIT,
    _continuous_operator,
    stationary_rms,
)
from aero_dva.wing.checks import non_negative, positive, real_array
from aero_dva.wing.model import DISPLACEMENT_NAMES, MAXWELL_RATE_LIMIT, AeroelasticModel

__all__ = ["continuous_rms_map", "hurwitz_stable"]

_PAIR_MARGIN = 1e-7  # min |lambda_i + lambda_j| / max |lambda| of A_ref for the fast route


def _poly_from_roots(roots: np.ndarray) -> np.ndarray:
    """Real coefficients (..., m + 1), highest power first, of the monic polynomials with the
    given roots (..., m) (closed under conjugation)."""
    coef = np.zeros(roots.shape[:-1] + (roots.shape[-1] + 1,), dtype=complex)
    coef[..., 0] = 1.0
    for k in range(roots.shape[-1]):
        coef[..., 1:k + 2] -= roots[..., k, None] * coef[..., :k + 1].copy()
    return coef.real


def hurwitz_stable(coef: np.ndarray) -> np.ndarray:
    """Routh-Hurwitz test, vectorised: every root in the open left half plane.

    Parameters
    ----------
    coef : ndarray, shape (..., m + 1)
        Real polynomial coefficients, highest power first, leading coefficient > 0.

    Returns
    -------
    ndarray of bool, shape (...)
        False for a root on the imaginary axis (a zero in the Routh array's first column).
    """
    coef = np.asarray(coef, dtype=float)
    m = coef.shape[-1] - 1
    width = m // 2 + 1
    prev = np.zeros(coef.shape[:-1] + (width,))
    cur = np.zeros_like(prev)
    prev[..., :(m + 2) // 2] = coef[..., 0::2]
    cur[..., :(m + 1) // 2] = coef[..., 1::2]
    ok = coef[..., 0] > 0
    for _ in range(m):
        ok &= cur[..., 0] > 0
        pivot = np.where(cur[..., 0] > 0, cur[..., 0], 1.0)[..., None]
        nxt = np.zeros_like(prev)
        nxt[..., :-1] = prev[..., 1:] - prev[..., :1] * cur[..., 1:] / pivot
        prev, cur = cur, nxt
    return ok


def _sym_maps(n: int, d: int):
    """Symmetric-unknown index of ``P[k, d]`` for each k (W^T), and U (n(n+1)/2, n)."""
    iu, ju = np.triu_indices(n)
    index = {(int(i), int(j)): s for s, (i, j) in enumerate(zip(iu, ju))}
    w_idx = np.array([index[(min(k, d), max(k, d))] for k in range(n)])
    u = np.zeros((iu.size, n))
    u[w_idx, np.arange(n)] = 1.0
    u[index[(d, d)], d] = 2.0
    return iu, ju, w_idx, u


def continuous_rms_map(model: AeroelasticModel, airspeeds, damping_grid, density: float, *,
                       force_std: float = 1000.0, sample_rate: float = 1000.0):
    """Continuous-limit stationary RMS of the four displacements on an (airspeed, c2) grid.

    Equal to ``stationary_rms(model, airspeeds[:, None], density, damping_grid[None, :],
    method="continuous")`` to 1e-9 relative (tests/unit/aero_dva/control/test_damping_map.py).

    Parameters
    ----------
    model : AeroelasticModel
        With a Maxwell absorber.
    airspeeds : array_like, shape (n_u,)
        [m/s], >= 0.
    damping_grid : array_like, shape (n_c,)
        ``c2`` [N s/m], >= 0 (inf allowed: a locked damper).
    density : float
        [kg/m^3]
    force_std, sample_rate : float
        ``sigma`` [N] per sample and [Hz]: the intensity is ``sigma^2 / sample_rate``.

    Returns
    -------
    rms : ndarray, shape (n_u, n_c, 4)
        RMS of :data:`~aero_dva.wing.model.DISPLACEMENT_NAMES`; ``inf`` where unstable.
    stable : ndarray of bool, shape (n_u, n_c)
    """
    if not isinstance(model, AeroelasticModel) or not model.has_maxwell:
        raise TypeError("model must be an AeroelasticModel with a Maxwell absorber")
    u = real_array(airspeeds, "airspeeds")
    c = real_array(damping_grid, "damping_grid", allow_inf=True)
    if u.ndim != 1 or c.ndim != 1:
        raise ValueError("airspeeds and damping_grid must be 1-D")
    if np.any(u < 0) or np.any(c < 0):
        raise ValueError("airspeeds and damping_grid must be >= 0")
    rho = positive(density, "density")
    sigma = non_negative(force_std, "force_std")
    q = sigma**2 / positive(sample_rate, "sample_rate")
    k2 = model.absorber.series_stiffness
    n_out = len(DISPLACEMENT_NAMES)
    rms = np.empty((u.size, c.size, n_out))
    stable = np.empty((u.size, c.size), dtype=bool)
    fast_c = np.isfinite(c) & (c * MAXWELL_RATE_LIMIT >= k2) & (k2 > 0)
    fast_u = np.zeros(u.size, dtype=bool)
    if fast_c.any() and u.size:
        fast_u = _fast(model, u, c[fast_c], rho, q, rms, stable, fast_c)
    for rows, cols in ((fast_u, ~fast_c), (~fast_u, np.ones(c.size, dtype=bool))):
        if rows.any() and cols.any():
            res = stationary_rms(model, u[rows, None], rho, c[None, cols], force_std=sigma,
                                 sample_rate=sample_rate, method="continuous")
            rms[np.ix_(rows, cols)] = res.displacement
            stable[np.ix_(rows, cols)] = res.stable
    return rms, stable


def _fast(model, u, c, rho, q, rms, stable, cols):
    """Fill the Maxwell columns ``cols`` of the rows it can; returns those rows (n_u,) bool."""
    k2 = model.absorber.series_stiffness
    n, d = model.n_states, 2 * model.n_dof
    r = k2 / c
    r_ref = float(np.exp(np.mean(np.log(r))))  # geometric middle of the grid's rates
    a_ref, b = model.matrices(u, rho, k2 / r_ref)
    lam = np.linalg.eigvals(a_ref)
    scale = np.abs(lam).max(axis=-1)
    pair = np.abs(lam[:, :, None] + lam[:, None, :]).min(axis=(-2, -1))
    ok = pair > _PAIR_MARGIN * scale
    if not ok.any():
        return ok
    a_ref, b, lam, scale = a_ref[ok], b[ok], lam[ok], scale[ok]
    iu, ju, w_idx, umat = _sym_maps(n, d)
    rhs = np.concatenate([-(b[:, iu] * b[:, ju])[..., None],
                          np.broadcast_to(umat, (a_ref.shape[0],) + umat.shape)], axis=-1)
    sol = np.linalg.solve(_continuous_operator(a_ref), rhs)
    p0, x = sol[..., 0], sol[..., 1:]
    h = x[:, w_idx, :]                      # (K, n, n)
    c_rows = model.c_displacement            # (4, n)
    xi = c_rows[:, iu] * c_rows[:, ju] * np.where(iu == ju, 1.0, 2.0)
    v0 = p0 @ xi.T                          # (K, 4)
    g = np.einsum("os,ksj->koj", xi, x)     # (K, 4, n)
    delta = r - r_ref
    # (I - delta H)^-1 = S diag(1 / (1 - delta eta)) S^-1: every c2 from one n x n eigenproblem.
    eta, s = np.linalg.eig(h)
    s_inv = np.linalg.inv(s)
    cond = np.abs(s).sum(axis=-2).max(axis=-1) * np.abs(s_inv).sum(axis=-2).max(axis=-1)
    left = g.astype(complex) @ s                               # (K, 4, n)
    right = np.einsum("kij,kj->ki", s_inv, p0[:, w_idx])      # (K, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        poles = 1.0 / (1.0 - delta[None, :, None] * eta[:, None, :])  # (K, F, n)
        tail = np.einsum("koj,kfj->kfo", left * right[:, None, :], poles).real
    var = q * (v0[:, None, :] + delta[None, :, None] * tail)
    redo = ~(np.isfinite(cond) & (cond <= CONDITION_LIMIT))
    if redo.any():  # a nearly defective H: solve (I - delta H) y = W^T p0 pair by pair
        m = np.eye(n) - delta[None, :, None, None] * h[redo, None]
        y = np.linalg.solve(m, np.broadcast_to(p0[redo][:, w_idx][:, None, :, None],
                                               m.shape[:-1] + (1,)))[..., 0]
        var[redo] = q * (v0[redo, None, :]
                         + delta[None, :, None] * np.einsum("koj,kfj->kfo", g[redo], y))
    # Characteristic polynomial, affine in delta; s scaled by |lambda|max for a balanced array.
    minor = np.delete(np.delete(a_ref, d, axis=-2), d, axis=-1)
    chi = _poly_from_roots(lam / scale[:, None])
    chi_d = _poly_from_roots(np.linalg.eigvals(minor) / scale[:, None])
    coef = np.repeat(chi[:, None, :], r.size, axis=1)
    coef[..., 1:] += (delta[None, :] / scale[:, None])[..., None] * chi_d[:, None, :]
    st = hurwitz_stable(coef)
    out = np.sqrt(np.maximum(var, 0.0))
    out[~st] = np.inf
    rows = np.flatnonzero(ok)
    rms[np.ix_(rows, np.flatnonzero(cols))] = out
    stable[np.ix_(rows, np.flatnonzero(cols))] = st
    return ok
