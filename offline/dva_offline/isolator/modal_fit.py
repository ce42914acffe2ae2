"""Unconstrained maximum-likelihood fit and the natural frequency / damping ratio it implies.

The study (section 4.3) imposes a measured w_n and zeta as exact constraints; it does not say
where they come from. The half-power method assumes light damping and is biased for rubber
mounts (zeta = 0.1-0.45). Here w_n and zeta are the modal solution of an unconstrained fit of
the general Maxwell model to the whole FRF, which holds for any damping:

1. Starts by variable projection on the dynamic stiffness K(w) = 1/H + m w^2 (known m, k):
   for fixed time constants tau_i, K - k = j w c + sum k_i j w tau_i / (1 + j w tau_i) is
   linear in (c, k_i). A grid of tau combinations is solved in one batch of small linear
   systems (weights 1/|K - m w^2|, first-order equivalent to the relative weights of H).
2. The best starts are refined with ``scipy.optimize.least_squares`` on the weighted FRF
   residuals (H_model - H) / |H| (maximum likelihood for multiplicative noise, eq. 4.13),
   analytic Jacobian, log-parameters for k_i, c_i.
3. w_n and zeta come from the eigenvalues of eq. (4.2); their standard errors from the
   Gauss-Newton covariance by the delta method.
4. Order rule: n elements are kept only if the data need them. An element whose time
   constant equals another's (merged), whose stiffness is negligible or whose removal does not
   raise the residual significantly (F-test, nested models) is removed and the model refitted.
"""
from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from dva_offline.isolator.maxwell_fit import FitWarning, MaxwellFit, _finish, _Problem
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties

#: Two elements whose time constants differ by less than this (relative) are one element.
SAME_TAU = 0.05
#: An element with k_i below this fraction of m w_n^2 is negligible.
NEGLIGIBLE_K = 1e-4
#: Significance level of the F-tests (order rule and constraint check).
ALPHA = 0.01


@dataclass(frozen=True)
class ModalFit:
    """Unconstrained fit and the modal solution it implies.

    Attributes
    ----------
    fit : MaxwellFit
        The unconstrained fit (``method == "least_squares"``) of the selected order.
    natural_frequency_rad_s, damping_ratio : float
        w_n [rad/s] and zeta [-] of the fitted model's complex eigenvalue pair.
    natural_frequency_std, damping_ratio_std : float
        Their standard errors (delta method) [rad/s], [-].
    ssr : float
        Sum of squared weighted residuals sum |(H_model - H) / |H||^2 [-].
    dof : int
        Residual degrees of freedom 2 N - (2 n + 1).
    requested_elements : int
        Number of elements asked for (the upper limit of the order rule).
    orders : tuple of int
        Orders fitted, ascending.
    order_frf_errors : tuple of float
        Relative FRF error of each fitted order [-].
    order_p_values : tuple of float
        p-value of the F-test "order n - 1 fits as well as order n" for each order (NaN for
        the lowest).
    reductions : tuple of str
        Why elements were merged or dropped (empty if none).
    """

    fit: MaxwellFit
    natural_frequency_rad_s: float
    damping_ratio: float
    natural_frequency_std: float
    damping_ratio_std: float
    ssr: float
    dof: int
    requested_elements: int
    orders: tuple[int, ...]
    order_frf_errors: tuple[float, ...]
    order_p_values: tuple[float, ...]
    reductions: tuple[str, ...]


def isolator_stiffness(omega, h, mass: float, quantity: str):
    """Dynamic stiffness of the mount K(w) [N/m] and its residual weights from an FRF.

    Returns K and 1/|K - m w^2| (1/|K| for ``stiffness`` data), so that weighted residuals of
    K have the scale of the relative residuals of H.
    """
    w2m = mass * omega**2
    if quantity == "receptance":
        z = 1.0 / h
    elif quantity == "accelerance":
        z = -(omega**2) / h
    elif quantity == "stiffness":
        return h, 1.0 / np.abs(h)
    else:  # transmissibility T = K / (K - m w^2)
        z = w2m / (h - 1.0)
    return z + w2m, 1.0 / np.abs(z)


