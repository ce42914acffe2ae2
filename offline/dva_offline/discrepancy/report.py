"""Report of a discrepancy run: a JSON-ready dict and PNG plots (matplotlib Agg, lazy).

The dict follows the CLI contract: ``baseline`` {model, error}, ``verdict`` {status, effect,
evidence}, ``augmented`` {model, error, parameters} or None, ``candidates`` [{effect, error,
...}], plus the residual evidence and the error definition. NaN and infinities become None.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dva_offline.cli_tools import json_safe
from dva_offline.discrepancy.fitting import ModelFit
from dva_offline.discrepancy.loop import CandidateScore, DiscrepancyResult
from dva_offline.discrepancy.residual import ResidualFeatures
from dva_offline.plotting import unwrapped_phase_deg as _unwrapped_deg


def _params(estimates) -> list[dict]:
    return [{"name": e.name, "value": e.value, "std": e.std, "unit": e.unit} for e in estimates]


def _hits(fit: ModelFit) -> list[dict]:
    return [{"parameter": h.name, "value": h.value, "bound": h.bound, "side": h.side,
             "unit": h.unit, "effect_parameter": h.added, "meaning": h.meaning}
            for h in fit.bound_hits]


def _fit(fit: ModelFit) -> dict:
    return {
        "model": fit.name, "error": fit.error, "error_l2": fit.error_l2,
        "train_error": fit.train_error, "n_parameters": fit.n_params,
        "parameters": _params(fit.estimates), "bound_hits": _hits(fit),
    }


def _features(f: ResidualFeatures) -> dict:
    loc = f.localisation
    out = {
        "rms": f.rms,
        "whiteness": {"test": "Ljung-Box on real and imaginary parts",
                      "statistic": f.whiteness.statistic, "dof": f.whiteness.dof,
                      "p_value": f.whiteness.p_value, "lags": f.whiteness.lags,
                      "lag1_autocorrelation": f.whiteness.lag1_autocorrelation},
        "localisation": {"band_edges_hz": loc.edges, "band_rms": loc.rms,
                         "excess_fraction": loc.excess_fraction,
                         "peak_band_center_hz": loc.peak_center,
                         "concentration": loc.concentration},
        "covariates": [{"name": c.name, "levels": c.levels, "rms_per_level": c.rms_per_level,
                        "f_statistic": c.f_statistic, "p_value": c.p_value,
                        "explained_fraction": c.explained_fraction} for c in f.covariates],
    }
    if f.phase is not None:
        out["phase_trend"] = {
            "phase_slope_rad_per_hz": f.phase.phase_slope,
            "phase_slope_std": f.phase.phase_slope_std,
            "equivalent_delay_s": f.phase.equivalent_delay_s,
            "log_magnitude_slope_per_hz": f.phase.log_magnitude_slope,
        }
    return out


def _law(fit) -> dict | None:
    return None if fit is None or fit.law is None else fit.law.to_dict(fit)


def trend_to_dict(t) -> dict:
    """A coordinate's per-condition values, its moving test and its laws (:mod:`.laws`)."""
    return {"effect": t.effect, "covariate": t.covariate, "coordinate": t.coordinate,
            "levels": t.x.tolist(), "values": t.values.tolist(), "std": t.std.tolist(),
            "chi2": t.chi2, "dof": t.dof, "p_value": t.p_value, "moving": t.moving,
            "law": t.law, "reason": t.reason,
            "laws": [{"law": sc.law, "n_parameters": sc.n_params,
                      "held_out_chi2": sc.loco, "chi2": sc.chi2,
                      "parameters": list(sc.theta), "std": list(sc.theta_std)}
                     for sc in t.scores]}


def _candidate(c: CandidateScore) -> dict:
    covariate, _, form = (c.label or "").partition(", ")
    item = {"effect": c.effect, "covariate": covariate or None, "form": form or None,
            "applicable": c.applicable, "failed": c.failed, "implausible": c.implausible}
    if c.implausible:  # fitted and significant, but meaningless physically: never added
        item.update(reason=c.reason, model=c.fit.name, error=c.fit.error,
                    delta_bic=c.delta_bic, p_value=c.p_value,
                    parameters=_params(c.fit.added), law=_law(c.fit))
        return item
    if not c.applicable:
        item.update(error=None, reason=c.reason)
        return item
    item.update(
        model=c.fit.name, error=c.fit.error, error_l2=c.fit.error_l2,
        train_error=c.fit.train_error, delta_bic=c.delta_bic, p_value=c.p_value,
        explained_fraction=c.explained_fraction, achieved_fraction=c.achieved_fraction,
        n_added=c.fit.n_added,
        parameters=_params(c.fit.added), signature=c.signature, bound_hits=_hits(c.fit),
        law=_law(c.fit),
    )
    return item


