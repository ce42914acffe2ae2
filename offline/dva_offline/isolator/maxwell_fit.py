"""General Maxwell model identification by constrained optimisation (study section 4.3).

Eq. (4.11) fits the model FRF to a measured FRF over the 2n + 1 unknowns (c, k_i, c_i), with
m and k known, subject to eq. (4.12): the model's natural frequency and damping ratio equal the
measured ones. The study solves it by SQP; we use scipy's SLSQP with these choices:

* Parameters scaled to O(1): theta = (c / c_ref, ln(k_i / k_ref), ln(c_i / c_ref)) with
  k_ref = m w_n^2 and c_ref = m w_n. The logs keep k_i, c_i > 0; c may be negative, as in the
  study's Tables 5.5-5.6 (we flag it).
* Eq. (4.12) is imposed in the equivalent, smooth form D(lambda*) = 0, where
  lambda* = -zeta w_n + j w_n sqrt(1 - zeta^2) is the measured eigenvalue and
  D(s) = m s^2 + c s + k + sum k_i c_i s / (k_i + c_i s). After the fit we check with the
  eigenvalues of eq. (4.2) that lambda* is the model's complex pair.
* Objective: eq. (4.11) uses sum |H(kappa) - H_j|; the default here is the smooth sum of
  squares (``objective="l2"``), ``"l1"`` is the study's. Residuals are weighted by 1/|H_j|
  (``weighting="relative"``, the maximum-likelihood choice for the multiplicative noise of
  eq. 4.13) or by one global scale (``"none"``).
* Analytic gradients of the objective and constraints, vectorised over frequency.
* Initial guesses follow section 4.3.2: elements of different types (one Type B, one Type C
  first), and stiffnesses chosen so that each guess already has the measured w_n and zeta.
  Several such guesses are tried; the best objective wins and disagreement among near-best
  solutions is reported as non-uniqueness.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import null_space
from scipy.optimize import least_squares, minimize

from dva_offline.isolator.element_types import ElementType, classify_elements
from dva_offline.isolator.maxwell_model import (
    QUANTITIES,
    MaxwellModel,
    ModalProperties,
    frf,
    modal_properties,
    target_eigenvalue,
)


class FitWarning(UserWarning):
    """A fit converged but is non-unique or non-physical."""


@dataclass(frozen=True)
class MaxwellFit:
    """Result of a general Maxwell model identification.

    Attributes
    ----------
    model : MaxwellModel
        Identified model (m and k as given).
    modal : ModalProperties or None
        Modal properties of the identified model (None if it has no complex pair).
    element_types : tuple of ElementType
        Type A/B/C of each identified element.
    frf_error : float
        Relative RMS error ||H_model - H||_2 / ||H||_2 against the fitted data [-].
    objective : float
        Final value of the scaled objective.
    c_std : float
        Standard error of c [N s/m] (NaN if not available).
    maxwell_k_std, maxwell_c_std : tuple of float
        Standard errors of k_i [N/m] and c_i [N s/m].
    constraint_error : float
        max(|w_n - w_n*| / w_n*, |zeta - zeta*|) of the identified model [-] (NaN if the
        model has no complex pair).
    warnings : tuple of str
        Non-physical or non-unique findings.
    success : bool
        Optimiser success flag of the best start.
    n_starts : int
        Number of initial guesses tried.
    method : str
        ``"slsqp"`` (constrained, eq. 4.11-4.12) or ``"least_squares"`` (unconstrained).
    """

    model: MaxwellModel
    modal: ModalProperties | None
    element_types: tuple[ElementType, ...]
    frf_error: float
    objective: float
    c_std: float
    maxwell_k_std: tuple[float, ...]
    maxwell_c_std: tuple[float, ...]
    constraint_error: float
    warnings: tuple[str, ...]
    success: bool
    n_starts: int
    method: str


def add_frf_noise(h, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Simulated measurement H_j = H_j(kappa_0) (1 + alpha_j), alpha_j ~ N(0, sigma^2) (eq. 4.13).

    Parameters
    ----------
    h : array_like, shape (N,)
        Noise-free FRF (any quantity).
    sigma : float
        Standard deviation of the real factor alpha_j, >= 0.
    rng : numpy.random.Generator
        Source of randomness (``numpy.random.default_rng(seed)``).
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    if not sigma >= 0:
        raise ValueError(f"sigma must be >= 0, got {sigma}")
    h = np.asarray(h, dtype=complex)
    return h * (1.0 + sigma * rng.standard_normal(h.shape))


# --- vectorised model evaluation with derivatives -------------------------------------------

class _Problem:
    """FRF residuals and constraints in scaled parameters theta, with analytic derivatives."""

    def __init__(self, omega, h, mass, k, n, wn, zeta, quantity, weighting):
        self.omega = omega
        self.h = h
        self.mass = mass
        self.k = k
        self.n = n
        self.lam = target_eigenvalue(wn, zeta)
        self.k_ref = mass * wn**2
        self.c_ref = mass * wn
        self.quantity = quantity
        self.s = 1j * omega
        if weighting == "relative":
            mag = np.abs(h)
            if np.any(mag == 0):
                raise ValueError("h contains zeros; use weighting='none'")
            self.weight = 1.0 / mag
        else:
            self.weight = np.full(omega.shape, 1.0 / np.sqrt(np.mean(np.abs(h) ** 2)))
        self.d_scale = 1.0 / (mass * abs(self.lam) ** 2)

    def physical(self, theta):
        c = theta[0] * self.c_ref
        ks = self.k_ref * np.exp(theta[1 : 1 + self.n])
        cs = self.c_ref * np.exp(theta[1 + self.n :])
        return c, ks, cs

    def theta(self, c, ks, cs):
        return np.concatenate(
            [[c / self.c_ref], np.log(np.asarray(ks) / self.k_ref),
             np.log(np.asarray(cs) / self.c_ref)]
        )

    def _stiffness_and_grad(self, theta, s):
        """K(s) (without the mass term) and dK/dtheta, shapes (N,) and (p, N)."""
        c, ks, cs = self.physical(theta)
        ks_ = ks[:, None]
        cs_ = cs[:, None]
        den = ks_ + cs_ * s[None, :]
        stiff = self.k + c * s + (ks_ * cs_ * s / den).sum(axis=0)
        grad = np.empty((1 + 2 * self.n, s.size), dtype=complex)
        grad[0] = s * self.c_ref
        grad[1 : 1 + self.n] = ks_ * (cs_ * s) ** 2 / den**2
        grad[1 + self.n :] = cs_ * ks_**2 * s / den**2
        return stiff, grad

    def residual(self, theta):
        """Weighted complex residuals (N,) and their Jacobian (p, N)."""
        stiff, dstiff = self._stiffness_and_grad(theta, self.s)
        w2m = self.mass * self.omega**2
        e = stiff - w2m
        if self.quantity == "receptance":
            model = 1.0 / e
            dq = -(model**2)
        elif self.quantity == "accelerance":
            model = -(self.omega**2) / e
            dq = self.omega**2 / e**2
        elif self.quantity == "transmissibility":
            model = stiff / e
            dq = -w2m / e**2
        else:
            model = stiff
            dq = np.ones_like(stiff)
        r = self.weight * (model - self.h)
        return r, self.weight * dq * dstiff

    def constraint(self, theta):
        """Real and imaginary part of the scaled D(lambda*), shape (2,), and Jacobian (2, p)."""
        s = np.array([self.lam])
        stiff, dstiff = self._stiffness_and_grad(theta, s)
        d = (stiff[0] + self.mass * self.lam**2) * self.d_scale
        g = dstiff[:, 0] * self.d_scale
        return np.array([d.real, d.imag]), np.vstack([g.real, g.imag])


def _objective_fn(problem: _Problem, objective: str):
    n_pts = problem.omega.size

    def fun(theta):
        r, jac = problem.residual(theta)
        if objective == "l2":
            val = np.sum(np.abs(r) ** 2) / n_pts
            grad = 2.0 * np.real(jac @ np.conj(r)) / n_pts
        else:
            mag = np.sqrt(np.abs(r) ** 2 + 1e-30)
            val = np.sum(mag) / n_pts
            grad = np.real(jac @ (np.conj(r) / mag)) / n_pts
        return val, grad

    return fun


def initial_guesses(
    mass: float, k: float, n_elements: int, natural_frequency_rad_s: float, damping_ratio: float
) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Initial guesses (c, k_i, c_i) following the two rules of section 4.3.2.

    Rule 1: the elements get different types (w_n tau_i spread over Types A/B/C, with the
    B + C pattern first for n = 2). Rule 2: for each pattern of time constants the common
    stiffness scale s (k_i = s) and c are solved from D(lambda*) = 0, so every guess already has
    the measured w_n and zeta. Patterns giving s <= 0 are dropped.

    Returns
    -------
    list of (c [N s/m], k_i [N/m] shape (n,), c_i [N s/m] shape (n,))
    """
    if n_elements < 1:
        raise ValueError(f"n_elements must be >= 1, got {n_elements}")
    w = natural_frequency_rad_s
    lam = target_eigenvalue(w, damping_ratio)
    if n_elements == 1:
        patterns = [[1.0], [5.0], [0.3], [20.0]]
    elif n_elements == 2:
        patterns = [[1.0, 10.0], [0.3, 10.0], [1.0, 30.0], [0.5, 3.0], [0.2, 1.0]]
    else:
        patterns = [
            list(np.logspace(-0.5, 1.5, n_elements)),
            list(np.logspace(0.0, 1.5, n_elements)),
            list(np.logspace(-0.7, 1.0, n_elements)),
        ]
    guesses = []
    for pattern in patterns:
        tau = np.asarray(pattern) / w
        e = np.sum(tau * lam / (1.0 + tau * lam))
        rhs = -(mass * lam**2 + k)
        a = np.array([[lam.real, e.real], [lam.imag, e.imag]])
        c, s = np.linalg.solve(a, [rhs.real, rhs.imag])
        if s <= 0:
            continue
        ks = np.full(n_elements, s)
        guesses.append((float(c), ks, tau * ks))
    if not guesses:
        # Still start somewhere: stiffness to reach w_n, damping from zeta.
        s = max(mass * w**2 - k, 0.1 * k) / n_elements
        tau = np.logspace(0, 1, n_elements) / w
        guesses.append((2 * mass * damping_ratio * w, np.full(n_elements, s), tau * s))
    return guesses


