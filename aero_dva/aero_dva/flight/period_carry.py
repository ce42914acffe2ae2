"""The states at the hold-period boundaries of a flight, as one banded triangular solve.

The recurrence ``s[b+1] = P[b] s[b] + g[b]`` (``P`` the period's ``phi^h``, ``g`` its forced
response from rest) over all ``B`` periods is the unit lower-triangular block-bidiagonal system

    s[0] = y,    s[b+1] - P[b] s[b] = g[b],

whose band (``2 n - 1`` sub-diagonals for ``n`` states) LAPACK's ``dtbtrs`` solves by forward
substitution: the same arithmetic as stepping the recurrence, in one compiled call instead of a
Python loop over periods. Its cost grows with the number of right-hand sides (flights) one by
one, so it serves single and few flights. Pure numerics.
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import as_strided

__all__ = ["period_starts"]


def period_starts(p: np.ndarray, g: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Start states of ``s[b+1] = p[b] @ s[b] + g[b]`` from ``s[0] = y``.

    ``p`` (B, n, n), ``g`` (B, n, F), ``y`` (n, F); returns (B + 1, n, F), the last entry the
    state after the last period.
    """
    from scipy.linalg import lapack  # here: the simulator node imports this module, not scipy

    nb, n, f = g.shape
    # Band storage of column j = n b + c (Fortran (2n, N) as a C buffer (B + 1, n, 2n)): the
    # entry n + r - c rows below the diagonal is -p[b, r, c]; row 0 (the unit diagonal) is
    # not read (diag="U").
    band = np.zeros((nb + 1, n, 2 * n))
    # band[b, c, n + r - c] as a view indexed [b, c, r], filled in one pass
    step = band.strides
    below = as_strided(band[:nb, 0, n:], shape=(nb, n, n),
                       strides=(step[0], step[1] - step[2], step[2]))
    np.negative(p.transpose(0, 2, 1), out=below)
    rhs = np.empty((nb + 1, n, f))
    rhs[0] = y
    rhs[1:] = g
    x, info = lapack.dtbtrs(band.reshape(-1, 2 * n).T, rhs.reshape(-1, f), uplo="L",
                            diag="U", overwrite_b=1)
    if info != 0:  # only an argument error can get here (unit diagonal)
        raise RuntimeError(f"dtbtrs failed with info {info}")
    return x.reshape(nb + 1, n, f)
