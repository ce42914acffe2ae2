"""The saturated reference: the baseline fitted separately to each test condition.

Held out on the same points as every other fit, its error says how far any model of the
baseline's family whose parameters depend on the covariate (temperature, force level, ...)
can get at all. The noise floor alone is the wrong target when the data hold more than white
noise (nonlinear distortion, level-dependent scatter): a covariate effect that recovers what
the per-condition fits recover has explained what the covariate can explain.

A condition whose own fit is impossible (fewer training residuals than parameters) or fails
keeps the pooled baseline's residual there (the reference is then conservative).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dva_offline.discrepancy.fitting import HoldoutSplit, ModelFit, ModelSpec, fit_model


@dataclass(frozen=True)
class SaturatedReference:
    """Held-out error of the per-condition baselines.

    Attributes
    ----------
    error : float
        RMS held-out relative error, as :attr:`ModelFit.error`.
    rss_held : float
        Sum of squared weighted held-out residuals.
    n_held : int
    n_fitted, n_conditions : int
        Conditions that got their own fit, of all.
    """

    error: float
    rss_held: float
    n_held: int
    n_fitted: int
    n_conditions: int


def saturated_reference(spec: ModelSpec, obs, split: HoldoutSplit,
                        base: ModelFit) -> SaturatedReference | None:
    """The reference of ``spec`` (the baseline, fitted as ``base`` to all conditions); None
    with fewer than two conditions."""
    labels = np.unique(obs.groups)
    if labels.size < 2:
        return None
    start = np.array([e.value for e in base.estimates])
    spec = replace(spec, starts=(start,), n_priority=0)
    residual = np.array(base.residual, dtype=complex)
    fitted = 0
    for g in labels:
        sel = obs.groups == g
        sub = HoldoutSplit(split.train & sel, split.held & sel, f"condition {g}")
        if not sub.held.any() or 2 * int(sub.train.sum()) <= len(spec.params):
            continue
        try:
            fit = fit_model(spec, obs, sub)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            continue
        residual[sel] = fit.residual[sel]
        fitted += 1
    held = split.held
    rss = float(np.sum(np.abs(residual[held]) ** 2))
    n_h = int(held.sum())
    return SaturatedReference(float(np.sqrt(rss / n_h)), rss, n_h, fitted, int(labels.size))
