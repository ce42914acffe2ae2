"""Modal analysis versus airspeed with mode tracking (Zhang (2006) section 6.1.2, fig. 6.2).

Each eigenvalue ``lambda`` of the system matrix gives a natural frequency ``|lambda|/(2 pi)``
[Hz] and a damping ratio ``-Re(lambda)/|lambda|``; a real eigenvalue has damping ratio +1
(decaying) or -1 (growing), so the *minimum damping ratio* over all eigenvalues is negative
exactly when the system is unstable. Modes are followed from one airspeed to the next by
matching eigenvalues to a linear prediction from the previous two airspeeds (optimal
assignment), and are labelled at the first airspeed by the degree of freedom that carries
most of their kinetic energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from aero_dva.wing.aerodynamics import TheodorsenAero
from aero_dva.wing.checks import real_array

__all__ = ["ModalResult", "damping_ratios", "min_damping_ratio", "modal_analysis",
           "track_modes"]

DOF_LABELS = ("translational", "rotational", "absorber")


def damping_ratios(eigenvalues: np.ndarray) -> np.ndarray:
    """Damping ratios ``-Re/|.|`` of eigenvalues (any shape); zero eigenvalues count as 0."""
    lam = np.asarray(eigenvalues)
    mag = np.abs(lam)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(mag > 0, -lam.real / np.where(mag > 0, mag, 1.0), 0.0)
    return z


def min_damping_ratio(a: np.ndarray) -> np.ndarray:
    """Minimum damping ratio over the eigenvalues of ``a`` (..., n, n) -> (...)."""
    return damping_ratios(np.linalg.eigvals(a)).min(axis=-1)


@dataclass(frozen=True)
class ModalResult:
    """Tracked modes versus airspeed.

    Attributes
    ----------
    airspeed : ndarray, shape (n_u,)
        [m/s]
    eigenvalues : ndarray, shape (n_modes, n_u), complex
        [rad/s] One oscillatory mode per row (the upper-half-plane member of each pair at the
        first airspeed), tracked across airspeeds.
    frequency : ndarray, shape (n_modes, n_u)
        Natural frequency ``|lambda| / (2 pi)`` [Hz].
    damping_ratio : ndarray, shape (n_modes, n_u)
        ``-Re(lambda)/|lambda|`` [1].
    labels : tuple of str
        Dominant degree of freedom of each mode at the first airspeed.
    min_damping_ratio : ndarray, shape (n_u,)
        Over *all* eigenvalues, including real ones (Maxwell element, aerodynamic lags).
    """

    airspeed: np.ndarray
    eigenvalues: np.ndarray
    frequency: np.ndarray
    damping_ratio: np.ndarray
    labels: tuple
    min_damping_ratio: np.ndarray


def track_modes(eigs: np.ndarray) -> np.ndarray:
    """Reorder eigenvalues (n_u, n) so that each column follows one branch.

    The position at step ``i`` is predicted linearly from steps ``i-1`` and ``i-2`` and the
    eigenvalues are assigned to predictions by minimum total distance.
    """
    eigs = np.asarray(eigs)
    out = eigs.copy()
    for i in range(1, len(out)):
        pred = out[i - 1] if i == 1 else 2 * out[i - 1] - out[i - 2]
        scale = np.maximum(np.abs(out[i - 1]), 1e-12)
        cost = np.abs(pred[:, None] - eigs[i][None, :]) / scale[:, None]
        rows, cols = linear_sum_assignment(cost)
        out[i, rows] = eigs[i][cols]
    return out


def _dof_energy(vectors: np.ndarray, model) -> np.ndarray:
    """Kinetic-energy share of each degree of freedom in each eigenvector (n_dof, n)."""
    n = model.n_dof
    mass = np.diag(model.mass_matrix)
    vel = vectors[n:2 * n, :]
    energy = mass[:, None] * np.abs(vel) ** 2
    return energy / np.maximum(energy.sum(axis=0, keepdims=True), 1e-300)


def modal_analysis(model, airspeeds, density: float, damping=None) -> ModalResult:
    """Natural frequencies and damping ratios versus airspeed (fig. 6.2, 6.21, 6.24).

    Parameters
    ----------
    model : AeroelasticModel
        Quasi-steady or finite-state aerodynamics.
    airspeeds : array_like, shape (n_u,)
        Increasing airspeeds [m/s], >= 0, closely enough spaced for tracking.
    density : float
        [kg/m^3]
    damping : float or array_like (n_u,), optional
        Tunable damper [N s/m] at each airspeed (e.g. a ``c2`` schedule).
    """
    if isinstance(model.aero, TheodorsenAero):
        raise ValueError("modal_analysis needs a time-domain aero model (quasi-steady, wagner)")
    u = real_array(airspeeds, "airspeeds")
    if u.ndim != 1 or u.size < 2 or np.any(np.diff(u) <= 0):
        raise ValueError("airspeeds must be a 1-D increasing array of at least 2 values")
    a, _ = model.matrices(u, density, damping)
    lam0, vec0 = np.linalg.eig(a[0])
    eigs = np.linalg.eigvals(a)
    eigs[0] = lam0
    tracked = track_modes(eigs)
    # Oscillatory branches: the upper member of each complex pair at the first airspeed.
    osc = np.flatnonzero(tracked[0].imag > 1e-9 * np.maximum(np.abs(tracked[0]), 1.0))
    energy = _dof_energy(vec0, model)
    order = osc[np.argsort(np.abs(tracked[0, osc]))]
    labels = tuple(DOF_LABELS[int(np.argmax(energy[:, j]))] for j in order)
    lam = tracked[:, order].T
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    return ModalResult(
        airspeed=u,
        eigenvalues=lam,
        frequency=np.abs(lam) / (2 * np.pi),
        damping_ratio=damping_ratios(lam),
        labels=labels,
        min_damping_ratio=damping_ratios(eigs).min(axis=1),
    )