def _step(number: int, st) -> dict:
    return {"step": number, "effect": st.effect,
            "covariate": st.label.partition(", ")[0] or None,
            "form": st.label.partition(", ")[2] or None, "model": st.model,
            "error_before": st.error_before, "error_after": st.error_after,
            "noise_floor_before": st.noise_before, "delta_bic": st.delta_bic,
            "p_value": st.p_value, "explained_fraction": st.explained_fraction,
            "achieved_fraction": st.achieved_fraction,
            "parameters": _params(st.fit.added), "bound_hits": _hits(st.fit),
            "law": _law(st.fit), "caveats": list(st.caveats)}


def result_to_dict(result: DiscrepancyResult, extra: dict | None = None) -> dict:
    """The JSON object of the CLI (see module docstring); ``extra`` keys are added first."""
    v = result.verdict
    aug = None
    if result.augmented is not None:
        a = result.augmented
        aug = {"model": a.name, "effect": a.effect,
               "covariate": (a.label or "").partition(", ")[0] or None,
               "form": (a.label or "").partition(", ")[2] or None, "bound_hits": _hits(a),
               "error": a.error, "error_l2": a.error_l2, "train_error": a.train_error,
               "error_ratio": a.error / result.baseline.error,
               "parameters": _params(a.added), "all_parameters": _params(a.estimates),
               "law": _law(a), "residual": _features(result.augmented_residual)}
    out = dict(extra or {})
    out.update({
        "domain": result.domain,
        "error_definition": result.error_definition,
        "holdout": {"scheme": result.split.scheme, "n_train": int(result.split.train.sum()),
                    "n_held_out": int(result.split.held.sum())},
        "noise_floor": {"sigma": result.noise.sigma, "method": result.noise.method},
        "saturated_reference": None if result.reference is None else {
            "error": result.reference.error, "n_fitted": result.reference.n_fitted,
            "n_conditions": result.reference.n_conditions, "used": result.reference_used,
            "definition": "the baseline fitted separately to each condition, held-out error "
                          "on the same points",
            "parameters": list(result.moving)},
        "trends": [trend_to_dict(t) for t in result.trends],
        "baseline": _fit(result.baseline),
        "residual": _features(result.residual),
        "verdict": {"status": v.status, "effect": v.effect,
                    "covariate": (v.label or "").partition(", ")[0] or None,
                    "form": (v.label or "").partition(", ")[2] or None,
                    "evidence": v.evidence, "caveats": list(v.caveats)},
        "augmented": aug,
        "candidates": [_candidate(c) for c in result.candidates],
        "decision_rule": {k: getattr(result.rule, k) for k in result.rule.__dataclass_fields__},
        "steps": [_step(i + 1, st) for i, st in enumerate(result.steps)],
        "final": None if result.final is None else {
            "status": result.final.status, "reason": result.final.reason,
            "model": result.final.model, "error": result.final.error,
            "noise_floor": result.final.noise,
            "error_over_noise": result.final.error / result.final.noise
            if result.final.noise > 0 else None,
            "effects": [{"effect": e, "covariate": lab.partition(", ")[0] or None,
                         "form": lab.partition(", ")[2] or None}
                        for e, lab in result.final.effects],
            "parameters": _params(result.final.fit.estimates),
            "bound_hits": _hits(result.final.fit),
        },
    })
    return json_safe(out)


#: SI units of the quantities a FRF file may hold (the table reader converts to these).
QUANTITY_UNITS = {"receptance": "m/N", "accelerance": "(m/s^2)/N", "mobility": "(m/s)/N",
                  "stiffness": "N/m", "modulus": "Pa"}


def _condition_label(observations, group: int) -> str:
    """What tells a condition apart: its covariates' levels (``temperature_c 23``)."""
    sel = observations.groups == group
    parts = [f"{name} {np.mean(col[sel]):.4g}" for name, col in observations.covariates.items()]
    return ", ".join(parts) if parts else f"condition {group}"


