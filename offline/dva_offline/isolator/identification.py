"""Isolator identification: w_n and zeta from the data, imposed constraints checked against it.

Pipeline of ``dva isolator identify``:

1. :func:`~dva_offline.isolator.modal_fit.fit_modal`: unconstrained fit of up to n Maxwell
   elements (order rule: degenerate elements merged or dropped), giving w_n and zeta with
   standard errors. This holds for heavy damping, unlike the half-power method.
2. Targets: by default that modal solution; ``modal_estimate="half-power"`` uses the zero
   crossing of Re(H) and the half-power points (Table 5.2), with a warning when zeta > 0.1
   where their bias is large. User-given values are imposed exactly.
3. When the targets are the fit's own modal solution the constrained fit of eq. (4.11-4.12) is
   the unconstrained fit. Otherwise the constrained fit (SLSQP, section 4.3) is run and checked
   against the data: an F-test compares the two fits (2 constraints), and z-scores
   (target - estimate) / standard error name the constraint(s) that the data contradict.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from dva_offline.isolator.frf_data import estimate_modal
from dva_offline.isolator.maxwell_fit import FitWarning, MaxwellFit, fit_maxwell_model
from dva_offline.isolator.maxwell_model import modal_properties
from dva_offline.isolator.modal_fit import (
    ALPHA,
    ModalFit,
    degenerate_elements,
    f_test,
    fit_modal,
    sort_elements,
    weighted_ssr,
)

#: Half-power damping ratios above this are flagged as biased.
HALF_POWER_LIMIT = 0.1
#: |z| above this names a constraint as contradicted by the data.
Z_LIMIT = 3.0


@dataclass(frozen=True)
class ConstraintCheck:
    """Imposed w_n / zeta against the unconstrained fit.

    Attributes
    ----------
    f_statistic, p_value : float
        F-test of the 2 constraints: ((SSR_c - SSR_u) / 2) / (SSR_u / dof_u).
    dof : int
        Residual degrees of freedom of the unconstrained fit.
    frf_error_constrained, frf_error_unconstrained : float
        Relative FRF errors of the two fits [-].
    z_natural_frequency, z_damping_ratio : float
        (target - estimate) / standard error of the estimate.
    rejected : bool
        True when p < alpha: imposing the constraints costs more than the noise explains.
    named : tuple of str
        Constraints the data contradict (``"natural_frequency"``, ``"damping_ratio"``).
    message : str
        One sentence for the report (empty when not rejected).
    """

    f_statistic: float
    p_value: float
    dof: int
    frf_error_constrained: float
    frf_error_unconstrained: float
    z_natural_frequency: float
    z_damping_ratio: float
    rejected: bool
    named: tuple[str, ...]
    message: str


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`.

    Attributes
    ----------
    fit : MaxwellFit
        The reported fit: constrained to the targets (eq. 4.12).
    modal_fit : ModalFit
        Unconstrained fit, its w_n / zeta with standard errors, and the order rule's record.
    target_natural_frequency_rad_s, target_damping_ratio : float
        Imposed w_n [rad/s] and zeta [-].
    target_sources : tuple of str
        Source of (w_n, zeta): ``"fit"``, ``"half-power"`` (w_n: zero crossing) or ``"given"``.
    constraint_check : ConstraintCheck or None
        None when the targets are the unconstrained fit's own modal solution.
    reductions : tuple of str
        Elements merged or dropped (order rule), unconstrained and constrained.
    warnings : tuple of str
        Everything the user should know (fit warnings, biased half-power, rejected constraints,
        resonance outside the data).
    """

    fit: MaxwellFit
    modal_fit: ModalFit
    target_natural_frequency_rad_s: float
    target_damping_ratio: float
    target_sources: tuple[str, str]
    constraint_check: ConstraintCheck | None
    reductions: tuple[str, ...]
    warnings: tuple[str, ...]

    @property
    def unconstrained(self) -> MaxwellFit:
        """The unconstrained fit."""
        return self.modal_fit.fit


