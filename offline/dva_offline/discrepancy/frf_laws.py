"""The FRF domain's covariate effects with laws found from their per-condition fits (a mixin
of :class:`~dva_offline.discrepancy.frf_domain.FrfDomain`; the method is in :mod:`.laws`).

The Maxwell parameters of a mount fitted to each condition alone trade with one another (an
element's spring against its damper, two elements with near corners), so their values per
condition say little about a law. The effect's own coordinates do: the reference condition's
own mount is held, and each condition alone is fitted with only

* ``amplitude_dependence`` (a level): its storage part Re K and loss part Im K scaled by a
  factor each (what the library's log law scales by 1 + s ln(a / a_0));
* ``covariate_shift`` (not a level): its frequency axis scaled by a_T (what WLF and
  Arrhenius give).

Those factors with their standard errors are the trend the laws are fitted to; the chosen
laws make one model (label ``COVARIATE, law``) started at the reference condition's own
mount and the laws' fitted values, refined by the loop's joint fit of the whole data.
"""
from __future__ import annotations

from dataclasses import replace
from functools import partial

import numpy as np

from dva_offline.discrepancy import laws
from dva_offline.discrepancy.covariate_kinds import is_level
from dva_offline.discrepancy.fitting import (
    HoldoutSplit,
    ModelFit,
    ModelSpec,
    NotApplicable,
    ParamSpec,
    fit_model,
)
from dva_offline.discrepancy.frf_terms import Term, absolute_temperature, compose, log_shift
from dva_offline.discrepancy.maxwell_starts import maxwell_from_stiffness

COORDINATES = {"amplitude_dependence": ("storage", "loss"), "covariate_shift": ("shift",)}
STAGE = {"amplitude_dependence": "level", "covariate_shift": "shift"}


