"""The discrepancy loop: baseline -> residual -> candidate effects -> verdict, step by step.

Loop: fit the baseline on training points -> error on held-out points -> characterise the
residual (noise floor, whiteness, localisation, phase trend, covariates) -> fit every candidate
effect of the domain's library -> score on held-out points with a penalty per added parameter
-> verdict ``consistent`` / ``explained`` (with the effect's name) / ``unexplained``.

Scores and decision (all thresholds in :class:`DecisionRule`):

* Noise floor sigma_hat from the data alone (:func:`.residual.noise_floor`).
* ``consistent`` when the baseline's held-out error e_0 <= consistency_ratio * sigma_hat and
  its residual passes the Ljung-Box whiteness test (p >= whiteness_alpha).
* Each candidate c (p_c added parameters, all parameters refitted on the training points):
  penalised held-out score dBIC_c = n ln(S_c / S_0) + p_c ln(n), n = 2 N_h real residuals,
  S = held-out sum of squared weighted residuals; a nested F test on the training points
  (baseline vs candidate) gives p-value p_c; the explained fraction
  R_c = (S_0 - S_c) / (S_0 - N_h sigma_hat^2) is the share of the excess (non-noise) held-out
  residual power that the candidate removes.
* ``explained`` when the best candidate (lowest dBIC) has p_c < significance,
  dBIC_c <= -min_bic_gain and R_c >= min_explained, and no other candidate with
  R >= min_explained comes within ambiguity_margin of its dBIC. Otherwise ``unexplained``.
* Covariate effects are also offered in the form built from the laws their per-condition
  fits follow (a domain's ``law_candidates``, :mod:`.laws`); a significant candidate whose
  parameters mean nothing physically is listed as implausible and never added
  (:mod:`.plausibility`).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from scipy import stats

from dva_offline.discrepancy import plausibility
from dva_offline.discrepancy.fitting import (
    EFFECT_VOCABULARY,
    ERROR_DEFINITION,
    STATUSES,
    HoldoutSplit,
    ModelFit,
    ModelSpec,
    NotApplicable,
    Observations,
    ParamSpec,
    fit_model,
    holdout_split,
)
from dva_offline.discrepancy.residual import NoiseFloor, ResidualFeatures, characterise
from dva_offline.discrepancy.saturated import (
    SaturatedReference,
    moving_parameters,
    saturated_reference,
)

# the model pieces a domain or a caller needs with the loop
__all__ = [
    "EFFECT_VOCABULARY", "ERROR_DEFINITION", "STATUSES", "CandidateScore", "DecisionRule",
    "DiscrepancyResult", "Domain", "HoldoutSplit", "ModelFit", "ModelSpec", "NotApplicable",
    "LoopOutcome", "Observations", "ParamSpec", "Step", "Verdict", "choose_step", "decide",
    "fit_model", "holdout_split", "run", "score_candidate",
]

# effects whose parameters make the model depend on a condition covariate: what they can
# explain at most is what the baseline fitted to each condition explains (the saturated
# reference, :mod:`.saturated`)
COVARIATE_EFFECTS = ("amplitude_dependence", "covariate_shift")


class Domain(Protocol):
    """What a domain supplies to :func:`run`."""

    name: str
    observations: Observations

    def baseline(self, train: np.ndarray) -> ModelSpec:
        """The baseline model, initialised from the training points (mask, shape (N,))."""

    def candidates(
        self, baseline: ModelFit, features: ResidualFeatures
    ) -> Sequence[ModelSpec | NotApplicable]:
        """The candidate library, each started from the fitted baseline."""

    def variants(self, spec: ModelSpec) -> Sequence[ModelSpec]:
        """Optional: other forms of a promising candidate (e.g. on a richer baseline); the
        loop keeps the form with the best score. Return [] for none."""




@dataclass(frozen=True)
class DecisionRule:
    """Thresholds of the verdict (module docstring).

    Attributes
    ----------
    consistency_ratio : float
        Baseline consistent if held-out error <= this x noise floor (and white).
    whiteness_alpha : float
        Ljung-Box p-value below which the residual is called correlated.
    significance : float
        F-test p-value a candidate must beat.
    min_bic_gain : float
        A candidate must lower the held-out BIC by at least this.
    min_explained : float
        Share of the excess residual power the best candidate must remove.
    ambiguity_margin : float
        Another candidate that also explains the residual within this BIC margin makes the
        attribution ambiguous (verdict ``unexplained``).
    strict_consistency : bool
        If True, ``consistent`` also needs that no candidate is significant (F-test p <
        significance and dBIC <= -min_bic_gain), and the noise level in the explained
        fraction R is capped by the best candidate's held-out error (a noise floor estimate
        that is too high, e.g. from correlated estimation noise, must not hide a clear
        effect). Off by default (domain 1); the flight domain uses it.
    min_step_explained : float
        Share of the excess an effect must remove to be added as a step of the loop when it
        does not explain min_explained alone (:func:`choose_step`).
    max_steps : int
        Most effects the loop adds.
    joint_ratio : float
        When no single effect explains >= min_explained, the effects the loop added in turn
        count as the explanation if the final held-out error is within this x the noise floor
        (whiteness not required: with hundreds of points Ljung-Box flags the smallest
        difference between the data's law and the library's, e.g. Kraus vs logarithmic), or,
        when a covariate effect was added and the saturated reference counts, within this x
        the reference's held-out error.
    min_reference_gain : float
        The saturated reference (baseline fitted to each condition) counts only when it
        lowers the baseline's held-out residual power by at least this share: the covariate
        can then explain something, and a covariate effect's share of that is reported and
        used beside the share of the excess over the noise.
    agreeing_conditions_verdict : bool
        With several conditions, each fitted alone (the saturated reference), when those fits
        gain less than min_reference_gain and no candidate is significant, the verdict is
        ``no_covariate_effect``: the measurements agree with one model, nothing to add or
        name; the evidence states the misfit the model family leaves, the same in every
        condition (it is above the noise, else the verdict would be ``consistent``).
    covariate_laws : bool
        Offer each covariate effect also built from the laws its per-condition fits follow
        (:mod:`.laws`; a domain's ``law_candidates``). Off: the library's fixed forms only.
    """

    consistency_ratio: float = 1.25
    whiteness_alpha: float = 1e-3
    significance: float = 1e-3
    min_bic_gain: float = 10.0
    min_explained: float = 0.9
    ambiguity_margin: float = 10.0
    strict_consistency: bool = False
    min_step_explained: float = 0.1
    max_steps: int = 12
    joint_ratio: float = 1.5
    min_reference_gain: float = 0.2
    agreeing_conditions_verdict: bool = True
    covariate_laws: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.max_steps, (int, np.integer)) or self.max_steps < 1:
            raise ValueError(f"max_steps must be an integer >= 1, got {self.max_steps!r}")


@dataclass(frozen=True)
class CandidateScore:
    """A library entry's result.

    Attributes
    ----------
    effect, label : str
    applicable : bool
    reason : str
        Why not applicable (empty otherwise).
    fit : ModelFit or None
    delta_bic : float
        Penalised held-out score relative to the baseline (negative is better).
    p_value : float
        Nested F test on the training points (baseline vs candidate).
    explained_fraction : float
        R (module docstring); NaN when the baseline has no excess over the noise floor.
    signature : str
    failed : bool
        The start or the fit failed (``reason`` says why); the loop went on without it.
    achieved_fraction : float
        For a covariate effect, when the saturated reference counts: the share of the
        held-out residual power above max(noise, reference) that it removes (NaN otherwise).
    implausible : bool
        Fitted and significant, but its parameters mean nothing physically (``reason``
        says why, :mod:`.plausibility`): listed, never added (``applicable`` is False).
    """

    effect: str
    label: str
    applicable: bool
    reason: str
    fit: ModelFit | None
    delta_bic: float
    p_value: float
    explained_fraction: float
    signature: str
    failed: bool = False
    achieved_fraction: float = np.nan
    implausible: bool = False


@dataclass(frozen=True)
class Verdict:
    """``status`` in :data:`STATUSES`; ``effect`` named only when explained; ``caveats``:
    what the named fit leaves in doubt (its effect's parameters that ended on a bound)."""

    status: str
    effect: str | None
    label: str
    evidence: str
    caveats: tuple = ()


@dataclass(frozen=True)
class DiscrepancyResult:
    """Everything the loop found.

    Attributes
    ----------
    domain : str
    split : HoldoutSplit
    baseline : ModelFit
    noise : NoiseFloor
    residual : ResidualFeatures
        Of the baseline's residual (all points).
    candidates : tuple of CandidateScore
        Sorted best first (applicable ones by delta_bic, then the others).
    verdict : Verdict
    augmented : ModelFit or None
        The named effect's fit, when explained.
    augmented_residual : ResidualFeatures or None
    rule : DecisionRule
    error_definition : str
    """

    domain: str
    split: HoldoutSplit
    baseline: ModelFit
    noise: NoiseFloor
    residual: ResidualFeatures
    candidates: tuple[CandidateScore, ...]
    verdict: Verdict
    augmented: ModelFit | None
    augmented_residual: ResidualFeatures | None
    rule: DecisionRule
    error_definition: str = ERROR_DEFINITION
    steps: tuple = ()
    final: LoopOutcome | None = None
    reference: SaturatedReference | None = None
    reference_used: bool = False
    # the per-condition trends of the covariate effects' coordinates and their laws
    # (:mod:`.laws`), and each baseline parameter's moving test over the conditions
    trends: tuple = ()
    moving: tuple = ()

    @property
    def error_reduction(self) -> float | None:
        """Augmented over baseline held-out error (None unless explained)."""
        if self.augmented is None:
            return None
        return self.augmented.error / self.baseline.error


@dataclass(frozen=True)
class Step:
    """One effect the loop added: the held-out error before and after, and its scores
    against the model of the step before."""

    effect: str
    label: str
    model: str
    error_before: float
    error_after: float
    noise_before: float
    delta_bic: float
    p_value: float
    explained_fraction: float
    fit: ModelFit
    caveats: tuple = ()
    achieved_fraction: float = np.nan


@dataclass(frozen=True)
class LoopOutcome:
    """Where the loop ended: ``consistent`` (residual within the noise) or ``stopped`` (and
    why), with the final model."""

    status: str
    reason: str
    model: str
    error: float
    noise: float
    effects: tuple
    fit: ModelFit


def score_candidate(base: ModelFit, fit: ModelFit, sigma: float) -> tuple[float, float, float]:
    """(delta_bic, p_value, explained_fraction) of a candidate fit against the baseline fit."""
    n = 2 * fit.n_held
    p_add = fit.n_added if fit.count_added is None else fit.count_added
    delta_bic = n * np.log(fit.rss_held / base.rss_held) + p_add * np.log(n)
    dof = 2 * fit.n_train - fit.n_params
    if p_add == 0 or dof <= 0 or fit.rss_train >= base.rss_train:
        p_value = 1.0
    else:
        f = ((base.rss_train - fit.rss_train) / p_add) / (fit.rss_train / dof)
        p_value = float(stats.f.sf(f, p_add, dof))
    excess = base.rss_held - fit.n_held * sigma**2
    frac = (base.rss_held - fit.rss_held) / excess if excess > 0 else np.nan
    return float(delta_bic), p_value, float(frac)


def _features(obs: Observations, fit: ModelFit, sigma=None) -> ResidualFeatures:
    with np.errstate(all="ignore"):
        ratio = obs.values / fit.prediction
    if not np.all(np.isfinite(ratio)) or np.any(ratio == 0):
        ratio = None
    return characterise(obs.axis, fit.residual, obs.groups, condition_levels(obs), ratio,
                        sigma, log=obs.log_axis)


def condition_levels(obs: Observations) -> dict:
    """Each covariate as its condition's mean at every point (a measured covariate drifts
    within a sweep; the residual's covariate test compares conditions)."""
    out = {}
    for name, col in obs.covariates.items():
        col = np.asarray(col, float)
        means = np.zeros(col.size)
        for g in np.unique(obs.groups):
            sel = obs.groups == g
            means[sel] = col[sel].mean()
        out[name] = means
    return out


def share(c) -> float:
    """What a candidate (or step) explains for the verdict: the larger of its share of the
    excess over the noise floor and, for a covariate effect, its share of what the
    per-condition fits reach (NaN when neither is defined)."""
    both = [x for x in (c.explained_fraction, c.achieved_fraction) if np.isfinite(x)]
    return max(both) if both else np.nan


def achieved_fraction(base: ModelFit, fit: ModelFit, sigma: float,
                      reference: SaturatedReference | None) -> float:
    """Share of the held-out residual power above max(noise, saturated reference) that a
    covariate effect's fit removes; NaN without a reference or with nothing above it."""
    if reference is None or fit.effect not in COVARIATE_EFFECTS:
        return np.nan
    floor = max(fit.n_held * sigma**2, reference.rss_held)
    room = base.rss_held - floor
    return float((base.rss_held - fit.rss_held) / room) if room > 0 else np.nan


def _describe(c: CandidateScore) -> str:
    label = f" ({c.label})" if c.label else ""
    reach = (f", recovers {100 * c.achieved_fraction:.0f} % of what the per-condition fits "
             "reach" if np.isfinite(c.achieved_fraction) else "")
    return (f"{c.effect}{label}: held-out error {c.fit.error:.4f}, dBIC {c.delta_bic:.1f}, "
            f"F-test p = {c.p_value:.2g}, explains {100 * c.explained_fraction:.0f} % of the "
            f"excess{reach}" + "".join(f" ({h.name} on its {h.side} bound {h.bound:.4g} {h.unit})"
                               for h in _added_hits(c)))


def _best_eligible(eligible, rule):
    """The eligible candidate with the lowest delta BIC; a form built from the laws of the
    per-condition fits (:mod:`.laws`) only when it beats every library form of the same
    effect by ``rule.ambiguity_margin`` (where the library's law does as well, it is the
    named one; "free per level" says less than WLF at the same score); when its added
    parameters hit a bound, another form of the same effect whose fit stays inside its
    bounds (Arrhenius for a WLF whose C2 ran to its bound) if it scores within the margin. A
    law form that also carries coordinates that did not move alone (``law.offered``: the
    effect's full form) likewise only when it beats the form of the moving coordinates by
    the margin."""
    best = min(eligible, key=lambda c: c.delta_bic)
    if best.fit.law is not None and best.fit.law.offered:
        moving = [c for c in eligible if c.effect == best.effect and c.fit.law is not None
                  and not c.fit.law.offered
                  and c.delta_bic - best.delta_bic < rule.ambiguity_margin]
        if moving:
            best = min(moving, key=lambda c: c.delta_bic)
    if best.fit.law is not None:
        library = [c for c in eligible if c.effect == best.effect and c.fit.law is None
                   and c.delta_bic - best.delta_bic < rule.ambiguity_margin]
        if library:
            best = min(library, key=lambda c: c.delta_bic)
    if _added_hits(best):
        inside = [c for c in eligible if c.effect == best.effect and not _added_hits(c)
                  and c.delta_bic - best.delta_bic < rule.ambiguity_margin]
        if inside:
            best = min(inside, key=lambda c: c.delta_bic)
    return best


def decide(base: ModelFit, noise: NoiseFloor, features: ResidualFeatures,
           scores: Sequence[CandidateScore], rule: DecisionRule,
           reference: SaturatedReference | None = None) -> Verdict:
    """Apply :class:`DecisionRule` (module docstring) to the scored candidates.

    ``reference``: the saturated reference when it was computed for every condition; when it
    does not count (the per-condition fits gain less than ``rule.min_reference_gain``) and
    no candidate is significant, the conditions agree with one model: ``no_covariate_effect``
    (``rule.agreeing_conditions_verdict``), the model family's misfit stated."""
    sigma = noise.sigma
    ratio = base.error / sigma if sigma > 0 else np.inf
    white = features.whiteness
    head = (f"baseline held-out error {base.error:.4f} = {ratio:.2f} x the noise floor "
            f"{sigma:.4f}; residual whiteness (Ljung-Box) p = {white.p_value:.2g}")
    fitted = [c for c in scores if c.applicable and c.fit is not None]
    eligible = [c for c in fitted if c.p_value < rule.significance
                and c.delta_bic <= -rule.min_bic_gain]
    if (ratio <= rule.consistency_ratio and white.p_value >= rule.whiteness_alpha
            and not (rule.strict_consistency and eligible)):
        return Verdict("consistent", None, "",
                       f"{head}: the baseline fits within the noise; nothing added")
    if not eligible:
        best = min(fitted, key=lambda c: c.delta_bic) if fitted else None
        tail = f"; best was {_describe(best)}" if best is not None else ""
        if _conditions_agree(base, reference, rule):
            return Verdict("no_covariate_effect", None, "",
                           f"{head}; the conditions agree with one model: fitted to each "
                           f"condition alone the baseline reaches a held-out error of "
                           f"{reference.error:.4f}, no better than {base.error:.4f} for all, "
                           "and no candidate improves the held-out score significantly"
                           f"{tail}; nothing added (the misfit of {ratio:.2f} x the noise "
                           "floor is the model family's, the same in every condition)")
        return Verdict("unexplained", None, "",
                       f"{head}; no candidate improves the held-out score significantly{tail}")
    best = _best_eligible(eligible, rule)
    frac = share(best)
    if not frac >= rule.min_explained:
        return Verdict(
            "unexplained", None, "",
            f"{head}; the best candidate explains too little (< "
            f"{100 * rule.min_explained:.0f} %): {_describe(best)}",
        )
    # (forms of the same effect, e.g. WLF and Arrhenius, are no rivals: the name is the same)
    rivals = [c for c in eligible if c.effect != best.effect
              and share(c) >= rule.min_explained
              and c.delta_bic - best.delta_bic < rule.ambiguity_margin]
    if rivals:
        return Verdict(
            "unexplained", None, "",
            f"{head}; ambiguous: {_describe(best)} and {_describe(rivals[0])} explain the "
            "residual about equally well",
        )
    runner = [c for c in fitted if c is not best]
    tail = (f"; next best {_describe(min(runner, key=lambda c: c.delta_bic))}"
            if runner else "")
    caveats = tuple(h.describe() for h in _added_hits(best))
    warn = ("; CAVEAT, fit on a bound: " + "; ".join(caveats)) if caveats else ""
    return Verdict("explained", best.effect, best.label,
                   f"{head}; {_describe(best)}; held-out error {base.error:.4f} -> "
                   f"{best.fit.error:.4f}{warn}{tail}", caveats)


def _conditions_agree(base: ModelFit, reference: SaturatedReference | None,
                      rule: DecisionRule) -> bool:
    """Whether every condition got its own fit and those fits do not lower the held-out
    residual power by ``rule.min_reference_gain``: no covariate law of the baseline's family
    can explain anything."""
    return (rule.agreeing_conditions_verdict and reference is not None
            and reference.n_fitted == reference.n_conditions
            and reference.rss_held > (1 - rule.min_reference_gain) * base.rss_held)


def _added_hits(c: CandidateScore) -> tuple:
    """The effect's own parameters of a candidate fit that ended on a bound."""
    return tuple(h for h in c.fit.bound_hits if h.added) if c.fit is not None else ()


def _capped_fractions(base: ModelFit, scores: list, sigma: float) -> list:
    """Explained fractions with the noise level capped by the best candidate's held-out RMS
    error (see ``DecisionRule.strict_consistency``)."""
    fits = [c.fit for c in scores if c.applicable and c.fit is not None]
    if not fits:
        return scores
    best_rms = min(np.sqrt(f.rss_held / f.n_held) for f in fits)
    capped = min(sigma, best_rms)
    out = []
    for c in scores:
        if c.applicable and c.fit is not None:
            _, _, frac = score_candidate(base, c.fit, capped)
            c = CandidateScore(c.effect, c.label, True, c.reason, c.fit, c.delta_bic, c.p_value,
                               frac, c.signature)
        out.append(c)
    return out


def _failed(effect: str, label: str, exc: Exception) -> CandidateScore:
    """A candidate whose start or fit failed: listed with the reason, never fatal."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return CandidateScore(effect, label, False, f"failed: {text}", None, np.nan, np.nan,
                          np.nan, "", failed=True)


def _fit_or_none(spec, obs, split):
    """fit_model, or the exception when the fit fails (numerical trouble of one candidate
    must not end the run: real data reach corners no generated set does)."""
    try:  # a spec that solves its linear parameters itself brings its own fit
        own = getattr(spec, "profiled_fit", None)
        fit = own(obs, split) if own is not None else fit_model(spec, obs, split)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return None, exc
    if not np.isfinite(fit.rss_held) or fit.rss_held <= 0 or not np.isfinite(fit.rss_train):
        return None, ValueError("the fit's residual is not finite")
    return fit, None


def _library(domain, base, features, per_condition=None):
    """The domain's library, with the covariate effects built from the laws of their
    per-condition fits when the domain offers them (``law_candidates``); when building it
    fails (an informed start on data no start rule foresaw), one failed entry instead."""
    try:
        out = list(domain.candidates(base, features))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return [_failed("library", "", exc)]
    laws = getattr(domain, "law_candidates", None)
    if laws is not None and per_condition is not None:
        try:
            out += list(laws(base, per_condition))
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            out.append(_failed("library", "laws", exc))
    return out


def _plausible(domain, obs, split, scores, specs, rule):
    """Each candidate that could be added (significant) checked for physical meaning
    (:mod:`.plausibility`); an implausible one is listed with the reason, not applicable."""
    out = []
    for c in scores:
        spec = specs.get((c.effect, c.label))
        if (c.applicable and spec is not None and c.p_value < rule.significance
                and c.delta_bic <= -rule.min_bic_gain):
            why, fit = plausibility.check(domain, spec, c.fit, obs, split,
                                          rule.significance)
            if why:
                c = replace(c, applicable=False, reason=f"implausible: {why}", fit=fit,
                            implausible=True)
        out.append(c)
    return out


def _candidates(domain, obs, split, base, features, noise, rule, progress, n_variants,
                reference=None, per_condition=None):
    """Fit and score every library entry (and the variants of the best) against ``base``;
    a candidate whose fit fails is listed as failed and the others go on; a significant one
    whose parameters mean nothing physically is listed as implausible."""
    scores, specs = [], {}
    for item in _library(domain, base, features, per_condition):
        if isinstance(item, CandidateScore):
            scores.append(item)
            continue
        if isinstance(item, NotApplicable):
            scores.append(CandidateScore(item.effect, item.label, False, item.reason, None,
                                         np.nan, np.nan, np.nan, ""))
            continue
        if progress:
            progress(item.effect + (f" ({item.label})" if item.label else ""))
        fit, exc = _fit_or_none(item, obs, split)
        if fit is None:
            scores.append(_failed(item.effect, item.label, exc))
            continue
        specs[(item.effect, item.label)] = item
        dbic, p, frac = score_candidate(base, fit, noise.sigma)
        scores.append(CandidateScore(item.effect, item.label, True, "", fit, dbic, p, frac,
                                     item.signature, achieved_fraction=achieved_fraction(
                                         base, fit, noise.sigma, reference)))
    # Promising candidates (lowest dBIC, significant) get their variants tried too.
    variants = getattr(domain, "variants", None)
    if variants is not None:
        # (only while they leave residual power above the noise: nothing to gain otherwise)
        ranked = sorted((c for c in scores if c.applicable and c.delta_bic < 0),
                        key=lambda c: c.delta_bic)[:n_variants]
        ranked = [c for c in ranked if c.fit.error > rule.consistency_ratio * noise.sigma]
        for c in ranked:
            try:
                forms = variants(specs[(c.effect, c.label)])
            except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                forms = []  # the candidate's own form stands
            for spec in forms:
                if progress:
                    progress(f"{spec.name}")
                fit, _ = _fit_or_none(spec, obs, split)
                if fit is None:
                    continue
                dbic, p, frac = score_candidate(base, fit, noise.sigma)
                if dbic < c.delta_bic:
                    i = scores.index(c)
                    c = CandidateScore(c.effect, c.label, True, "", fit, dbic, p, frac,
                                       c.signature, achieved_fraction=achieved_fraction(
                                           base, fit, noise.sigma, reference))
                    scores[i] = c
                    specs[(c.effect, c.label)] = spec
    if rule.strict_consistency:
        scores = _capped_fractions(base, scores, noise.sigma)
    scores = _plausible(domain, obs, split, scores, specs, rule)
    scores.sort(key=lambda c: (not c.applicable, c.delta_bic if c.applicable else 0.0))
    return scores, specs


def _consistent(base, noise, features, rule) -> bool:
    return (base.error <= rule.consistency_ratio * noise.sigma
            and features.whiteness.p_value >= rule.whiteness_alpha)


def choose_step(scores, rule) -> tuple[CandidateScore | None, str]:
    """The effect the loop adds next, or None and why it stops.

    The same held-out and significance rules as the verdict (F-test p < significance, dBIC <=
    -min_bic_gain, forms of one effect inside their bounds preferred, no rival *effect* that
    also explains >= min_explained within the ambiguity margin), except that the effect may
    explain only part of the excess (>= ``min_step_explained``): another effect may be hiding
    the rest, and the loop's next step tests that.
    """
    fitted = [c for c in scores if c.applicable and c.fit is not None]
    eligible = [c for c in fitted if c.p_value < rule.significance
                and c.delta_bic <= -rule.min_bic_gain]
    if not eligible:
        best = min(fitted, key=lambda c: c.delta_bic) if fitted else None
        tail = f" (best: {_describe(best)})" if best is not None else ""
        return None, f"no candidate improves the held-out score significantly{tail}"
    best = _best_eligible(eligible, rule)
    frac = share(best)
    if frac >= rule.min_explained:
        rivals = [c for c in eligible if c.effect != best.effect
                  and share(c) >= rule.min_explained
                  and c.delta_bic - best.delta_bic < rule.ambiguity_margin]
        if rivals:
            return None, (f"ambiguous: {_describe(best)} and {_describe(rivals[0])} explain the "
                          "residual about equally well")
    if not frac >= rule.min_step_explained:
        return None, (f"the best candidate explains too little (< "
                      f"{100 * rule.min_step_explained:.0f} % of the excess): {_describe(best)}")
    return best, ""


def run(domain: Domain, rule: DecisionRule | None = None, split: HoldoutSplit | None = None,
        progress: Callable[[str], None] | None = None, n_variants: int = 2,
        noise: NoiseFloor | None = None) -> DiscrepancyResult:
    """Run the discrepancy loop on a domain.

    Parameters
    ----------
    domain : Domain
    rule : DecisionRule, optional
    split : HoldoutSplit, optional
        Default :func:`holdout_split` with every 4th point held out.
    progress : callable, optional
        Called with a short text before each fit (progress bars live in the CLI).
    n_variants : int
        How many of the best candidates get the domain's variants tried.
    noise : NoiseFloor, optional
        The noise measured by the test (replicates, coherence: :mod:`.noise_sources`); the
        verdict then uses it at every step instead of the second-difference floor.

    Returns
    -------
    DiscrepancyResult
    """
    rule = rule or DecisionRule()
    obs = domain.observations
    split = split or holdout_split(obs.groups)
    if split.train.shape != obs.values.shape or split.held.sum() < 5:
        raise ValueError("split must have the observations' shape and >= 5 held-out points")
    if progress:
        progress("baseline")
    base_spec = domain.baseline(split.train)
    base = fit_model(base_spec, obs, split)
    measured = noise
    features = _features(obs, base, None if measured is None else measured.sigma)
    noise = measured or with_known_noise(
        domain, replace(features.noise, method=f"{features.noise.method}, of the residual of "
                                               f"{base.name}"))
    # (a domain whose groups are no test conditions of a covariate says so)
    reference = None
    if getattr(domain, "per_condition_reference", True):
        if progress:
            progress("per-condition reference")
        reference = saturated_reference(base_spec, obs, split, base, domain)
    used = (reference is not None
            and reference.rss_held <= (1 - rule.min_reference_gain) * base.rss_held)
    per_condition = reference if rule.covariate_laws else None
    scores, specs = _candidates(domain, obs, split, base, features, noise, rule, progress,
                                n_variants, reference if used else None, per_condition)
    verdict = decide(base, noise, features, scores, rule, reference)
    steps, final = (), None
    if hasattr(domain, "augment"):
        steps, final, last = _iterate(domain, obs, split, base, features, noise, scores, specs,
                                      rule, progress, n_variants, reference if used else None,
                                      measured is not None, per_condition)
        if last is not noise:  # one floor per report: the lowest estimate, for every ratio
            noise = last
            features = _features(obs, base, noise.sigma)
            scores, steps = _rescored(base, scores, steps, noise.sigma,
                                      reference if used else None)
            verdict = decide(base, noise, features, scores, rule, reference)
        verdict = _loop_verdict(verdict, steps, final, rule.joint_ratio,
                                reference if used else None)
    odd = [c for c in scores if c.implausible]
    if odd:  # the first step's significant candidates that mean nothing physically
        verdict = replace(verdict, evidence=verdict.evidence + "; listed implausible, never "
                          "added: " + "; ".join(f"{c.effect}" + (f" ({c.label})" if c.label
                                                                 else "")
                                                + f" (held-out error {c.fit.error:.4f}, dBIC "
                                                  f"{c.delta_bic:.1f})" for c in odd))
    augmented = aug_features = None
    if verdict.status == "explained":
        chosen = (steps[0].fit if steps else
                  next(c for c in scores if c.applicable and c.effect == verdict.effect
                       and c.label == verdict.label).fit)
        augmented = chosen
        aug_features = _features(obs, augmented, noise.sigma)
    # a domain whose weights are not plain 1/|y| states its own definition
    definition = getattr(domain, "error_definition", ERROR_DEFINITION)
    return DiscrepancyResult(domain.name, split, base, noise, features, tuple(scores), verdict,
                             augmented, aug_features, rule, definition, tuple(steps), final,
                             reference, used, tuple(getattr(domain, "trends", ())),
                             tuple(moving_parameters(reference, rule.significance)))


def with_known_noise(domain, floor: NoiseFloor) -> NoiseFloor:
    """``floor`` with the noise the domain knows its residual holds beyond what second
    differences see (``domain.known_noise``: (sigma, why), e.g. the flight domain's
    resolution of the logged airspeed and c2 in a noise-free log) added in quadrature."""
    known = getattr(domain, "known_noise", None)
    if not known or not known[0] > 0:
        return floor
    sigma, why = known
    part = sigma / np.sqrt(2.0)  # split evenly between the real and imaginary parts
    return replace(floor, sigma=float(np.hypot(floor.sigma, sigma)),
                   sigma_real=float(np.hypot(floor.sigma_real, part)),
                   sigma_imag=float(np.hypot(floor.sigma_imag, part)),
                   method=f"{floor.method}; with {sigma:.4g} added in quadrature: {why}")


def _iterate(domain, obs, split, base, features, noise, scores, specs, rule, progress,
             n_variants, reference=None, measured=False, per_condition=None):
    """Add effects one at a time (:func:`choose_step`) until the residual is consistent with
    the noise, nothing in the library explains the rest, or ``rule.max_steps`` is reached."""
    steps = []
    while True:
        if _consistent(base, noise, features, rule):
            status = "consistent"
            reason = (f"held-out error {base.error:.4f} <= {rule.consistency_ratio:g} x the noise "
                      f"floor {noise.sigma:.4f} and a white residual (Ljung-Box p = "
                      f"{features.whiteness.p_value:.2g})")
            break
        if steps:  # the candidates on the new baseline, only when they can be used
            scores, specs = _candidates(domain, obs, split, base, features, noise, rule,
                                        progress, n_variants, reference, per_condition)
        choice, reason = choose_step(scores, rule)
        if choice is None:
            status = "stopped"
            break
        if len(steps) == rule.max_steps:
            status, reason = "stopped", f"reached the limit of {rule.max_steps} steps"
            break
        domain.augment(specs[(choice.effect, choice.label)], choice.fit)
        steps.append(Step(choice.effect, choice.label, choice.fit.name, base.error,
                          choice.fit.error, noise.sigma, choice.delta_bic, choice.p_value,
                          choice.explained_fraction, choice.fit,
                          tuple(h.describe() for h in _added_hits(choice)),
                          choice.achieved_fraction))
        if progress:
            progress(f"step {len(steps) + 1}")
        base = choice.fit
        # The noise floor is a property of the data; its second-difference estimate can only
        # be inflated by model error that is not smooth at the sampling (sparse sweeps), so
        # each step keeps the lowest estimate so far.
        # (a noise measured by replicates or coherence stays as it is)
        fresh = with_known_noise(domain, _features(obs, base).noise)
        if fresh.sigma < noise.sigma and not measured:
            noise = replace(fresh, method=f"{fresh.method}, of the residual of {base.name} "
                                          "(the lowest estimate of the models fitted)")
        features = _features(obs, base, noise.sigma)
    final = LoopOutcome(status, reason, base.name, base.error, noise.sigma,
                        tuple((s.effect, s.label) for s in steps), base)
    return steps, final, noise


def _rescored(base, scores, steps, sigma, reference):
    """The first step's candidates and every step scored again against one noise floor
    ``sigma`` (the fits do not depend on it, only the shares of the excess do)."""
    out = []
    for c in scores:
        if c.applicable and c.fit is not None:
            _, _, frac = score_candidate(base, c.fit, sigma)
            c = replace(c, explained_fraction=frac,
                        achieved_fraction=achieved_fraction(base, c.fit, sigma, reference))
        out.append(c)
    again, before = [], base
    for st in steps:
        _, _, frac = score_candidate(before, st.fit, sigma)
        again.append(replace(st, noise_before=sigma, explained_fraction=frac,
                             achieved_fraction=achieved_fraction(before, st.fit, sigma,
                                                                 reference)))
        before = st.fit
    return out, tuple(again)


def _loop_verdict(first: Verdict, steps, final, joint_ratio: float,
                  reference: SaturatedReference | None = None) -> Verdict:
    """The first step's verdict, unless no single effect explained enough but the effects
    added in turn left a residual consistent with the noise or within ``joint_ratio`` x the
    floor (then explained, naming the first; all are in ``steps``). The floor is the noise
    floor, or the saturated reference's error when that is higher and a covariate effect
    was added (what a covariate can explain at all)."""
    names = ", ".join(s.effect + (f" ({s.label})" if s.label else "") for s in steps)
    if first.status == "explained" or not steps:
        tail = (f"; the loop then added {names} and stopped: {final.reason}"
                if len(steps) > 1 else "")
        return Verdict(first.status, first.effect, first.label, first.evidence + tail,
                       first.caveats)
    floor, what = final.noise, "the noise floor"
    if (reference is not None and reference.error > floor
            and any(s.effect in COVARIATE_EFFECTS for s in steps)):
        floor, what = reference.error, "the per-condition fits' held-out error"
    if final.status == "consistent" or final.error <= joint_ratio * floor:
        caveats = tuple(c for s in steps for c in s.caveats)
        return Verdict("explained", steps[0].effect, steps[0].label,
                       f"{first.evidence}; no single effect explains the residual, but {names} "
                       f"added in turn leave a held-out error of {final.error:.4f} = "
                       f"{final.error / floor:.2f} x {what} {floor:.4f}: {final.reason}",
                       caveats)
    return Verdict(first.status, None, "",
                   f"{first.evidence}; the loop added {names} and stopped without reaching "
                   f"the noise: {final.reason}")