def _receptance(omega, h, mass, quantity):
    if quantity == "receptance":
        return omega, h
    if quantity == "accelerance":
        keep = omega > 0
        return omega[keep], h[keep] / -(omega[keep] ** 2)
    if quantity == "stiffness":
        return omega, 1.0 / (h - mass * omega**2)
    raise ValueError("the half-power estimate needs receptance, accelerance or stiffness data")


def check_constraints(constrained: MaxwellFit, modal: ModalFit, omega, h, wn_target,
                      zeta_target, quantity="receptance", alpha=ALPHA) -> ConstraintCheck:
    """F-test of the imposed w_n, zeta against the unconstrained fit, and which one fails."""
    ssr_c = weighted_ssr(constrained.model, omega, h, quantity)
    f_stat, p = f_test(ssr_c, modal.ssr, 2, modal.dof)
    with np.errstate(divide="ignore", invalid="ignore"):  # exact data: zero standard errors
        z_w = np.float64(wn_target - modal.natural_frequency_rad_s) / modal.natural_frequency_std
        z_z = np.float64(zeta_target - modal.damping_ratio) / modal.damping_ratio_std
    rejected = p < alpha
    named: tuple[str, ...] = ()
    message = ""
    if rejected:
        zs = {"natural_frequency": z_w, "damping_ratio": z_z}
        named = tuple(n for n, z in zs.items() if abs(z) > Z_LIMIT) or (
            max(zs, key=lambda n: abs(zs[n])),)
        text = {
            "natural_frequency": (f"natural frequency {wn_target:.6g} rad/s (data: "
                                  f"{modal.natural_frequency_rad_s:.6g} +- "
                                  f"{modal.natural_frequency_std:.2g}, z = {z_w:.3g})"),
            "damping_ratio": (f"damping ratio {zeta_target:.4g} (data: {modal.damping_ratio:.4g}"
                              f" +- {modal.damping_ratio_std:.2g}, z = {z_z:.3g})"),
        }
        message = (
            "the data contradict the imposed " + " and ".join(text[n] for n in named)
            + f": imposing the constraints raises the FRF error from {modal.fit.frf_error:.4g} to "
            f"{constrained.frf_error:.4g} (F = {f_stat:.3g} on 2 and {modal.dof} dof, "
            f"p = {p:.2g} < {alpha:g})"
        )
    return ConstraintCheck(
        f_statistic=f_stat, p_value=p, dof=modal.dof,
        frf_error_constrained=constrained.frf_error,
        frf_error_unconstrained=modal.fit.frf_error, z_natural_frequency=float(z_w),
        z_damping_ratio=float(z_z), rejected=rejected, named=named, message=message,
    )


def _constrained(omega, h, mass, k, n, wn, zeta, quantity, start, fit_kwargs):
    from dva_offline.isolator.maxwell_fit import initial_guesses

    guesses = initial_guesses(mass, k, n, wn, zeta)
    if start is not None:
        guesses = [start, *guesses]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        return sort_elements(fit_maxwell_model(omega, h, mass, k, n, wn, zeta,
                                               quantity=quantity, initial=guesses, **fit_kwargs))