def sort_elements(fit: MaxwellFit) -> MaxwellFit:
    """The same fit with its elements in ascending time constant (a unique report order)."""
    model = fit.model
    order = np.argsort(model.time_constants, kind="stable")
    if model.n_elements < 2 or np.all(order == np.arange(model.n_elements)):
        return fit

    def pick(seq):
        # element_types is empty when the model has no complex pair (nothing to classify).
        return tuple(seq[i] for i in order) if len(seq) == order.size else tuple(seq)

    return replace(
        fit, model=model.with_elements(pick(model.maxwell_k), pick(model.maxwell_c)),
        element_types=pick(fit.element_types), maxwell_k_std=pick(fit.maxwell_k_std),
        maxwell_c_std=pick(fit.maxwell_c_std),
    )


def _tau_grid(omega, n: int) -> np.ndarray:
    """Log grid of time constants over the band the data can resolve [s]."""
    w = omega[omega > 0]
    size = {1: 121, 2: 48, 3: 24}.get(n, 14)
    return np.logspace(np.log10(0.1 / w.max()), np.log10(10.0 / w.min()), size)


def variable_projection_starts(omega, h, mass, k, n, quantity="receptance", keep=3):
    """Initial guesses (c, k_i, c_i) from a grid search over the time constants.

    For each combination of n grid time constants the weighted linear least-squares problem
    in (c, k_1..k_n) is solved (one batch of (n+1) x (n+1) normal equations); combinations
    with all k_i > 0 are ranked by residual and the best ``keep`` returned.
    """
    use = omega > 0
    w, hh = omega[use], h[use]
    stiff, weight = isolator_stiffness(w, hh, mass, quantity)
    taus = _tau_grid(w, n)
    s = 1j * w
    cols = np.vstack([s[None, :], (s * taus[:, None]) / (1.0 + s * taus[:, None])])
    cols = cols * weight
    a = np.hstack([cols.real, cols.imag])  # (T + 1, 2M)
    b_c = (stiff - k) * weight
    b = np.concatenate([b_c.real, b_c.imag])
    # Scale the columns so that the normal equations are well conditioned.
    scale = np.linalg.norm(a, axis=1)
    a = a / scale[:, None]
    gram = a @ a.T
    rhs = a @ b
    combos = np.array(list(itertools.combinations(range(taus.size), n)))
    sub = np.hstack([np.zeros((combos.shape[0], 1), dtype=int), 1 + combos])
    mat = gram[sub[:, :, None], sub[:, None, :]]
    mat = mat + 1e-12 * np.eye(n + 1)
    vec = rhs[sub]
    x = np.linalg.solve(mat, vec[..., None])[..., 0]
    ssr = b @ b - np.sum(x * vec, axis=1)
    x = x / scale[sub]
    valid = np.all(x[:, 1:] > 0, axis=1)
    order = np.argsort(np.where(valid, ssr, np.inf))
    starts = []
    for i in order[:keep]:
        if not valid[i]:
            break
        ks = x[i, 1:]
        starts.append((float(x[i, 0]), ks, ks * taus[combos[i]]))
    return starts


def _stack(problem: _Problem, theta):
    r, jac = problem.residual(theta)
    return np.concatenate([r.real, r.imag]), np.vstack([jac.real.T, jac.imag.T])


def weighted_ssr(model: MaxwellModel, omega, h, quantity="receptance") -> float:
    """Sum of squared relative residuals sum |(H_model - H) / H|^2 [-]."""
    return float(np.sum(np.abs((frf(model, omega, quantity) - h) / h) ** 2))


