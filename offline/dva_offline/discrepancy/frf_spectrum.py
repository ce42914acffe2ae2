"""Materials in the FRF domain: the relaxation spectrum as a Prony series, with the shift form
re-selected each time the spectrum grows (a mixin of
:class:`~dva_offline.discrepancy.frf_domain.FrfDomain`).

Once the loop has added a temperature (or other covariate) shift to a material's modulus, the
Maxwell elements added one per step are a slow way to span the 15-25 decades of reduced
frequency of a master curve. Offered then, as forms of ``maxwell_element``: the spectrum
replaced by a Prony series with fixed log-spaced time constants (:mod:`.prony_spectrum`, two
per decade; once taken, three per decade is offered next), each with every shift form: WLF,
Arrhenius (temperatures) and a free shift per condition. The moduli are solved non-negative
for each shift (variable projection): only the shift parameters are searched. The form is
chosen by the loop's held-out score like any form of an effect, so the shift chosen at step 1
on a three-element spectrum (where WLF may end on its C2 bound because the spectrum cannot span
the curve) is reconsidered on a spectrum that can.

Parameter count in the scores: the non-zero moduli (the others sit on their bound 0) plus the
shift parameters, against the model of the step before (counted as at least one added); the
effect's parameters reported with the step are the shift's.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from dva_offline.discrepancy.fitting import (
    Estimate,
    HoldoutSplit,
    ModelFit,
    ModelSpec,
    NotApplicable,
    Observations,
    ParamSpec,
    fit_model,
)
from dva_offline.discrepancy.frf_terms import R_GAS, SIGNATURES, absolute_temperature, log_shift
from dva_offline.discrepancy.prony_spectrum import (
    free_shift_values,
    nonnegative_moduli,
    pairwise_shifts,
    prony_columns,
    relaxation_times,
)

DENSITIES = (2.0, 3.0)  # time constants per decade: the first spectrum, then its growth
OUTER_ROUNDS = 2  # refits with the time-constant grid following the fitted shift


@dataclass(frozen=True)
class ProfiledSpec(ModelSpec):
    """A model whose linear parameters are solved inside its own fit: the loop calls
    ``profiled_fit(obs, split)`` instead of :func:`fit_model`."""

    profiled_fit: Callable[[Observations, HoldoutSplit], ModelFit] | None = None


@dataclass(frozen=True)
class ShiftForm:
    """One shift law: parameters, log10 a_T at every point and, with a vertical factor,
    log10 b_T at every point (``vertical`` its form's name, ``n_shift`` the parameters of the
    horizontal law, the vertical ones after them)."""

    form: str
    params: tuple[ParamSpec, ...]
    log_shift: Callable[[np.ndarray], np.ndarray]
    starts: tuple[np.ndarray, ...]
    vertical: str = ""
    log_vertical: Callable[[np.ndarray], np.ndarray] | None = None
    n_shift: int = -1

    def label(self) -> str:
        return self.form + (f" + vertical {self.vertical}" if self.vertical else "")

    def factors(self, v) -> tuple[np.ndarray, np.ndarray | None]:
        """log10 a_T and log10 b_T (None without a vertical factor) at every point."""
        if self.log_vertical is None:
            return self.log_shift(v), None
        return self.log_shift(v[:self.n_shift]), self.log_vertical(v[self.n_shift:])


class SpectrumLibrary:
    """Prony-spectrum candidates and per-condition shift factors (methods of FrfDomain)."""

    def _spectrum_ready(self) -> str:
        """Why the Prony candidates are not offered (empty when they are)."""
        if not getattr(self, "modulus", False):
            return "only for a material's modulus (--quantity modulus)"
        if getattr(self, "_spectrum", None):
            return ""
        stages = {t.stage for t in self._stack}
        if "shift" not in stages:
            return "needs a shift along the frequency axis in the model (a covariate shift)"
        if not stages <= {"shift", "element"}:
            return "the model holds effects other than the shift and relaxation elements"
        return ""

    def _current_log_shift(self) -> tuple[str, np.ndarray]:
        """The shifted covariate's name and the model's log10 a_T at every point."""
        if getattr(self, "_spectrum", None):
            return self._spectrum["covariate"], self._spectrum["log_shift"]
        start = len(self._base_values) - self._stack_size()
        total, name, i = np.zeros(self.omega.size), "", 0
        for t in self._stack:
            if t.stage == "shift":
                total = total + log_shift(t, self._base_values[start + i: start + i + t.size])
                name = t.label.partition(", ")[0]
            i += t.size
        return name, total

    def _shift_forms(self, name: str, current: np.ndarray) -> list[ShiftForm]:
        obs = self.observations
        col = obs.covariates[name]
        groups = obs.groups
        ref = float(col[groups == self.reference].mean())
        dt = col - ref
        forms = []
        c2_min = float(max(-dt.min(), 0.0)) + 1.0
        # a second start for every form: each sweep shifted onto its neighbour (the manual
        # construction of a master curve), independent of the shift fitted before
        labels = np.unique(groups)
        pair_g = pairwise_shifts(np.log10(obs.axis), np.log10(np.abs(obs.values)), groups, col,
                                 self.reference)
        pair = pair_g[np.searchsorted(labels, groups)]

        def wlf(v):
            return -v[0] * v[1] * dt / (v[1] + dt)

        # start at the WLF law closest to the current shift (and a few others)
        wlf_grid = [np.array([b, c]) for b in (0.02, 0.05, 0.1)
                    for c in (max(100.0, 2 * c2_min), 300.0)]
        wlf_bounds = ([-1.0, c2_min], [1.0, 1e4])
        fitted = _closest(wlf, current, wlf_grid, wlf_bounds)
        forms.append(ShiftForm("WLF", (
            ParamSpec("b", "1/K", float(fitted[0]), -1.0, 1.0, scale=0.02,
                      at_lower="the shift slope is at its limit -1 /K",
                      at_upper="the shift slope is at its limit 1 /K"),
            ParamSpec("C2", "K", float(fitted[1]), c2_min, 1e4, log=True,
                      at_lower=f"the WLF singularity T_inf = T0 - C2 sits just below the lowest "
                               f"level ({ref - c2_min + 1:.4g}): the shift diverges there",
                      at_upper="C2 -> infinity: the WLF law degenerates to a shift linear in "
                               "the covariate")),
            wlf, (_closest(wlf, pair, wlf_grid, wlf_bounds),)))
        kelvin = absolute_temperature(name, col)
        if kelvin is not None:
            t_ref = float(kelvin[groups == self.reference].mean())
            inv = 1.0 / kelvin - 1.0 / t_ref

            def arrhenius(v):
                return v[0] / (R_GAS * np.log(10.0)) * inv

            ea = _closest(arrhenius, current, [np.array([1e5])], ([1e3], [5e6]))
            forms.append(ShiftForm("Arrhenius", (
                ParamSpec("E_a", "J/mol", float(ea[0]), 1e3, 5e6, log=True,
                          at_lower="no measurable thermal activation (E_a -> 0)",
                          at_upper="an activation energy above 5 MJ/mol"),), arrhenius,
                (_closest(arrhenius, pair, [np.array([1e5])], ([1e3], [5e6])),)))
        others = labels != self.reference
        means = np.array([current[groups == g].mean() for g in labels[others]])
        span = max(10.0, 3 * float(np.max(np.abs(np.concatenate([means, pair_g])))))
        forms.append(ShiftForm("per condition", tuple(
            ParamSpec(f"log_aT_{g}", "-", float(m), -span, span, scale=1.0)
            for g, m in zip(labels[others], means)),
            lambda v: free_shift_values(groups, self.reference, v), (pair_g[others],)))
        return forms

    def _vertical_forms(self, name: str, form: ShiftForm) -> list[ShiftForm]:
        """``form`` with the vertical factor of time-temperature superposition, b_T, in its
        two forms: the physical one, b_T = T rho(T) / (T_ref rho_ref) with rho(T) / rho_ref =
        1 - alpha (T - T_ref) (alpha the volumetric thermal expansion, 0-2e-3 /K), and free,
        one log10 b_T per condition (the reference condition's at 0). A temperature only."""
        obs = self.observations
        col, groups = obs.covariates[name], obs.groups
        kelvin = absolute_temperature(name, col)
        if kelvin is None:
            return []
        t_ref = float(kelvin[groups == self.reference].mean())
        ratio, dt = kelvin / t_ref, kelvin - t_ref
        n = len(form.params)
        labels = np.unique(groups)
        others = labels != self.reference

        def density(v):
            return np.log10(ratio * (1.0 - v[0] * dt))

        alpha = ParamSpec("alpha", "1/K", 6e-4, 0.0, 2e-3, scale=1e-4,
                          at_lower="no thermal expansion: b_T = T / T_ref",
                          at_upper="a thermal expansion above 2e-3 /K (no polymer melt has it)")
        free = tuple(ParamSpec(f"log_bT_{g}", "-", 0.0, -0.5, 0.5, scale=0.01,
                               at_lower="a vertical factor below 1/3",
                               at_upper="a vertical factor above 3") for g in labels[others])
        starts = tuple(np.r_[s, 0.0 * np.ones(len(free))] for s in form.starts)
        return [
            replace(form, params=form.params + (alpha,), vertical="T rho",
                    log_vertical=density, n_shift=n,
                    starts=tuple(np.r_[s, a] for s in form.starts for a in (0.0, 6e-4))),
            replace(form, params=form.params + free, vertical="per condition",
                    log_vertical=lambda v: free_shift_values(groups, self.reference, v),
                    n_shift=n, starts=starts)]

    def _spectrum_library(self, base_n_params: int) -> list:
        """The Prony candidates of this step, or a NotApplicable saying why there are none."""
        why = self._spectrum_ready()
        if why:
            return [NotApplicable("maxwell_element", f"Prony spectrum: {why}", "Prony spectrum")]
        now = getattr(self, "_spectrum", None)
        done = now["per_decade"] if now else 0.0
        denser = [d for d in DENSITIES if d > done]
        name, current = self._current_log_shift()
        vertical = now.get("vertical", "") if now else ""
        out = []
        if not denser:
            out.append(NotApplicable("maxwell_element", "Prony spectrum: already at "
                                     f"{done:g} time constants per decade", "Prony spectrum"))
        for per_decade in denser[:1]:
            for form in self._shift_forms(name, current):
                if vertical:  # the vertical factor found before stays, in its form
                    form = next(f for f in self._vertical_forms(name, form)
                                if f.vertical == vertical)
                out.append(self._prony_candidate("maxwell_element", name, form, per_decade,
                                                 current, base_n_params))
        if now and not vertical:
            # time-temperature superposition's vertical factor on the spectrum as it is,
            # beside its horizontal shift (both refitted): a form of the covariate shift
            form = next(f for f in self._shift_forms(name, current) if f.form == now["form"])
            out += [self._prony_candidate("covariate_shift", name, v, done, current,
                                          base_n_params)
                    for v in self._vertical_forms(name, form)]
        return out

    def _prony_candidate(self, effect, name, form, per_decade, current, base_n_params):
        label = f"{name}, Prony spectrum {per_decade:g}/decade + {form.label()}"
        spec_name = f"prony({per_decade:g}/decade) + covariate_shift({name}, {form.label()})"
        spec = ProfiledSpec(spec_name, effect, form.params, len(form.params),
                            lambda v: v, signature=SIGNATURES[effect], label=label)
        return replace(spec, profiled_fit=self._make_fitter(
            spec, form, per_decade, name, current, base_n_params))

    def _make_fitter(self, spec, form, per_decade, name, current, base_n_params):
        def fitter(obs, split):
            return self._fit_spectrum(spec, form, per_decade, name, current, base_n_params,
                                      obs, split)
        return fitter

    def _fit_spectrum(self, spec, form, per_decade, name, current, base_n_params, obs, split):
        """Variable projection: the shift parameters by :func:`fit_model`, the moduli by
        non-negative least squares on the training points for each shift; the grid of time
        constants follows the fitted shift for ``OUTER_ROUNDS`` rounds."""
        w, y, wt, train = self.omega, obs.values, obs.weights, split.train
        f = self.observations.axis
        params, shift = form.params, current
        fit = None
        for _ in range(OUTER_ROUNDS):
            taus = relaxation_times(np.log10(f * 10.0**shift), per_decade)

            def predict(v, taus=taus):
                log_a, log_b = form.factors(v)
                cols = prony_columns(w * 10.0**log_a, taus)
                if log_b is not None:  # the modulus scaled by b_T at every point
                    cols = cols * 10.0**log_b[:, None]
                return cols @ nonnegative_moduli(cols, y, wt, train)

            inner = ModelSpec(spec.name, "maxwell_element", params, len(params), predict,
                              form.starts,
                              batch_predict=lambda vs, p=predict: np.array([p(v) for v in vs]))
            fit = fit_model(inner, obs, split, n_screen=4)
            values = np.array([e.value for e in fit.estimates])
            shift, vertical = form.factors(values)
            params = tuple(replace(p, initial=float(np.clip(v, p.lower, p.upper)))
                           for p, v in zip(params, values))
        cols = prony_columns(w * 10.0**shift, taus)
        if vertical is not None:
            cols = cols * 10.0**vertical[:, None]
        moduli = nonnegative_moduli(cols, y, wt, train)
        unit_k = self.units["k"]
        active = np.nonzero(moduli[1:] > 0)[0]
        estimates = [Estimate("k_inf", unit_k, float(moduli[0]), np.nan)]
        estimates += [Estimate(f"k(tau={taus[i]:.3g} s)", unit_k, float(moduli[1 + i]), np.nan)
                      for i in active]
        estimates += list(fit.estimates)
        count = int(np.clip(len(estimates) - base_n_params, 1, len(estimates)))
        self._spectrum_fits[spec.name] = dict(
            per_decade=per_decade, covariate=name, form=form.form, log_shift=shift,
            taus=taus, moduli=moduli, vertical=form.vertical, log_vertical=vertical)
        return replace(fit, name=spec.name, label=spec.label, estimates=tuple(estimates),
                       n_added=len(form.params), count_added=count)

    def _augment_spectrum(self, spec) -> bool:
        """Take a Prony candidate as the model of the next step (True if ``spec`` is one)."""
        if not isinstance(spec, ProfiledSpec):
            return False
        self._spectrum = self._spectrum_fits[spec.name]
        return True

    def shift_factors(self, fit: ModelFit) -> dict | None:
        """log10 a_T of ``fit`` per condition (the mean over its points), with the covariate's
        level of each condition; None when the model has no shift."""
        done = self._spectrum_fits.get(fit.name) if hasattr(self, "_spectrum_fits") else None
        vertical = None
        if done is not None:
            name, shift, form = done["covariate"], done["log_shift"], done["form"]
            if done.get("vertical"):
                vertical = done["log_vertical"]
                form = f"{form} + vertical {done['vertical']}"
        else:
            shifts = [t for t in self._stack if t.stage == "shift"]
            if not shifts:
                return None
            values = np.array([e.value for e in fit.estimates])
            start, i, shift = len(values) - self._stack_size(), 0, np.zeros(self.omega.size)
            for t in self._stack:
                if t.stage == "shift":
                    shift = shift + log_shift(t, values[start + i: start + i + t.size])
                i += t.size
            name, _, form = shifts[-1].label.partition(", ")
            form = form or "WLF"
        obs = self.observations
        col = obs.covariates[name]
        rows = [{"condition": int(g), "level": float(col[obs.groups == g].mean()),
                 "log10_aT": float(shift[obs.groups == g].mean()),
                 "b_T": 1.0 if vertical is None else float(
                     10.0 ** vertical[obs.groups == g].mean())}
                for g in np.unique(obs.groups)]
        return {"covariate": name, "form": form,
                "reference_level": float(col[obs.groups == self.reference].mean()),
                "vertical": vertical is not None, "per_condition": rows}


def _closest(law, target, starts, bounds) -> np.ndarray:
    """Parameters of a shift law closest to ``target`` (log10 a_T per point), within bounds:
    the start of that form from the shift the model had before."""
    best = None
    for s in starts:
        try:
            r = least_squares(lambda v: law(v) - target, np.clip(s, *bounds), bounds=bounds)
        except ValueError:
            continue
        if np.all(np.isfinite(r.x)) and (best is None or r.cost < best.cost):
            best = r
    return np.clip(starts[0], *bounds) if best is None else best.x