def identify(
    omega_rad_s,
    h,
    mass: float,
    k: float,
    n_elements: int = 2,
    natural_frequency_rad_s: float | None = None,
    damping_ratio: float | None = None,
    modal_estimate: str = "fit",
    quantity: str = "receptance",
    alpha: float = ALPHA,
    **fit_kwargs,
) -> Identification:
    """Identify a general Maxwell model with w_n and zeta estimated from or checked on the data.

    Parameters
    ----------
    omega_rad_s, h : array_like, shape (N,)
        Frequencies [rad/s] and measured FRF of kind ``quantity``.
    mass, k : float
        Mass [kg] and static stiffness [N/m].
    n_elements : int
        Largest number of Maxwell elements; the order rule may use fewer.
    natural_frequency_rad_s, damping_ratio : float, optional
        Values to impose exactly (eq. 4.12); a missing one is estimated.
    modal_estimate : {"fit", "half-power"}
        How a missing value is estimated: modal solution of the unconstrained fit, or zero
        crossing of Re(H) / half-power points (Table 5.2, light damping only).
    alpha : float
        Significance level of the F-tests.
    **fit_kwargs
        ``objective`` / ``weighting`` of the constrained fit (:func:`fit_maxwell_model`).
    """
    if modal_estimate not in ("fit", "half-power"):
        raise ValueError(f"modal_estimate must be 'fit' or 'half-power', got {modal_estimate!r}")
    omega = np.asarray(omega_rad_s, dtype=float)
    h = np.asarray(h, dtype=complex)
    if omega.ndim != 1 or h.shape != omega.shape:
        raise ValueError("omega_rad_s and h must be 1-D arrays of the same length")
    if not (np.all(np.isfinite(omega)) and np.all(np.isfinite(h))) or np.any(h == 0):
        raise ValueError("omega_rad_s and h must be finite and h nonzero")
    notes: list[str] = []
    modal = fit_modal(omega, h, mass, k, n_elements, quantity, alpha)
    n = modal.fit.model.n_elements
    wn, zeta = natural_frequency_rad_s, damping_ratio
    sources = ["given" if wn is not None else modal_estimate,
               "given" if zeta is not None else modal_estimate]
    if (wn is None or zeta is None) and modal_estimate == "half-power":
        w_r, h_r = _receptance(omega, h, mass, quantity)
        est = estimate_modal(w_r, h_r)
        wn = est.natural_frequency_rad_s if wn is None else wn
        if zeta is None:
            zeta = est.damping_ratio
            if zeta > HALF_POWER_LIMIT:
                notes.append(
                    f"half-power damping ratio {zeta:.4g} > {HALF_POWER_LIMIT:g}: the method "
                    "assumes light damping and is biased here (the unconstrained fit gives "
                    f"{modal.damping_ratio:.4g} +- {modal.damping_ratio_std:.2g}); use the "
                    "default modal estimate 'fit'")
    wn = modal.natural_frequency_rad_s if wn is None else float(wn)
    zeta = modal.damping_ratio if zeta is None else float(zeta)
    reductions = list(modal.reductions)
    check = None
    if sources == ["fit", "fit"]:
        fit = replace(modal.fit, constraint_error=0.0)
    else:
        u = modal.fit.model
        fit = _constrained(omega, h, mass, k, n, wn, zeta, quantity,
                           (u.c, np.asarray(u.maxwell_k), np.asarray(u.maxwell_c)), fit_kwargs)
        while fit.model.n_elements > 1:
            degenerate = degenerate_elements(fit.model, wn)
            if not degenerate:
                break
            i, reason, action, partner = degenerate[0]
            m_ = fit.model.n_elements
            word = f"merged into element {partner + 1}" if action == "merge" else "dropped"
            reductions.append(f"constrained fit: element {i + 1} of {m_} {word}: {reason}")
            fit = _constrained(omega, h, mass, k, m_ - 1, wn, zeta, quantity, None, fit_kwargs)
        check = check_constraints(fit, modal, omega, h, wn, zeta, quantity, alpha)
        if check.rejected:
            notes.append(check.message)
    band = omega[omega > 0]
    if not band.min() <= modal.natural_frequency_rad_s <= band.max():
        notes.append(
            f"the fitted natural frequency {modal.natural_frequency_rad_s:.4g} rad/s lies "
            f"outside the data ({band.min():.4g}-{band.max():.4g} rad/s): it is extrapolated")
    try:
        modal_properties(fit.model)
    except ValueError:
        notes.append("the reported model has no complex eigenvalue pair")
    return Identification(
        fit=fit, modal_fit=modal, target_natural_frequency_rad_s=wn,
        target_damping_ratio=zeta, target_sources=(sources[0], sources[1]),
        constraint_check=check, reductions=tuple(reductions),
        warnings=tuple(notes) + tuple(fit.warnings),
    )