def fit_unconstrained(omega, h, mass, k, n, quantity="receptance", starts=None) -> MaxwellFit:
    """Unconstrained weighted least-squares fit of an n-element model (see module docstring).

    Parameters
    ----------
    omega, h : numpy.ndarray, shape (N,)
        Frequencies [rad/s] and measured FRF of kind ``quantity``.
    mass, k : float
        Mass [kg] and static stiffness [N/m], fixed.
    n : int
        Number of Maxwell elements.
    starts : list of (c, k_i, c_i), optional
        Extra initial guesses, tried besides the variable-projection ones.
    """
    guesses = variable_projection_starts(omega, h, mass, k, n, quantity) + list(starts or [])
    if not guesses:
        wr = np.sqrt(k / mass)
        guesses = [(0.1 * mass * wr, np.full(n, 0.5 * k), np.full(n, 0.5 * k) *
                    np.logspace(-0.5, 0.5, n) / wr)]
    wr = np.sqrt((k + np.sum(guesses[0][1])) / mass)
    problem = _Problem(omega, h, mass, k, n, wr, 0.1, quantity, "relative")
    lower = np.r_[-50.0, np.full(2 * n, -9.5)]
    upper = -lower
    best = None
    for c0, ks0, cs0 in guesses:
        theta0 = np.clip(problem.theta(c0, ks0, cs0), lower + 0.5, upper - 0.5)
        res = least_squares(lambda t: _stack(problem, t)[0], theta0,
                            jac=lambda t: _stack(problem, t)[1], bounds=(lower, upper),
                            method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=400)
        if best is None or res.cost < best.cost:
            best = res
    value = 2.0 * best.cost / omega.size
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        fit = _finish(problem, best.x, value, best.success, len(guesses), "least_squares", [],
                      False)
    return sort_elements(replace(fit, constraint_error=float("nan")))


def modal_standard_errors(fit: MaxwellFit, omega, h, quantity="receptance"):
    """w_n, zeta of a fit and their standard errors by the delta method.

    Covariance of theta = (c, ln k_i, ln c_i): s^2 (J'J)^+, s^2 = SSR / (2N - p); gradient
    of (w_n, zeta) by central differences of the eigenvalues of eq. (4.2).

    Returns
    -------
    (w_n, zeta, std w_n, std zeta)
    """
    model = fit.model
    n = model.n_elements
    modal = modal_properties(model)
    x0 = np.r_[model.c, np.log(model.maxwell_k), np.log(model.maxwell_c)]

    def wz(x):
        m = MaxwellModel(model.mass, model.k, x[0], tuple(np.exp(x[1:1 + n])),
                         tuple(np.exp(x[1 + n:])))
        p = modal_properties(m)
        return np.array([p.natural_frequency_rad_s, p.damping_ratio])

    def resid(x):
        m = MaxwellModel(model.mass, model.k, x[0], tuple(np.exp(x[1:1 + n])),
                         tuple(np.exp(x[1 + n:])))
        r = (frf(m, omega, quantity) - h) / np.abs(h)
        return np.concatenate([r.real, r.imag])

    steps = np.r_[max(abs(model.c), 1e-3 * modal.natural_frequency_rad_s * model.mass) * 1e-6,
                  np.full(2 * n, 1e-6)]
    jac = np.empty((2 * omega.size, x0.size))
    grad = np.empty((2, x0.size))
    for i, step in enumerate(steps):
        e = np.zeros_like(x0)
        e[i] = step
        jac[:, i] = (resid(x0 + e) - resid(x0 - e)) / (2 * step)
        grad[:, i] = (wz(x0 + e) - wz(x0 - e)) / (2 * step)
    r0 = resid(x0)
    dof = r0.size - x0.size
    s2 = float(r0 @ r0) / dof
    cov = np.linalg.pinv(jac.T @ jac) * s2
    var = np.einsum("ij,jk,ik->i", grad, cov, grad)
    std = np.sqrt(np.clip(var, 0, None))
    return modal.natural_frequency_rad_s, modal.damping_ratio, float(std[0]), float(std[1])


def f_test(ssr_small: float, ssr_big: float, extra: int, dof_big: int) -> tuple[float, float]:
    """F statistic and p-value that the smaller (nested or constrained) model fits as well.

    F = ((SSR_small - SSR_big) / extra) / (SSR_big / dof_big). An exact fit of the smaller
    model (noise-free data) gives F = 0, p = 1.
    """
    if ssr_small <= ssr_big * (1 + 1e-9) or ssr_small < 1e-20 * max(dof_big, 1):
        return 0.0, 1.0
    if ssr_big <= 0:
        return float("inf"), 0.0
    f = ((ssr_small - ssr_big) / extra) / (ssr_big / dof_big)
    return float(f), float(stats.f.sf(f, extra, dof_big))