def plot_result(result: DiscrepancyResult, observations, plot_dir, quantity: str,
                title: str = "", panels: list[tuple[str, str]] | None = None,
                condition_labels: dict | None = None) -> list[Path]:
    """Write ``discrepancy_frf.png`` (measured, baseline, augmented), ``discrepancy_residual.png``
    (relative residual before/after vs frequency, noise floor) and
    ``discrepancy_candidates.png`` (held-out error and dBIC per candidate) into ``plot_dir``.

    ``panels``: (name, unit) of the quantity in each column of the FRF figure; group ``g`` of
    ``observations`` goes to column ``g % len(panels)`` (a flight's plunge and pitch channels).
    Default: one column, ``quantity`` in its SI unit. ``condition_labels``: group -> its name in
    the legend (default: its covariates' levels). Each condition has its colour; measured
    points are dots, the baseline dashed, the augmented model solid; phases are unwrapped."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    from matplotlib.lines import Line2D

    out_dir = Path(plot_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    obs = observations
    f, y, groups = obs.axis, obs.values, obs.groups
    fits = [("baseline", result.baseline, "b-")]
    if result.augmented is not None:
        fits.append((f"+ {result.augmented.effect}", result.augmented, "r-"))
    if result.final is not None and len(result.steps) > 1:
        fits.append((f"final ({len(result.steps)} effects)", result.final.fit, "g-"))
    written = []

    panels = panels or [(quantity, QUANTITY_UNITS.get(quantity, ""))]
    fit_styles = dict(zip([label for label, _, _ in fits], ("--", "-", ":")))
    fig, axes = plt.subplots(2, len(panels), sharex=True, squeeze=False,
                             figsize=(8 if len(panels) == 1 else 12, 7.5))
    handles = []
    for k, (name, unit) in enumerate(panels):
        ax_m, ax_p = axes[:, k]
        conditions = [g for g in np.unique(groups) if g % len(panels) == k]
        colours = plt.cm.viridis(np.linspace(0, 0.9, len(conditions))) if len(conditions) > 10 \
            else plt.cm.tab10(np.arange(len(conditions)))
        start = None  # every condition's phase on the branch of the first one's start
        for g, colour in zip(conditions, colours):
            sel = groups == g
            best = _unwrapped_deg(fits[-1][1].prediction[sel])
            start = best[0] if start is None else start
            best -= 360.0 * np.round((best[0] - start) / 360.0)
            for label, fit, _ in fits:
                phase = _unwrapped_deg(fit.prediction[sel])
                phase -= 360.0 * np.round((phase[0] - best[0]) / 360.0)
                # the baseline in grey: the model that lacks the effect, under every condition
                style = dict(ls=fit_styles[label], lw=1,
                             color="0.45" if fit is result.baseline else colour)
                ax_m.loglog(f[sel], np.abs(fit.prediction[sel]), **style)
                ax_p.semilogx(f[sel], phase, **style)
            ax_m.loglog(f[sel], np.abs(y[sel]), ".", color=colour, ms=3)
            ax_p.semilogx(f[sel], _unwrapped_deg(y[sel], best), ".", color=colour, ms=3)
            if k == 0:
                handles.append(Line2D([], [], color=colour, marker=".", ls="-",
                                      label=(condition_labels or {}).get(g)
                                      or _condition_label(obs, g)))
        ax_m.set_ylabel(f"|{name.split()[0]}|" + (f" [{unit}]" if unit else ""))
        ax_p.set_ylabel("phase [deg], unwrapped")
        ax_p.set_xlabel("frequency [Hz]")
        ax_m.set_title(name, fontsize=9)
        for ax in (ax_m, ax_p):
            ax.grid(True, which="both", alpha=0.3)
            ax.xaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1, 2, 5)))
            ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    handles += [Line2D([], [], color="k", marker=".", ls="none", label="measured")]
    handles += [Line2D([], [], color="0.45" if fit is result.baseline else "k",
                       ls=fit_styles[label], label=label) for label, fit, _ in fits]
    rows = -(-len(handles) // 4)
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.suptitle((title + ": " if title else "")
                 + f"verdict {result.verdict.status} {result.verdict.effect or ''}".rstrip(),
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.025 * rows + 0.01, 1, 1))
    path = out_dir / "discrepancy_frf.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)

    fig, ax = plt.subplots(figsize=(8, 4))
    for label, fit, style in fits:
        err = fit.error
        ax.semilogx(f, np.abs(fit.residual), style[0] + ".", ms=2,
                    label=f"{label} (held-out error {err:.4f})")
    ax.axhline(result.noise.sigma, color="k", ls="--",
               label=f"noise floor {result.noise.sigma:.4f}")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|relative residual| [-]")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path = out_dir / "discrepancy_residual.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)

    fitted = [c for c in result.candidates if c.applicable]
    fig, (ax_e, ax_b) = plt.subplots(1, 2, figsize=(9, 3.5))
    names = [c.effect + (f"\n({c.label})" if c.label else "") for c in fitted]
    ax_e.barh(names, [c.fit.error for c in fitted], color="tab:orange")
    ax_e.axvline(result.baseline.error, color="b", label="baseline")
    ax_e.axvline(result.noise.sigma, color="k", ls="--", label="noise floor")
    ax_e.set_xlabel("held-out error (relative) [-]")
    ax_e.legend(fontsize=7)
    ax_b.barh(names, [c.delta_bic for c in fitted], color="tab:green")
    ax_b.axvline(-result.rule.min_bic_gain, color="k", ls="--")
    ax_b.set_xlabel("dBIC vs baseline [-] (lower is better)")
    ax_b.set_yticklabels([])
    fig.tight_layout()
    path = out_dir / "discrepancy_candidates.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)
    return written