class FrfLaws:
    """Law candidates of the FRF domain (methods of :class:`FrfDomain`)."""

    _law_inputs = None
    trends: list = []

    def _effects_of(self, name, col) -> list[str]:
        """The covariate effects the library offers on this covariate (:mod:`.frf_library`)."""
        out = []
        if absolute_temperature(name, col) is None and np.all(col > 0):
            out.append("amplitude_dependence")
        # (a material's shift: the Prony spectrum's per-condition forms, :mod:`.frf_spectrum`;
        # a reference mount of three elements cannot follow a master curve across decades)
        if not (is_level(name) and np.all(col > 0)) and not self.modulus:
            out.append("covariate_shift")
        return out

    def _condition_factors(self, values, n, effect, g):
        """The effect's factors of condition ``g`` alone, the mount held at ``values``:
        (factors, standard errors), or None when the fit fails."""
        obs = self.observations
        m, k, c, ks, cs, _ = self._unpack(values, n)
        which = COORDINATES[effect]
        cov = laws.Covariate("condition", 0.0, None, (0.0, 1.0), 0.0, 1.0)
        term = Term(effect, "", STAGE[effect], len(which), "law",
                    {"coords": [(w, "free", 1) for w in which], "x": np.zeros(obs.axis.size),
                     "cov": cov, "level_index": np.zeros(obs.axis.size, dtype=int)})
        maxwell = partial(self._stiffness, k, c, ks, cs)

        def predict(v):
            return compose(maxwell, [term], [v], self.omega, m, self.quantity)

        if effect == "covariate_shift":
            params = (ParamSpec("a_T", "-", 1.0, 1e-12, 1e12, log=True),)
            starts = tuple(np.array([10.0**e]) for e in np.linspace(-4, 4, 17))
        else:
            params = tuple(ParamSpec(w, "-", 1.0, np.exp(-4), np.exp(4), log=True)
                           for w in which)
            starts = ()
        spec = ModelSpec(f"condition {g}", None, params, 0, predict, starts)
        sel = obs.groups == g
        split = HoldoutSplit(self._train & sel, ~self._train & sel, f"condition {g}")
        if split.train.sum() < 2 * len(params) or not split.held.any():
            return None
        try:
            fit = fit_model(spec, obs, split, n_screen=4)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
        return (np.array([e.value for e in fit.estimates]),
                np.array([e.std for e in fit.estimates]))

    def _law_trends(self, reference) -> list:
        """Per covariate and effect: its coordinates per condition and their laws
        (module docstring); computed once, on the first step's baseline."""
        if self._law_inputs is not None:
            return self._law_inputs
        obs = self.observations
        g = obs.groups
        labels = [int(x) for x in np.unique(g)]
        ref_values = getattr(self, "_reference_values", None)
        out = []
        n = self._setup["n"]
        if ref_values is not None and len(labels) >= 2:
            for name, col in self._varying().items():
                kelvin = absolute_temperature(name, col)
                offset = None if kelvin is None else float(np.mean(kelvin - col))
                cov = laws.covariate_info(name, col, g, self.reference, offset)
                x = np.array([col[g == lab].mean() for lab in labels])
                for effect in self._effects_of(name, col):
                    per = [self._condition_factors(ref_values, n, effect, lab)
                           for lab in labels]
                    trends = []
                    for i, which in enumerate(COORDINATES[effect]):
                        y = np.array([p[0][i] if p is not None else np.nan for p in per])
                        s = np.array([p[1][i] if p is not None else np.nan for p in per])
                        t = laws.find_law(effect, cov, which, (which,), x, y, s)
                        if t is not None:
                            trends.append(t)
                    out.append((name, effect, cov, trends))
        self._law_inputs = out
        self.trends = [t for *_, ts in out for t in ts]
        return out

    def law_candidates(self, baseline: ModelFit, reference) -> list:
        """Each covariate effect built from the laws of its moving coordinates (label
        ``COVARIATE, law``), on the current baseline."""
        if self._spectrum:  # a master curve's Prony spectrum chooses its own shift forms
            return []
        self._law_trends(reference)
        return self._law_specs([self._base_values], self._setup["n"])

    def _law_specs(self, bases, n, extra=0, only=None) -> list:
        """The law candidates on Maxwell order ``n`` started at ``bases`` (``extra``: added
        parameters besides the laws', e.g. one more element; ``only``: (effect, label))."""
        out = []
        present = {(t.effect, t.label.partition(", ")[0]) for t in self._stack
                   if t.effect not in ("maxwell_element", "foundation_mode")}
        g = self.observations.groups
        for name, effect, cov, trends in self._law_inputs or ():
            label = f"{name}, law"
            if (effect, name) in present or only not in (None, (effect, label)):
                continue
            moving = [t for t in trends if t.moving]
            if not moving:
                out.append(NotApplicable(effect, f"no {' or '.join(COORDINATES[effect])} "
                                                 f"factor moves with {name} beyond its errors",
                                         label))
                continue
            coords, added, parts = [], [], []
            for t in moving:
                sc = t.chosen
                specs = laws.param_specs(t.law, cov, sc.theta if sc is not None else (),
                                         t.coordinate, name)
                coords.append((t.coordinate, t.law, len(specs)))
                added += specs
                parts.append(laws.LawPart(t.coordinate, t.law, tuple(p.name for p in specs)))
            col = self.observations.covariates[name]
            means = np.array([col[g == lab].mean() for lab in range(len(self.conditions))])
            term = Term(effect, label, STAGE[effect], len(added), "law",
                        {"coords": coords, "x": col, "cov": cov,
                         "level_index": cov.level_index(means[g])})
            init = np.array([p.initial for p in added])
            priority = []
            ref_values = self._reference_start(n, bases[0].size)
            if ref_values is not None:
                priority.append(np.concatenate([ref_values, init]))
            spec = self._spec(effect, tuple(added), term, bases, n, (), label, extra,
                              priority)
            law = laws.LawModel(effect, cov, tuple(parts),
                                tuple(t.coordinate for t in trends if not t.moving))
            out.append(replace(spec, law=law))
        return out

    def condition_model(self, spec: ModelSpec, start: np.ndarray):
        """The baseline for one condition fitted alone (the saturated reference), and its
        start from the pooled fit: with the static stiffness free when it was given, since
        a level effect scales it with the rest of the storage part (the mass stays: an
        inertia does not depend on a covariate)."""
        s = self._setup
        if s["free_k"] or self._stack:
            return spec, start
        i = 1 if s["free_m"] else 0
        n = s["n"]

        def predict(v):
            m, _, c, ks, cs, _ = self._unpack(np.delete(v, i, axis=0), n)
            return compose(partial(self._stiffness, v[i], c, ks, cs), [], [], self.omega, m,
                           self.quantity)

        k = s["k"]
        params = (*spec.params[:i], ParamSpec("k", self.units["k"], k, 1e-3 * k, 1e3 * k,
                                              log=True), *spec.params[i:])
        return (ModelSpec(spec.name, None, params, 0, predict,
                          batch_predict=lambda vs: predict(np.asarray(vs, float).T[..., None])),
                np.insert(start, i, k))

    def condition_starts(self, points) -> list:
        """A start for the baseline fitted to one condition alone (the saturated reference,
        in :meth:`condition_model`'s parameters): the corner-grid search on its training
        points (the pooled fit is a compromise between the conditions, a local minimum for
        each of them)."""
        if self._stack or self._setup is None:
            return []
        s = self._setup
        m = float(s["refined"][s["n"]][0]) if s["free_m"] else s["m"]
        w, kapp, d = self._apparent_stiffness(m, points)
        fit = maxwell_from_stiffness(w, kapp, d, s["n"], None)
        if fit is None:
            return []
        k, c, ks, cs, _ = fit
        return [np.array([*[m] * s["free_m"], k, c, *ks, *cs])]

    def _reference_start(self, n, size):
        """The reference condition's own mount of order ``n`` (the laws are normalised
        there): its fit from the first step, or, for another order, the corner-grid search
        on its training points; None without it or with effects stacked."""
        ref = getattr(self, "_reference_values", None)
        if self._stack:
            return None
        if ref is not None and ref.size == size:
            return ref
        points = self._train & (self.observations.groups == self.reference)
        m = self._setup["m"]
        if self._setup["free_m"] and ref is not None:
            m = float(ref[0])
        start = self._grid_start(points, n, m)
        return start if start is not None and start.size == size else None

    def implausible(self, spec: ModelSpec, fit: ModelFit) -> str:
        """A shift of the frequency axis larger than the data can determine: two conditions
        next to each other in the covariate whose shifted sweeps no longer overlap (the
        shift between them then rests on the model's extrapolation alone)."""
        entry = self._term_of.get(spec.name)
        if entry is None or entry[0].stage != "shift":
            return ""
        term = entry[0]
        values = np.array([e.value for e in fit.estimates])
        size = term.size
        shift = log_shift(term, values[len(values) - size:])
        obs = self.observations
        name = term.label.partition(", ")[0]
        col = obs.covariates.get(name)
        if col is None:
            return ""
        rows = []
        for lab in np.unique(obs.groups):
            sel = obs.groups == lab
            f = obs.axis[sel]
            la = float(shift[sel].mean())
            rows.append((float(col[sel].mean()), np.log10(f.min()) + la,
                         np.log10(f.max()) + la, la))
        rows.sort()
        for (x1, lo1, hi1, a1), (x2, lo2, hi2, a2) in zip(rows, rows[1:]):
            if min(hi1, hi2) - max(lo1, lo2) <= 0:
                return (f"the shift between {name} = {x1:.4g} and {x2:.4g} is "
                        f"{abs(a2 - a1):.3g} decades, more than the sweeps span (they no longer "
                        "overlap): a shift the data cannot determine")
        return ""