def degenerate_elements(model: MaxwellModel, natural_frequency_rad_s: float):
    """Reasons why elements of ``model`` are not separate elements.

    Returns
    -------
    list of (index, reason, "merge" or "drop", partner index or None)
    """
    out = []
    tau = model.time_constants
    k_ref = model.mass * natural_frequency_rad_s**2
    for i, ki in enumerate(model.maxwell_k):
        if ki < NEGLIGIBLE_K * k_ref:
            out.append((i, f"negligible stiffness k = {ki:.3g} N/m "
                           f"(< {NEGLIGIBLE_K:g} m w_n^2)", "drop", None))
    for i, j in itertools.combinations(range(model.n_elements), 2):
        if abs(np.log(tau[i] / tau[j])) < SAME_TAU:
            out.append((j, f"same time constant as element {i + 1} "
                           f"({1e3 * tau[i]:.4g} vs {1e3 * tau[j]:.4g} ms)", "merge", i))
    return out


def fit_modal(omega, h, mass: float, k: float, n_elements: int, quantity="receptance",
              alpha: float = ALPHA) -> ModalFit:
    """Unconstrained fit with the order rule, and w_n, zeta with standard errors.

    Parameters
    ----------
    omega, h : array_like, shape (N,)
        Frequencies [rad/s] and measured FRF of kind ``quantity``.
    mass, k : float
        Mass [kg] and static stiffness [N/m].
    n_elements : int
        Largest number of Maxwell elements (>= 1).
    alpha : float
        Significance level of the order rule's F-test.

    Raises
    ------
    ValueError
        If no fitted order has a complex eigenvalue pair (overdamped mass mode).
    """
    omega = np.asarray(omega, dtype=float)
    h = np.asarray(h, dtype=complex)
    if not isinstance(n_elements, (int, np.integer)) or n_elements < 1:
        raise ValueError(f"n_elements must be an integer >= 1, got {n_elements!r}")
    if omega.size < 2 * n_elements + 3:
        raise ValueError(f"too few frequency points ({omega.size}) for {n_elements} elements")
    fits = {}
    for n in range(1, n_elements + 1):
        extra = []
        if n > 1:
            prev = fits[n - 1].model
            # Lower-order solution plus a weak element: a start next to the nested model.
            for tau in (0.3, 3.0):
                wn = np.sqrt((k + sum(prev.maxwell_k)) / mass)
                extra.append((prev.c, np.r_[prev.maxwell_k, 0.05 * k],
                              np.r_[prev.maxwell_c, 0.05 * k * tau / wn]))
        fits[n] = fit_unconstrained(omega, h, mass, k, n, quantity, extra)
    ssr = {n: weighted_ssr(f.model, omega, h, quantity) for n, f in fits.items()}
    dof = {n: 2 * omega.size - (2 * n + 1) for n in fits}
    p_values = {1: float("nan")}
    for n in range(2, n_elements + 1):
        p_values[n] = f_test(ssr[n - 1], ssr[n], 2, dof[n])[1]
    reductions = []
    n = n_elements
    while n > 1:
        model = fits[n].model
        try:
            wn = modal_properties(model).natural_frequency_rad_s
        except ValueError:
            wn = np.sqrt((k + sum(model.maxwell_k)) / mass)
        degenerate = degenerate_elements(model, wn)
        if degenerate:
            i, reason, action, _ = degenerate[0]
            word = "merged into element " + str(degenerate[0][3] + 1) if action == "merge" \
                else "dropped"
            reductions.append(f"element {i + 1} of {n} {word}: {reason}")
        elif p_values[n] > alpha:
            reductions.append(
                f"element {n} of {n} dropped: {n} elements fit no better than {n - 1} "
                f"(F-test p = {p_values[n]:.2g} > {alpha:g})")
        else:
            break
        n -= 1
    fit = fits[n]
    try:
        wn, zeta, wn_std, zeta_std = modal_standard_errors(fit, omega, h, quantity)
    except ValueError:
        raise ValueError(
            "the fitted model has no complex eigenvalue pair (overdamped mass mode): natural "
            "frequency and damping ratio are undefined"
        ) from None
    orders = tuple(range(1, n_elements + 1))
    return ModalFit(
        fit=fit, natural_frequency_rad_s=wn, damping_ratio=zeta, natural_frequency_std=wn_std,
        damping_ratio_std=zeta_std, ssr=ssr[n], dof=dof[n], requested_elements=n_elements,
        orders=orders, order_frf_errors=tuple(fits[o].frf_error for o in orders),
        order_p_values=tuple(p_values[o] for o in orders), reductions=tuple(reductions),
    )