def _validate(omega_rad_s, h, mass, k, n_elements, wn, zeta, quantity):
    omega = np.asarray(omega_rad_s, dtype=float)
    h = np.asarray(h, dtype=complex)
    if omega.ndim != 1 or h.shape != omega.shape:
        raise ValueError(
            f"omega_rad_s and h must be 1-D of equal length, got {omega.shape} and {h.shape}"
        )
    if not (np.all(np.isfinite(omega)) and np.all(np.isfinite(h))):
        raise ValueError("omega_rad_s and h must be finite (no NaN)")
    if not isinstance(n_elements, (int, np.integer)) or n_elements < 1:
        raise ValueError(f"n_elements must be an integer >= 1, got {n_elements!r}")
    if omega.size < 2 * n_elements + 2:
        raise ValueError(
            f"too few frequency points ({omega.size}) for {2 * n_elements + 1} unknowns"
        )
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")
    if not mass > 0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    if not k > 0:
        raise ValueError(f"k must be > 0 N/m, got {k}")
    target_eigenvalue(wn, zeta)  # validates w_n and zeta
    return omega, h


def _standard_errors(problem: _Problem, theta, with_constraints: bool):
    """Standard errors of (c, k_i, c_i) from the residual Jacobian (Gauss-Newton covariance).

    With the equality constraints the covariance is restricted to their null space:
    cov = s^2 Z (Z' J' J Z)^-1 Z', s^2 = SSR / (2N - dof).
    """
    r, jac_c = problem.residual(theta)
    jac = np.hstack([jac_c.real, jac_c.imag]).T  # (2N, p)
    res = np.concatenate([r.real, r.imag])
    p = theta.size
    z = null_space(problem.constraint(theta)[1]) if with_constraints else np.eye(p)
    dof = res.size - z.shape[1]
    if dof <= 0:
        return np.full(p, np.nan), np.inf
    jz = jac @ z
    info = jz.T @ jz
    cond = np.linalg.cond(info)
    s2 = float(res @ res) / dof
    cov = z @ np.linalg.pinv(info) @ z.T * s2
    se_theta = np.sqrt(np.clip(np.diag(cov), 0, None))
    c, ks, cs = problem.physical(theta)
    n = problem.n
    se = np.empty(p)
    se[0] = se_theta[0] * problem.c_ref
    se[1 : 1 + n] = se_theta[1 : 1 + n] * ks  # delta method on ln k_i
    se[1 + n :] = se_theta[1 + n :] * cs
    return se, cond


