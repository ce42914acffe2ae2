"""Exact zero-order-hold discretisation (Zhang (2006) eq. 6.7-6.9), vectorised over many systems.

The study writes ``Gamma = A^-1 (Phi - I) B`` (eq. 6.9), which fails when ``A`` is singular
(a locked Maxwell damper, lag states at ``U = 0``) and loses accuracy when it is
ill-conditioned (the Maxwell node as ``c2 -> 0``). Instead both come from one matrix
exponential of the augmented matrix (Van Loan)::

    expm([[A, B], [0, 0]] T) = [[Phi, Gamma], [0, I]]

:func:`expm_batch` evaluates many small exponentials at once: degree-18 Taylor polynomial
(Paterson-Stockmeyer, 7 products) after scaling each matrix to 1-norm <= 1, then squaring
back; the truncation error is below ``1/19! ~ 8e-18`` relative.
"""

from __future__ import annotations

import math

import numpy as np

from aero_dva.wing.checks import positive

__all__ = ["TAYLOR", "check_sampling", "expm_batch", "zoh"]

TAYLOR = np.array([1.0 / math.factorial(k) for k in range(19)])
"""The coefficients ``1 / k!`` of the degree-18 Taylor polynomial of ``exp``."""


# Paterson-Stockmeyer's blocks: the leading c[16] I + c[17] x + c[18] x^2, then
# c[4j] I + c[4j+1] x + c[4j+2] x^2 + c[4j+3] x^3 for j = 0..3. Their coefficients of x, x^2,
# x^3 (shaped to scale a stack (3, k, n, n); the leading block has no x^3) and of I.
_BLOCK_POWERS = np.array([[TAYLOR[17], TAYLOR[18], 0.0]]
                         + [TAYLOR[4 * j + 1:4 * j + 4] for j in range(4)]).reshape(5, 3, 1, 1, 1)
_BLOCK_IDENTITY = np.array([TAYLOR[16], *TAYLOR[0:16:4]]).reshape(5, 1, 1)


def _taylor18(x: np.ndarray) -> np.ndarray:
    """Degree-18 Taylor polynomial of ``exp`` for a stack (k, n, n), Paterson-Stockmeyer.

    The blocks are built together (their terms scaled in one product and summed in the order
    x, x^2, x^3, then the identity added on the diagonal only): for the small matrices here
    each elementwise operation costs as much as a matrix product.
    """
    x2 = x @ x
    x3 = x2 @ x
    x4 = x2 @ x2
    k, n = x.shape[0], x.shape[-1]
    terms = _BLOCK_POWERS * np.stack((x, x2, x3))
    blocks = terms[:, 0] + terms[:, 1]
    blocks[1:] += terms[1:, 2]
    blocks.reshape(5, k, n * n)[:, :, :: n + 1] += _BLOCK_IDENTITY
    out = blocks[0]
    for j in (3, 2, 1, 0):
        out = out @ x4
        out += blocks[j + 1]
    return out


def expm_batch(m) -> np.ndarray:
    """Matrix exponential of each matrix in ``m`` (..., n, n)."""
    m = np.asarray(m, dtype=float)
    if m.ndim < 2 or m.shape[-1] != m.shape[-2]:
        raise ValueError("m must have shape (..., n, n)")
    if not np.isfinite(m).all():
        raise ValueError("m must be finite")
    # C order: the products' rounding does not depend on how the caller laid the stack out
    flat = np.ascontiguousarray(m.reshape((-1,) + m.shape[-2:]))
    norms = np.abs(flat).sum(axis=-2).max(axis=-1)
    squarings = np.maximum(0, np.ceil(np.log2(np.maximum(norms, 1e-300)))).astype(int)
    if squarings.size == 1 or (squarings.size and (squarings == squarings[0]).all()):
        # one scaling for the whole stack (a streamed flight's few new conditions): the
        # stack is scaled as it is, not gathered by a mask
        s = squarings[0]
        e = _taylor18(flat / 2.0**s)
        for _ in range(s):
            e = e @ e
        return e.reshape(m.shape)
    out = np.empty_like(flat)
    for s in np.unique(squarings):
        sel = squarings == s
        e = _taylor18(flat[sel] / 2.0**s)
        for _ in range(s):
            e = e @ e
        out[sel] = e
    return out.reshape(m.shape)


def zoh(a, b, dt: float, expm=None):
    """Exact ZOH discretisation of ``y' = A y + B u`` for one or many systems.

    Parameters
    ----------
    a : array_like, shape (..., n, n)
    b : array_like, shape (..., n) or (..., n, m)
    dt : float
        Sample interval [s], > 0.
    expm : callable, optional
        The matrix exponential of a stack (K, n, n) (default :func:`expm_batch`).

    Returns
    -------
    phi : ndarray, shape (..., n, n)
        ``exp(A dt)`` (eq. 6.8).
    gamma : ndarray, same shape as ``b``
        ``int_0^dt exp(A s) ds B`` (eq. 6.9 without inverting ``A``).
    """
    dt = positive(dt, "dt")
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    vector = b.ndim == a.ndim - 1
    if vector:
        b = b[..., None]
    n, m = a.shape[-1], b.shape[-1]
    if a.shape[-2] != n or b.shape[-2] != n:
        raise ValueError(f"a must be (..., n, n) and b (..., n[, m]); got {a.shape}, {b.shape}")
    shape = a.shape[:-2]
    if b.shape[:-2] != shape:
        shape = np.broadcast_shapes(shape, b.shape[:-2])
    aug = np.zeros(shape + (n + m, n + m))
    np.multiply(a, dt, out=aug[..., :n, :n])
    np.multiply(b, dt, out=aug[..., :n, n:])
    e = (expm_batch if expm is None else expm)(aug)
    phi = e[..., :n, :n]
    gamma = e[..., :n, n:]
    return phi, (gamma[..., 0] if vector else gamma)


def check_sampling(a, dt: float) -> None:
    """Raise ValueError if an oscillatory mode of ``a`` is at or above the Nyquist frequency.

    Exact ZOH stays exact at any ``dt``, but a sampled mode above Nyquist aliases: the
    discrete model would then show it at a wrong frequency, so such a request is refused.
    """
    lam = np.linalg.eigvals(np.asarray(a, dtype=float))
    fast = np.abs(lam.imag) * dt
    if np.any(fast >= np.pi):
        f_mode = np.abs(lam.imag).max() / (2 * np.pi)
        raise ValueError(
            f"sample_rate {1.0 / dt:g} Hz is too low: a mode at {f_mode:.4g} Hz is at or above "
            "the Nyquist frequency"
        )
