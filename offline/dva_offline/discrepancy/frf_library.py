"""The FRF domain's candidate library and its informed starting values (a mixin of
:class:`~dva_offline.discrepancy.frf_domain.FrfDomain`, split out for size).

Each library entry is the current baseline (Maxwell order n plus the effects the loop added)
with one more :class:`~dva_offline.discrepancy.frf_terms.Term`; the table of effects and their
signatures is in :mod:`.frf_domain`'s docstring. Starts that do not inherit the baseline's
distortion come from the global searches of :mod:`.maxwell_starts`.
"""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy.covariate_kinds import is_level
from dva_offline.discrepancy.fitting import ModelSpec, NotApplicable, ParamSpec
from dva_offline.discrepancy.frf_terms import Term, absolute_temperature
from dva_offline.discrepancy.maxwell_starts import (
    maxwell_from_stiffness,
    modal_term_scan,
    residual_peaks,
)
from dva_offline.isolator.maxwell_model import maxwell_element_stiffness


class FrfLibrary:
    """Candidate library of the FRF domain (methods of :class:`FrfDomain`)."""

    def _apparent_stiffness(self, m, points=None):
        """Mount stiffness seen in the data (default: the training points), K_app =
        1 / H_rec + m w^2 (the data for stiffness), and d_j = |dH_j / H_j| per unit |dK_app|:
        the factor turning a stiffness error into the relative error the fits minimise."""
        tr = self._train if points is None else points
        w, y = self.omega[tr], self.observations.values[tr]
        if self.quantity == "stiffness":
            return w, y, 1.0 / np.abs(y)
        rec = y if self.quantity == "receptance" else -y / w**2
        return w, 1.0 / rec + m * w**2, np.abs(rec)

    def _grid_start(self, points, n, m):
        """Parameter vector of an order-n Maxwell model fitted to ``points`` by the global
        corner-grid search (:func:`maxwell_from_stiffness`), or None."""
        s = self._setup
        w, kapp, d = self._apparent_stiffness(m, points)
        fit = maxwell_from_stiffness(w, kapp, d, n, None if s["free_k"] else s["k"])
        if fit is None:
            return None
        k, c, ks, cs, _ = fit
        return np.array([*[m] * s["free_m"], *[k] * s["free_k"], c, *ks, *cs])

    def _foundation_informed(self, base, n, count=3):
        """Full starts for ``foundation_mode`` that do not inherit the baseline's distortion.

        A baseline fitted without the foundation bends its Maxwell elements to imitate it;
        refitting from there ends in a local minimum (elements at a bound, zeta_f at its
        lower bound). Instead: (1) the foundation is a single-mode term in the compliance,
        1/K_app = 1/K + 1/K_f, so scan (f_f, zeta_f) for the term that best fits
        1/K_app - 1/K_base (m_f linear); (2) remove that foundation from the data,
        K = 1/(1/K_app - 1/K_f), and refit the Maxwell model of order n by the global
        corner-grid search of :func:`maxwell_from_stiffness`; (3) repeat once with that
        mount. Each of the ``count`` best distinct foundation frequencies gives one start.
        """
        s = self._setup
        m, k, c, ks, cs, _ = self._unpack(base, n)
        w, kapp, d = self._apparent_stiffness(m)
        f = self.observations.axis
        f_n = s["wn"] / (2 * np.pi)
        grid = np.geomspace(max(float(f.min()), 1.2 * f_n), float(f.max()), 60)
        zetas = (0.003, 0.01, 0.02, 0.04, 0.08, 0.15)
        k_fixed = None if s["free_k"] else s["k"]
        with np.errstate(all="ignore"):
            u_c = np.abs(kapp) ** 2 * d  # relative error per unit compliance error
            comp = 1.0 / kapp
            rows = modal_term_scan(w, comp - 1.0 / self._stiffness(k, c, ks, cs, w), u_c,
                                   grid, zetas, background=3)
        picked = []
        for _, ff, zf, a in rows:
            if len(picked) == count:
                break
            if all(abs(np.log(ff / p[0])) > 0.1 for p in picked):
                picked.append((ff, zf, a))
        out = []
        for ff, zf, a in picked:
            vec = None
            for _ in range(2):
                wf = 2 * np.pi * ff
                with np.errstate(all="ignore"):
                    kf = (wf**2 - w**2 + 2j * zf * wf * w) / a
                    mount = 1.0 / (comp - 1.0 / kf)
                    u_k = np.abs(kapp / mount) ** 2 * d
                ok = np.isfinite(mount) & np.isfinite(u_k)
                fit = maxwell_from_stiffness(w[ok], mount[ok], u_k[ok], n, k_fixed)
                if fit is None:
                    break
                k1, c1, ks1, cs1, _ = fit
                # (3) the foundation again, against this mount, near the last estimate
                with np.errstate(all="ignore"):
                    again = modal_term_scan(
                        w, comp - 1.0 / self._stiffness(k1, c1, ks1, cs1, w), u_c,
                        np.geomspace(ff / 1.15, ff * 1.15, 9), zetas)
                if again:
                    _, ff, zf, a = again[0]
                head = [m] * s["free_m"] + [k1] * s["free_k"]
                stacked = base[len(base) - self._stack_size():]  # effects added earlier
                vec = np.array([*head, c1, *ks1, *cs1, *stacked, ff, zf, 1.0 / a])
            if vec is not None:
                out.append(vec)
        return out


    def variants(self, spec: ModelSpec) -> list[ModelSpec]:
        """The same effect on a baseline with one more Maxwell element (automatic order only).

        The baseline order is chosen without the effect; an effect can hide the benefit of an
        element that the augmented model needs. The variant's extra element counts as two
        added parameters in the score.
        """
        s = self._setup
        n = s["n"]
        if (self.elements is not None or spec.effect == "maxwell_element"
                or n + 1 not in s["refined"] or self._stack):
            return []
        # bases: the refined order n + 1, and the baseline plus a fresh element on a grid of
        # corner frequencies and stiffnesses (the refined n + 1 may have a dormant element)
        base = self._base_values
        head = 2 - [s["free_m"], s["free_k"]].count(False)
        f = self.observations.axis
        bases = [s["refined"][n + 1]]
        wn = s["wn"]
        for fc in np.geomspace(f.min(), f.max(), 8):
            for r in (0.3, 1.0, 3.0):
                ke = r * s["k"]
                ce = ke / (2 * np.pi * fc)
                # the primary damper gives up the damping the new element adds at w_n
                c_new = base[head] - float(np.imag(
                    maxwell_element_stiffness([ke], [ce], [1j * wn])[0, 0])) / wn
                bases.append(np.concatenate([base[:head], [c_new], base[head + 1: head + 1 + n],
                                             [ke], base[head + 1 + n:], [ce]]))
        make = self._law_specs if spec.law is not None else self._library
        return [item for item in make(bases, n + 1, extra=2, only=(spec.effect, spec.label))
                if isinstance(item, ModelSpec)]

    def _library(self, bases, n, extra=0, only=None):
        s = self._setup
        obs = self.observations
        features = self._features
        f = obs.axis
        f_min, f_max = float(f.min()), float(f.max())
        m_b, k_b, *_ = self._unpack(bases[0], n)
        out: list[ModelSpec | NotApplicable] = []

        # an effect already in the model is not offered again (a second shift or delay on
        # the same covariate would only bend the first); elements and foundations may repeat
        present = {(t.effect, t.label.partition(", ")[0]) for t in self._stack
                   if t.effect not in ("maxwell_element", "foundation_mode")}

        def wanted(effect, label=""):
            if (effect, label.partition(", ")[0]) in present:
                return False
            return only is None or only == (effect, label)

        def spec(effect, added, term, starts=(), label="", more_bases=(), priority=()):
            return self._spec(effect, added, term, [*bases, *more_bases], n, starts, label,
                              extra, priority)

        ref_bases = ([self._reference_values] if extra == 0 and not self._stack
                     and self._reference_values is not None else [])

        # maxwell_element
        if only is None and (self.elements is not None or n >= self.max_elements
                             or self._stack):

            ke0 = 0.3 * k_b
            tau0 = 1.0 / (2 * np.pi * np.sqrt(f_min * f_max))  # corner in mid-band
            # corners across the material's (reduced) frequency range
            below, above = self._reduced_span()
            n_corner = 12 + int(round(2 * (below + above)))
            out.append(spec(
                "maxwell_element",
                (ParamSpec("k_e", self.units["k"], ke0, s["k_lo"], s["k_hi"], log=True),
                 ParamSpec("c_e", self.units["c"], ke0 * tau0, s["c_lo"] / 10**above,
                           s["c_hi"] * 10**below, log=True)),
                Term("maxwell_element", "", "element", 2),
                starts=[np.array([r * k_b, r * k_b * t]) for t in
                        1.0 / (2 * np.pi * np.geomspace(f_min / 10**below, f_max * 10**above,
                                                        n_corner))
                        for r in (0.1, 0.3, 1.0, 3.0)],
            ))
        elif only is None:
            out.append(NotApplicable(
                "maxwell_element",
                f"the order was selected automatically ({n} elements of at most "
                f"{self.max_elements}); extra elements are part of the baseline (fix the order "
                "with elements/--elements to test for a missing one)"))

        # sensor_delay
        sign = 1.0 if self.quantity == "stiffness" else -1.0
        if wanted("sensor_delay"):
            tau_eq = features.phase.equivalent_delay_s if features.phase is not None else 0.0
            tau_eq = -tau_eq if self.quantity == "stiffness" else tau_eq
            lo_t, hi_t = -0.5 / f_max, 2.0 / f_max
            starts = [np.array([t]) for t in (tau_eq, *np.linspace(lo_t, hi_t, 41)[1:-1])
                      if lo_t < t < hi_t]
            out.append(spec(
                "sensor_delay", (ParamSpec("tau", "s", 0.0, lo_t, hi_t, scale=0.1 / f_max),),
                Term("sensor_delay", "", "output", 1, "output", {"sign": sign}), starts))

        # fixture_mass
        m_ref = s["m"]
        if wanted("fixture_mass") and s["free_m"]:
            out.append(NotApplicable(
                "fixture_mass", "the mass is a fitted baseline parameter (give --mass)"))
        elif wanted("fixture_mass"):
            lower = -0.9 * m_ref if self.quantity != "stiffness" else -100 * m_ref
            out.append(spec(
                "fixture_mass",
                (ParamSpec("dm", self.units["m"], 0.0, lower, 100 * m_ref, scale=0.01 * m_ref),),
                Term("fixture_mass", "", "mass", 1),
                starts=[np.array([r * m_ref]) for r in np.linspace(-0.3, 0.5, 17)]))

        # foundation_mode
        if wanted("foundation_mode"):
            # Starts: the residual's strongest peaks, then a grid over the band, each taken
            # as the coupled resonance f_p of mount + foundation (K + K_f = 0), for several
            # foundation-to-mount stiffness ratios r = m_f w_p^2 / |K(w_p)|; then
            # f_f = f_p sqrt(1 - 1/r).
            _, k_c, c_c, ks_c, cs_c, _ = self._unpack(bases[0], n)
            f_n = s["wn"] / (2 * np.pi)
            f_lo = max(f_min, 1.2 * f_n)  # a foundation mode above the mount resonance
            peaks = [pk for pk in residual_peaks(f, self._base_residual, obs.groups, 5)
                     if pk > f_lo][:3]
            grid = np.geomspace(f_lo, f_max, 40)
            found_starts = []
            for fp, zetas in [(pk, (0.005, 0.01, 0.02, 0.05)) for pk in peaks] + [
                    (g, (0.02, 0.1)) for g in grid]:
                wp = 2 * np.pi * fp
                kp = float(np.abs(self._stiffness(k_c, c_c, ks_c, cs_c, np.array([wp]))[0]))
                for zf in zetas:
                    for ratio in (1.5, 3.0, 8.0, 30.0):
                        found_starts.append(np.array([fp * np.sqrt(1.0 - 1.0 / ratio), zf,
                                                      ratio * kp / wp**2]))
            informed = []
            for fp in peaks:
                wp = 2 * np.pi * fp
                kp = float(np.abs(self._stiffness(k_c, c_c, ks_c, cs_c, np.array([wp]))[0]))
                informed += [np.array([fp * np.sqrt(1.0 - 1.0 / r), zf, r * kp / wp**2])
                             for zf in (0.01, 0.03) for r in (1.5, 3.0, 8.0, 30.0)]
            informed += self._foundation_informed(bases[0], n)
            first = found_starts[0]
            out.append(spec(
                "foundation_mode",
                (ParamSpec("f_f", "Hz", first[0], max(0.5 * f_n, 0.5 * f_min), 2.0 * f_max,
                           log=True),
                 ParamSpec("zeta_f", "-", first[1], 1e-3, 0.15, log=True),
                 ParamSpec("m_f", self.units["m"], first[2], 1e-5 * m_ref, 1e4 * m_ref, log=True)),
                Term("foundation_mode", "", "series", 3), found_starts[1:], priority=informed))

        # covariate candidates
        varying = self._varying()
        if not varying and only is None:
            reason = ("needs sweeps at >= 2 levels of a covariate (e.g. --covariates "
                      "excitation_n or temperature_c)")
            out.append(NotApplicable("amplitude_dependence", reason))
            out.append(NotApplicable("covariate_shift", reason))
        for name, col in varying.items():
            # measured covariates may drift within a sweep: the reference level is the mean
            ref = float(col[obs.groups == self.reference].mean())
            if absolute_temperature(name, col) is not None:
                # a level law on a temperature would be a vertical shift of the master curve,
                # not an amplitude dependence: temperatures get the shift forms only
                if only is None:
                    out.append(NotApplicable("amplitude_dependence",
                                             f"covariate {name!r} is a temperature", name))
            elif wanted("amplitude_dependence", f"{name}, logarithmic") and np.all(col > 0):
                log_level = np.log(col / ref)
                bound = 0.95 / float(np.max(np.abs(log_level)))

                out.append(spec(
                    "amplitude_dependence",
                    (ParamSpec("s_k", "-", 0.0, -bound, bound, scale=0.05),
                     ParamSpec("s_d", "-", 0.0, -bound, bound, scale=0.05)),
                    Term("amplitude_dependence", f"{name}, logarithmic", "level", 2, "level",
                         {"log_level": log_level}), label=f"{name}, logarithmic",
                    more_bases=ref_bases,
                    starts=[np.array([a * bound, b * bound]) for a in np.linspace(-0.8, 0.8, 5)
                            for b in np.linspace(-0.8, 0.8, 5)]))
            elif wanted("amplitude_dependence", name):
                out.append(NotApplicable("amplitude_dependence",
                                         f"covariate {name!r} has values <= 0 (not a level)",
                                         name))
            if is_level(name) and np.all(col > 0):
                # a shift with an excitation level is the amplitude law above, by its name
                if only is None:
                    out.append(NotApplicable(
                        "covariate_shift", f"covariate {name!r} is an excitation level (a "
                        "shift with it is amplitude_dependence)", name))
            elif wanted("covariate_shift", f"{name}, WLF"):
                dt = col - ref
                c2_min = float(max(-dt.min(), 0.0)) + 1.0

                c2_0 = max(100.0, 2 * c2_min)
                out.append(spec(
                    "covariate_shift",
                    (ParamSpec("b", "1/K", 0.02, -1.0, 1.0, scale=0.02,
                               at_lower="the shift slope is at its limit -1 /K",
                               at_upper="the shift slope is at its limit 1 /K"),
                     ParamSpec("C2", "K", c2_0, c2_min, 1e4, log=True,
                               at_lower=f"the WLF singularity T_inf = T0 - C2 sits just below "
                                        f"the lowest level ({ref - c2_min + 1:.4g}): the shift "
                                        "diverges there",
                               at_upper="C2 -> infinity: the WLF law degenerates to a shift "
                                        "linear in the covariate (log a_T = -b (T - T0)); the "
                                        "data do not show WLF curvature (see the Arrhenius "
                                        "form for a temperature)")),
                    Term("covariate_shift", f"{name}, WLF", "shift", 2, "wlf", {"dt": dt}),
                    label=f"{name}, WLF", more_bases=ref_bases,
                    starts=[np.array([b, c2]) for b in np.linspace(-0.1, 0.1, 21)
                            for c2 in (c2_0, 3 * c2_0)]))
            kelvin = absolute_temperature(name, col)
            if kelvin is not None and wanted("covariate_shift", f"{name}, Arrhenius"):
                t_ref = float(kelvin[obs.groups == self.reference].mean())
                inv = 1.0 / kelvin - 1.0 / t_ref
                to_ea = 8.314462618 * np.log(10.0) * t_ref**2  # E_a for a slope b [1/K] at T0

                out.append(spec(
                    "covariate_shift",
                    (ParamSpec("E_a", "J/mol", 0.02 * to_ea, 1e3, 5e6, log=True,
                               at_lower="no measurable thermal activation (E_a -> 0)",
                               at_upper="an activation energy above 5 MJ/mol: the shift is "
                                        "steeper than any Arrhenius process (near a glass "
                                        "transition WLF applies)"),),
                    Term("covariate_shift", f"{name}, Arrhenius", "shift", 1, "arrhenius",
                         {"inv": inv}), label=f"{name}, Arrhenius", more_bases=ref_bases,
                    starts=[np.array([b * to_ea]) for b in np.geomspace(1e-3, 0.3, 15)]))
        return out