def _finish(problem, theta, objective_value, success, n_starts, method, notes, constrained):
    c, ks, cs = problem.physical(theta)
    model = MaxwellModel(problem.mass, problem.k, float(c), tuple(ks), tuple(cs))
    notes = list(notes)
    try:
        modal = modal_properties(model)
    except ValueError:
        modal = None
        notes.append("identified model has no complex eigenvalue pair (overdamped)")
    if modal is not None:
        wn_t = abs(problem.lam)
        zeta_t = -problem.lam.real / wn_t
        cons_err = max(
            abs(modal.natural_frequency_rad_s - wn_t) / wn_t, abs(modal.damping_ratio - zeta_t)
        )
        if not modal.is_stable:
            notes.append("identified model is unstable (an eigenvalue has Re >= 0)")
        types = classify_elements(model, modal.natural_frequency_rad_s)
    else:
        cons_err = np.nan
        types = ()
    if constrained and not cons_err <= 1e-6:
        notes.append(
            f"natural frequency / damping ratio constraints not met (error {cons_err:.2e}): "
            "the measured eigenvalue is not the model's complex pair"
        )
    if c < 0:
        notes.append(
            f"primary damping c = {c:.4g} N s/m is negative (the study allows it, Tables "
            "5.5-5.6, but the primary damper alone is then non-physical)"
        )
    bound = 9.0
    if np.any(np.abs(theta[1:]) > bound):
        notes.append("a Maxwell parameter reached the search bounds (element inactive or rigid)")
    se, cond = _standard_errors(problem, theta, constrained)
    if cond > 1e12:
        notes.append(
            f"parameters are poorly determined by the data (Fisher condition {cond:.1e}): "
            "the fit is not unique"
        )
    r, _ = problem.residual(theta)
    h_model = problem.h + r / problem.weight
    frf_err = float(np.linalg.norm(h_model - problem.h) / np.linalg.norm(problem.h))
    for note in notes:
        warnings.warn(note, FitWarning, stacklevel=3)
    n = problem.n
    return MaxwellFit(
        model=model,
        modal=modal,
        element_types=types,
        frf_error=frf_err,
        objective=float(objective_value),
        c_std=float(se[0]),
        maxwell_k_std=tuple(float(v) for v in se[1 : 1 + n]),
        maxwell_c_std=tuple(float(v) for v in se[1 + n :]),
        constraint_error=float(cons_err),
        warnings=tuple(notes),
        success=bool(success),
        n_starts=int(n_starts),
        method=method,
    )


