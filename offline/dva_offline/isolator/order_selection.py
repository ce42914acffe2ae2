"""Model-order selection: Voigt -> M-V -> M-M-V -> ... on held-out frequency points.

Beyond the study, which picks the number of Maxwell elements by inspection (section 4.3.2).
Every ``holdout_every``-th frequency point is held out; each order is fitted to the rest and
scored by its relative RMS FRF error on the held-out points. Order 0 is the better of Voigt
Model M and Model K (section 3.4) on the training points. The selected order is the smallest
whose held-out error is within ``tolerance`` (relative) of the best one, so an extra element
must buy a real improvement.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from dva_offline.isolator.maxwell_fit import FitWarning, MaxwellFit, fit_maxwell_model
from dva_offline.isolator.maxwell_model import MaxwellModel, frf
from dva_offline.isolator.mv_curves import frf_error
from dva_offline.isolator.voigt_identification import voigt_model_k, voigt_model_m


@dataclass(frozen=True)
class OrderSelection:
    """Result of :func:`select_model_order`.

    Attributes
    ----------
    orders : tuple of int
        Numbers of Maxwell elements tried (0 = Voigt).
    holdout_errors : tuple of float
        Relative RMS FRF error on the held-out points, per order [-].
    train_errors : tuple of float
        Relative RMS FRF error on the training points, per order [-].
    selected_order : int
    model : MaxwellModel
        The selected model (Voigt models are returned with their own mass and stiffness).
    fit : MaxwellFit or None
        Fit of the selected order refitted on all points (None for order 0).
    models : tuple of MaxwellModel
        The model of every order tried, fitted on the training points (same order as
        ``orders``), for tools that refine or compare them.
    """

    orders: tuple[int, ...]
    holdout_errors: tuple[float, ...]
    train_errors: tuple[float, ...]
    selected_order: int
    model: MaxwellModel
    fit: MaxwellFit | None
    models: tuple[MaxwellModel, ...] = ()


def select_model_order(
    omega_rad_s,
    h,
    mass: float,
    k: float,
    natural_frequency_rad_s: float,
    damping_ratio: float,
    quantity: str = "receptance",
    max_elements: int = 3,
    holdout_every: int = 4,
    tolerance: float = 0.1,
    **fit_kwargs,
) -> OrderSelection:
    """Choose the number of Maxwell elements by held-out FRF error (see module docstring).

    Parameters
    ----------
    omega_rad_s, h : array_like, shape (N,)
        Frequencies [rad/s] and measured FRF (complex) of kind ``quantity``.
    mass, k : float
        Mass [kg] and static stiffness [N/m].
    natural_frequency_rad_s, damping_ratio : float
        Measured w_n [rad/s] and zeta.
    max_elements : int
        Largest number of Maxwell elements tried (>= 1).
    holdout_every : int
        Hold out every this-many-th point (>= 2).
    tolerance : float
        Relative slack on the best held-out error (>= 0).
    **fit_kwargs
        Passed to :func:`fit_maxwell_model`.
    """
    omega = np.asarray(omega_rad_s, dtype=float)
    h = np.asarray(h, dtype=complex)
    if omega.shape != h.shape or omega.ndim != 1:
        raise ValueError("omega_rad_s and h must be 1-D arrays of the same length")
    if not isinstance(max_elements, int) or max_elements < 1:
        raise ValueError(f"max_elements must be an integer >= 1, got {max_elements!r}")
    if not isinstance(holdout_every, int) or holdout_every < 2:
        raise ValueError(f"holdout_every must be an integer >= 2, got {holdout_every!r}")
    if not tolerance >= 0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance}")
    held = np.zeros(omega.size, dtype=bool)
    held[holdout_every // 2 :: holdout_every] = True
    train = ~held
    if train.sum() < 2 * max_elements + 2 or held.sum() < 2:
        raise ValueError(f"too few frequency points ({omega.size}) for order selection")

    orders, hold_err, train_err, models = [], [], [], []
    voigts = [
        voigt_model_m(mass, natural_frequency_rad_s, damping_ratio).as_maxwell_model(),
        voigt_model_k(k, natural_frequency_rad_s, damping_ratio).as_maxwell_model(),
    ]
    voigt = min(voigts, key=lambda m: frf_error(frf(m, omega[train], quantity), h[train]))
    orders.append(0)
    models.append(voigt)
    train_err.append(frf_error(frf(voigt, omega[train], quantity), h[train]))
    hold_err.append(frf_error(frf(voigt, omega[held], quantity), h[held]))
    for n in range(1, max_elements + 1):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitWarning)
            fit = fit_maxwell_model(
                omega[train], h[train], mass, k, n, natural_frequency_rad_s, damping_ratio,
                quantity=quantity, **fit_kwargs,
            )
        orders.append(n)
        models.append(fit.model)
        train_err.append(fit.frf_error)
        hold_err.append(frf_error(frf(fit.model, omega[held], quantity), h[held]))
    best = min(hold_err)
    selected = next(i for i, e in enumerate(hold_err) if e <= best * (1 + tolerance) + 1e-12)
    final_fit = None
    model = models[selected]
    if selected > 0:
        final_fit = fit_maxwell_model(
            omega, h, mass, k, selected, natural_frequency_rad_s, damping_ratio,
            quantity=quantity, **fit_kwargs,
        )
        model = final_fit.model
    return OrderSelection(
        tuple(orders), tuple(hold_err), tuple(train_err), orders[selected], model, final_fit,
        tuple(models),
    )
