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

from dataclasses import dataclass, field, replace

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
    per_condition : dict
        Condition label -> its own fit's :class:`~.fitting.Estimate` tuple (values with
        standard errors); conditions without their own fit are absent.
    """

    error: float
    rss_held: float
    n_held: int
    n_fitted: int
    n_conditions: int
    per_condition: dict = field(default_factory=dict)


def saturated_reference(spec: ModelSpec, obs, split: HoldoutSplit,
                        base: ModelFit, domain=None) -> SaturatedReference | None:
    """The reference of ``spec`` (the baseline, fitted as ``base`` to all conditions); None
    with fewer than two conditions. A ``domain`` may give the model for one condition
    alone (``condition_model(spec, start)``: e.g. a parameter the user fixed for all
    conditions that a covariate effect changes) and further starts for it
    (``condition_starts(points)``, its training points as a mask: e.g. a global search that
    does not inherit the pooled fit's compromise between the conditions)."""
    labels = np.unique(obs.groups)
    if labels.size < 2:
        return None
    start = np.array([e.value for e in base.estimates])
    if getattr(domain, "condition_model", None) is not None:
        spec, start = domain.condition_model(spec, start)
    starts = getattr(domain, "condition_starts", None)
    pooled = replace(spec, starts=(start,), n_priority=0)
    residual = np.array(base.residual, dtype=complex)
    fitted, own = 0, {}
    for g in labels:
        sel = obs.groups == g
        sub = HoldoutSplit(split.train & sel, split.held & sel, f"condition {g}")
        if not sub.held.any() or 2 * int(sub.train.sum()) <= len(spec.params):
            continue
        more = [v for v in (starts(sub.train) if starts is not None else ())
                if v is not None and np.shape(v) == start.shape]
        this = pooled if not more else replace(spec, starts=(start, *more),
                                               n_priority=len(more) + 1)
        try:
            fit = fit_model(this, obs, sub)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            continue
        residual[sel] = fit.residual[sel]
        own[int(g)] = fit.estimates
        fitted += 1
    held = split.held
    rss = float(np.sum(np.abs(residual[held]) ** 2))
    n_h = int(held.sum())
    return SaturatedReference(float(np.sqrt(rss / n_h)), rss, n_h, fitted, int(labels.size),
                              own)


def moving_parameters(reference: SaturatedReference | None, alpha: float = 1e-3) -> list[dict]:
    """Each baseline parameter of the per-condition fits: its value and standard error per
    condition, and whether it moves beyond its errors (chi^2 of the values against their
    weighted mean with G - 1 degrees of freedom, p < ``alpha``). Conditions whose fit left
    the parameter without a standard error (on a bound) are left out of its test."""
    from scipy import stats

    if reference is None or len(reference.per_condition) < 2:
        return []
    labels = sorted(reference.per_condition)
    first = reference.per_condition[labels[0]]
    out = []
    for i, est in enumerate(first):
        v = np.array([reference.per_condition[g][i].value for g in labels])
        s = np.array([reference.per_condition[g][i].std for g in labels])
        ok = np.isfinite(v) & np.isfinite(s) & (s > 0)
        chi2, p = np.nan, np.nan
        if ok.sum() >= 2:
            w = s[ok] ** -2
            m = np.average(v[ok], weights=w)
            chi2 = float(np.sum((v[ok] - m) ** 2 * w))
            p = float(stats.chi2.sf(chi2, ok.sum() - 1))
        out.append({"name": est.name, "unit": est.unit, "conditions": labels,
                    "values": v.tolist(), "std": s.tolist(), "chi2": chi2,
                    "dof": int(ok.sum()) - 1, "p_value": p,
                    "moving": bool(np.isfinite(p) and p < alpha)})
    return out