def fit_maxwell_model(
    omega_rad_s,
    h,
    mass: float,
    k: float,
    n_elements: int,
    natural_frequency_rad_s: float,
    damping_ratio: float,
    quantity: str = "receptance",
    objective: str = "l2",
    weighting: str = "relative",
    initial: list | None = None,
    max_iter: int = 400,
) -> MaxwellFit:
    """Identify c, k_i, c_i of an n-element general Maxwell model (eq. 4.11-4.12, SQP).

    Parameters
    ----------
    omega_rad_s : array_like, shape (N,)
        Frequencies of the measured FRF [rad/s].
    h : array_like, shape (N,)
        Measured FRF (complex) of kind ``quantity``.
    mass : float
        Isolated mass m [kg] (weighed).
    k : float
        Primary stiffness [N/m] (static stiffness experiment).
    n_elements : int
        Number of Maxwell elements n >= 1.
    natural_frequency_rad_s, damping_ratio : float
        Measured w_n [rad/s] and zeta [-], imposed as equality constraints (eq. 4.12).
    quantity : str
        ``receptance`` (default), ``accelerance``, ``transmissibility`` or ``stiffness``.
    objective : {"l2", "l1"}
        Sum of squared (default) or absolute (eq. 4.11) weighted residuals.
    weighting : {"relative", "none"}
        Residual weights 1/|H_j| or one global scale.
    initial : list of (c, k_i, c_i), optional
        Initial guesses; default :func:`initial_guesses`.
    max_iter : int
        SLSQP iteration limit per start.

    Returns
    -------
    MaxwellFit
    """
    omega, h = _validate(
        omega_rad_s, h, mass, k, n_elements, natural_frequency_rad_s, damping_ratio, quantity
    )
    if objective not in ("l2", "l1"):
        raise ValueError(f"objective must be 'l2' or 'l1', got {objective!r}")
    if weighting not in ("relative", "none"):
        raise ValueError(f"weighting must be 'relative' or 'none', got {weighting!r}")
    problem = _Problem(
        omega, h, mass, k, n_elements, natural_frequency_rad_s, damping_ratio, quantity,
        weighting,
    )
    fun = _objective_fn(problem, objective)
    if initial is None:
        initial = initial_guesses(
            mass, k, n_elements, natural_frequency_rad_s, damping_ratio
        )
    bounds = [(-50.0, 50.0)] + [(-9.5, 9.5)] * (2 * n_elements)
    cons = {
        "type": "eq",
        "fun": lambda t: problem.constraint(t)[0],
        "jac": lambda t: problem.constraint(t)[1],
    }
    results = []
    for c0, ks0, cs0 in initial:
        theta0 = np.clip(problem.theta(c0, ks0, cs0), -9.0, 9.0)
        res = minimize(
            fun, theta0, jac=True, method="SLSQP", bounds=bounds, constraints=[cons],
            options={"maxiter": max_iter, "ftol": 1e-15},
        )
        feasible = np.max(np.abs(problem.constraint(res.x)[0])) < 1e-6
        results.append((not feasible, res.fun, res))
    results.sort(key=lambda item: (item[0], item[1]))
    best = results[0][2]
    notes = []
    # Non-uniqueness: other feasible starts reaching (almost) the same objective elsewhere.
    for infeasible, value, res in results[1:]:
        if infeasible or value > best.fun * 1.01 + 1e-14:
            continue
        c_b, k_b, cs_b = problem.physical(best.x)
        c_o, k_o, cs_o = problem.physical(res.x)
        order_b, order_o = np.argsort(cs_b / k_b), np.argsort(cs_o / k_o)
        diff = np.max(np.abs(np.log(k_o[order_o] / k_b[order_b])))
        diff = max(diff, np.max(np.abs(np.log(cs_o[order_o] / cs_b[order_b]))))
        if diff > 0.1:
            notes.append(
                "fit is not unique: another initial guess reaches the same FRF error with "
                f"parameters differing by up to {100 * (np.exp(diff) - 1):.0f} %"
            )
            break
    return _finish(problem, best.x, best.fun, best.success, len(initial), "slsqp", notes, True)


