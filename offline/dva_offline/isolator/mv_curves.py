"""Maxwell-Voigt identification by constant-frequency / constant-damping curves (section 3.4).

The study draws curves of constant w_mv (Fig. 3.5) and constant zeta_mv (Fig. 3.8) in the
(k_1, c_1) plane and reads their intersection for each trial primary damper c. The
intersection has a closed form: lambda = -zeta w + j w sqrt(1 - zeta^2) is a root of

    D(s) = m s^2 + c s + k + k_1 c_1 s / (k_1 + c_1 s) = 0.

With P = m lambda^2 + c lambda + k and dividing by k_1 c_1 this is *linear* in (1/c_1, 1/k_1):

    P / c_1 + P lambda / k_1 = -lambda,

one complex equation = two real equations, so for each c there is exactly one intersection
(k_1, c_1); it is physical when both are positive. Sweeping c gives the study's family of
solutions (Tables 3.5-3.7), bounded by Voigt Model K (c -> -inf) and Voigt Model M (k_1 -> 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from dva_offline.isolator.maxwell_model import (
    MaxwellModel,
    frf,
    target_eigenvalue,
)


@dataclass(frozen=True)
class MvSolution:
    """One member of the M-V family with a prescribed w_n and zeta.

    Attributes
    ----------
    c : float
        Primary damping [N s/m] (the free parameter of the family).
    k1 : float
        Maxwell spring [N/m] (may be <= 0 when ``physical`` is False).
    c1 : float
        Maxwell damper [N s/m].
    physical : bool
        True when k1 > 0 and c1 > 0.
    sensitivity : float
        Largest |d ln(k1 or c1) / d ln(w_n or zeta)| [-]: how many percent the solution moves
        per percent error in the measured w_n or zeta. Large values mean ill-conditioned.
    """

    c: float
    k1: float
    c1: float
    physical: bool
    sensitivity: float

    def model(self, mass: float, k: float) -> MaxwellModel:
        """The M-V model of this solution (needs ``physical``)."""
        if not self.physical:
            raise ValueError(f"no physical M-V model for c = {self.c} N s/m (k1 or c1 <= 0)")
        return MaxwellModel(mass, k, self.c, (self.k1,), (self.c1,))


def _solve(mass, k, c, w, z):
    lam = target_eigenvalue(w, z)
    p = mass * lam**2 + c * lam + k
    a = np.array([[p.real, (p * lam).real], [p.imag, (p * lam).imag]])
    u, v = np.linalg.solve(a, [-lam.real, -lam.imag])  # u = 1/c1, v = 1/k1
    return 1.0 / v, 1.0 / u


def solve_mv_element(
    mass: float, k: float, c: float, natural_frequency_rad_s: float, damping_ratio: float
) -> MvSolution:
    """Maxwell element (k_1, c_1) giving the M-V model the target w_n and zeta for a given c.

    Parameters
    ----------
    mass : float
        [kg]
    k : float
        Primary (static) stiffness [N/m].
    c : float
        Trial primary damping [N s/m].
    natural_frequency_rad_s, damping_ratio : float
        Target modal properties (measured), w_n [rad/s] and zeta [-].

    Returns
    -------
    MvSolution
    """
    if not mass > 0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    if not k > 0:
        raise ValueError(f"k must be > 0 N/m, got {k}")
    if not np.isfinite(c):
        raise ValueError(f"c must be finite, got {c}")
    w, z = natural_frequency_rad_s, damping_ratio
    with np.errstate(divide="ignore"):
        k1, c1 = _solve(mass, k, c, w, z)
    physical = bool(np.isfinite(k1) and np.isfinite(c1) and k1 > 0 and c1 > 0)
    sens = np.inf
    if physical:
        h = 1e-6
        rows = []
        for dw, dz in ((h, 0.0), (0.0, h)):
            kp, cp = _solve(mass, k, c, w * (1 + dw), z * (1 + dz))
            km, cm = _solve(mass, k, c, w * (1 - dw), z * (1 - dz))
            with np.errstate(invalid="ignore"):
                rows.append(
                    [np.log(kp / km) / (2 * h) if kp * km > 0 else np.inf,
                     np.log(cp / cm) / (2 * h) if cp * cm > 0 else np.inf]
                )
        sens = float(np.max(np.abs(rows)))
    return MvSolution(float(c), float(k1), float(c1), physical, sens)


def mv_family(
    mass: float, k: float, natural_frequency_rad_s: float, damping_ratio: float, c_values
) -> tuple[MvSolution, ...]:
    """The family of M-V solutions over the primary damper c (Tables 3.5-3.7, Figs. 3.14-3.16).

    ``c_values`` is array_like of shape (M,) [N s/m]; returns M solutions (check ``physical``).
    """
    c_values = np.atleast_1d(np.asarray(c_values, dtype=float))
    return tuple(
        solve_mv_element(mass, k, c, natural_frequency_rad_s, damping_ratio) for c in c_values
    )


def max_primary_damping(
    mass: float, k: float, natural_frequency_rad_s: float, damping_ratio: float
) -> float:
    """Largest c with a physical M-V solution [N s/m] (the Voigt Model M limit, section 3.4).

    Found by bisection on ``physical`` between c = 0 and the first non-physical c.
    """
    def ok(c):
        return solve_mv_element(mass, k, c, natural_frequency_rad_s, damping_ratio).physical

    lo = -1.0
    while not ok(lo):
        lo *= 2.0
        if lo < -1e9:
            raise ValueError("no physical M-V solution for any primary damping c")
    hi = abs(lo) + 1.0
    while ok(hi):
        hi *= 2.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def modal_pairs(mass: float, k: float, c: float, k1, c1):
    """w_mv [rad/s] and zeta_mv of M-V models with paired (k_1, c_1) (vectorised eq. 3.2).

    Parameters
    ----------
    k1, c1 : array_like, same shape S
        Maxwell stiffness [N/m] and damping [N s/m], > 0.

    Returns
    -------
    omega_rad_s, zeta : numpy.ndarray
        Shape S each; NaN where the mass mode is overdamped.
    """
    kk, cc = np.broadcast_arrays(np.asarray(k1, dtype=float), np.asarray(c1, dtype=float))
    if np.any(kk <= 0) or np.any(cc <= 0):
        raise ValueError("k1 and c1 must be > 0")
    a = np.zeros(kk.shape + (3, 3))
    a[..., 0, 0] = -c / mass
    a[..., 0, 1] = -(k + kk) / mass
    a[..., 0, 2] = kk / mass
    a[..., 1, 0] = 1.0
    a[..., 2, 1] = kk / cc
    a[..., 2, 2] = -kk / cc
    eig = np.linalg.eigvals(a)
    idx = np.argmax(eig.imag, axis=-1)
    lam = np.take_along_axis(eig, idx[..., None], axis=-1)[..., 0]
    under = lam.imag > 1e-9 * np.abs(lam)
    omega = np.where(under, np.abs(lam), np.nan)
    zeta = np.where(under, -lam.real / np.abs(lam), np.nan)
    return omega, zeta


def modal_grid(mass: float, k: float, c: float, k1_values, c1_values):
    """w_mv [rad/s] and zeta_mv on a (k_1, c_1) grid, for the curves of Figs. 3.5 and 3.8.

    Parameters
    ----------
    k1_values : array_like, shape (P,)
        [N/m], > 0.
    c1_values : array_like, shape (Q,)
        [N s/m], > 0.

    Returns
    -------
    omega_rad_s, zeta : numpy.ndarray
        Shape (Q, P) each (rows follow c1, columns follow k1); NaN where overdamped.
    """
    k1 = np.asarray(k1_values, dtype=float)
    c1 = np.asarray(c1_values, dtype=float)
    if k1.ndim != 1 or c1.ndim != 1:
        raise ValueError("k1_values and c1_values must be 1-D arrays")
    kk, cc = np.meshgrid(k1, c1)
    return modal_pairs(mass, k, c, kk, cc)


def frf_error(h_model, h_ref) -> float:
    """Relative RMS FRF error ||H_model - H_ref||_2 / ||H_ref||_2 [-]."""
    h_model = np.asarray(h_model)
    h_ref = np.asarray(h_ref)
    if h_model.shape != h_ref.shape:
        raise ValueError(f"shape mismatch {h_model.shape} vs {h_ref.shape}")
    return float(np.linalg.norm(h_model - h_ref) / np.linalg.norm(h_ref))


def select_primary_damping(
    omega_rad_s,
    h_measured,
    mass: float,
    k: float,
    natural_frequency_rad_s: float,
    damping_ratio: float,
    quantity: str = "receptance",
    c_min: float | None = None,
) -> MvSolution:
    """Pick the member of the M-V family whose FRF is closest to the measured one (Table 4.2).

    The last step of section 3.4: among all (c, k_1(c), c_1(c)) with the measured w_n and zeta,
    choose c minimising the relative RMS FRF error. Bounded scalar search on
    [c_min, max_primary_damping]; ``c_min`` defaults to -10 * (2 m zeta w_n).
    """
    omega = np.asarray(omega_rad_s, dtype=float)
    h_measured = np.asarray(h_measured, dtype=complex)
    if omega.shape != h_measured.shape or omega.ndim != 1:
        raise ValueError("omega_rad_s and h_measured must be 1-D arrays of the same shape")
    w, z = natural_frequency_rad_s, damping_ratio
    c_max = max_primary_damping(mass, k, w, z)
    if c_min is None:
        c_min = -10.0 * 2.0 * mass * z * w

    def cost(c):
        sol = solve_mv_element(mass, k, c, w, z)
        if not sol.physical:
            return np.inf
        return frf_error(frf(sol.model(mass, k), omega, quantity), h_measured)

    # Coarse scan first: the error is not unimodal over the whole family in general.
    grid = np.linspace(c_min, c_max * (1 - 1e-9), 81)
    costs = np.array([cost(c) for c in grid])
    i = int(np.argmin(costs))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
    best = res.x if res.fun <= costs[i] else grid[i]
    return solve_mv_element(mass, k, float(best), w, z)