def fit_unconstrained_least_squares(
    omega_rad_s,
    h,
    mass: float,
    k: float,
    n_elements: int,
    natural_frequency_rad_s: float,
    damping_ratio: float,
    quantity: str = "receptance",
    weighting: str = "relative",
) -> MaxwellFit:
    """Baseline: plain ``scipy.optimize.least_squares`` on (c, k_i, c_i), no eq. (4.12).

    Physical parameters, finite-difference Jacobian, started from the first guess of
    :func:`initial_guesses` (w_n and zeta are used only for that guess and the scaling of the
    reported result). Used by ``bench/bench_isolator_fit.py`` for comparison.
    """
    omega, h = _validate(
        omega_rad_s, h, mass, k, n_elements, natural_frequency_rad_s, damping_ratio, quantity
    )
    problem = _Problem(
        omega, h, mass, k, n_elements, natural_frequency_rad_s, damping_ratio, quantity,
        weighting,
    )
    c0, ks0, cs0 = initial_guesses(mass, k, n_elements, natural_frequency_rad_s, damping_ratio)[0]
    n = n_elements

    def resid(x):
        model = MaxwellModel(mass, k, x[0], tuple(x[1 : 1 + n]), tuple(x[1 + n :]))
        r = problem.weight * (frf(model, omega, quantity) - h)
        return np.concatenate([r.real, r.imag])

    x0 = np.concatenate([[c0], ks0, cs0])
    lower = np.concatenate([[-np.inf], np.full(2 * n, 1e-9)])
    res = least_squares(resid, x0, bounds=(lower, np.inf), x_scale="jac")
    theta = problem.theta(res.x[0], res.x[1 : 1 + n], res.x[1 + n :])
    value = 2.0 * res.cost / omega.size
    return _finish(problem, theta, value, res.success, 1, "least_squares", [], False)
