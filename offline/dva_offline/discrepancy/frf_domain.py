"""Domain 1: frequency responses of isolators and viscoelastic mounts (Zhang (2006) chapters 3-5).

Baseline: the general Maxwell model of the isolator tool, K(w) = k + j w c +
sum_i j w c_i k_i / (k_i + j w c_i) (eq. 4.8), seen through the measured quantity
(receptance 1 / (K - m w^2), accelerance -w^2 / (K - m w^2) or the stiffness K itself). Its
order comes from the isolator's own order selection
(:func:`dva_offline.isolator.order_selection.select_model_order`, Voigt -> M-V -> M-M-V -> ...,
on the training points only), or is fixed by the user (``elements``). The isolator fit imposes
the natural frequency and damping ratio estimated from the data (eq. 4.12); since those are
estimates, the loop then refits all parameters of that model by weighted least squares
without the constraint (weights 1/|H_j|, the maximum-likelihood choice for multiplicative
noise). Mass m and static stiffness k are fixed when given, fitted otherwise.

Several conditions (sweeps at several temperatures or excitation levels) are pooled: the
baseline has no covariate dependence.

Candidate library (each reduces to the baseline at its null value; all baseline parameters
are refitted with the effect's):

=====================  =====================================================  ================
effect                 model                                                  added params
=====================  =====================================================  ================
maxwell_element        K + j w c_e k_e / (k_e + j w c_e)                      k_e, c_e
sensor_delay           H exp(-j w tau) (stiffness data: K exp(+j w tau))      tau
fixture_mass           K - dm w^2 (receptance: 1 / (K - (m + dm) w^2))        dm
foundation_mode        K K_f / (K + K_f), K_f = m_f (w_f^2 - w^2 + 2j z_f w_f w)  f_f, z_f, m_f
amplitude_dependence   Re K (1 + s_k L) + j Im K (1 + s_d L), L = ln(a / a_0)   s_k, s_d
covariate_shift        K0(w a_T), log10 a_T = -b C2 (T - T0) / (C2 + T - T0)   b, C2
  (temperatures also)  log10 a_T = E_a / (R ln 10) (1/T - 1/T0), T in kelvin    E_a
=====================  =====================================================  ================

``maxwell_element`` is a candidate only when the order is fixed (or the automatic order hit
its maximum, or the loop has added an effect); otherwise extra elements are already part of
the baseline. ``a`` and ``T`` are covariates whose sweep levels differ (values per point as
measured; a_0, T0 = the reference sweep's mean, the sweep at the median level).
covariate_shift is the WLF form of time-temperature superposition with C1 = b C2, and for a
temperature also its Arrhenius form (a candidate of its own, label ``NAME, Arrhenius``); a
temperature gets no level law. The effects are terms of one model (:mod:`.frf_terms`), so the
loop can take a chosen effect into the baseline (:meth:`FrfDomain.augment`) and offer the
library again on top of it (the library itself is in :mod:`.frf_library`).

Starting values that do not inherit the baseline's distortion (the baseline bends its elements
to imitate the missing effect): :func:`maxwell_from_stiffness` fits the Maxwell model globally
over a grid of element corners (linear least squares per combination), and
:func:`modal_term_scan` finds a foundation mode in the compliance; together they deconvolve a
foundation from the data (``foundation_mode``) and start the reference-condition fit of the
covariate candidates.
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence
from functools import partial

import numpy as np

from dva_offline.discrepancy.fitting import (
    DataError,
    HoldoutSplit,
    ModelFit,
    ModelSpec,
    NotApplicable,
    ParamSpec,
    fit_model,
)
from dva_offline.discrepancy.frf_laws import FrfLaws
from dva_offline.discrepancy.frf_library import FrfLibrary
from dva_offline.discrepancy.frf_spectrum import SpectrumLibrary
from dva_offline.discrepancy.frf_terms import (
    SIGNATURES,
    Term,
    compose,
    log_shift,
    maxwell_parts,
    maxwell_stiffness,
)
from dva_offline.discrepancy.maxwell_starts import (
    positive,
)
from dva_offline.discrepancy.pooling import pool_conditions
from dva_offline.discrepancy.residual import ResidualFeatures, ljung_box, noise_floor
from dva_offline.isolator.frf_data import FrfData, estimate_modal, to_receptance
from dva_offline.isolator.maxwell_fit import FitWarning, fit_maxwell_model
from dva_offline.isolator.maxwell_model import MaxwellModel, maxwell_element_stiffness
from dva_offline.isolator.order_selection import select_model_order


class FrfDomain(FrfLibrary, SpectrumLibrary, FrfLaws):
    """Isolator FRF data for :func:`dva_offline.discrepancy.loop.run`.

    Parameters
    ----------
    conditions : sequence of FrfData
        One or more sweeps (same quantity), e.g. one per temperature; each sorted by frequency.
    mass : float, optional
        Isolated mass m [kg] (weighed). Fitted when omitted (receptance/accelerance); for
        stiffness data it only sets the natural frequency of the isolator tool's initial fit.
    static_stiffness : float, optional
        Static stiffness k [N/m]; fitted when omitted.
    elements : int, optional
        Fixed number of Maxwell elements (0 = Voigt); default: the isolator's order selection.
    max_elements : int
        Largest order of the automatic selection (>= 1).
    covariates : sequence of str, optional
        Condition covariates to analyse (default: every covariate column that varies between
        conditions).
    order_tolerance : float
        Automatic order: the smallest order n whose refined held-out error satisfies
        e_n^2 <= e_best^2 + order_tolerance * sigma_hat^2 (sigma_hat: noise floor) and, if
        any of these orders has a white residual (Ljung-Box p >= ``whiteness_alpha``), whose
        residual is white.
    whiteness_alpha : float
        Ljung-Box level of the order choice (the loop's default whiteness level).
    modulus : bool
        The data are a material's modulus (stiffness data per unit geometry factor): the
        parameters are reported in Pa, Pa s and Pa s^2 instead of N/m, N s/m and kg.
    """

    name = "frf"

    def __init__(self, conditions: Sequence[FrfData], mass: float | None = None,
                 static_stiffness: float | None = None, elements: int | None = None,
                 max_elements: int = 3, covariates: Sequence[str] | None = None,
                 order_tolerance: float = 0.15, whiteness_alpha: float = 1e-3,
                 modulus: bool = False) -> None:
        conditions = list(conditions)
        if not conditions or not all(isinstance(c, FrfData) for c in conditions):
            raise TypeError("conditions must be a non-empty sequence of FrfData")
        quantities = {c.quantity for c in conditions}
        if len(quantities) != 1:
            raise ValueError(f"all conditions must have the same quantity, got {quantities}")
        self.quantity = quantities.pop()
        if mass is not None and not mass > 0:
            raise ValueError(f"mass must be > 0 kg, got {mass}")
        if static_stiffness is not None and not static_stiffness > 0:
            raise ValueError(f"static_stiffness must be > 0 N/m, got {static_stiffness}")
        if elements is not None and (not isinstance(elements, (int, np.integer)) or elements < 0):
            raise ValueError(f"elements must be an integer >= 0 or None, got {elements!r}")
        if not isinstance(max_elements, (int, np.integer)) or max_elements < 1:
            raise ValueError(f"max_elements must be an integer >= 1, got {max_elements!r}")
        if not order_tolerance >= 0:
            raise ValueError(f"order_tolerance must be >= 0, got {order_tolerance}")
        if not 0 < whiteness_alpha < 1:
            raise ValueError(f"whiteness_alpha must be in (0, 1), got {whiteness_alpha}")
        # a modulus is a stiffness per unit geometry factor: its parameters in Pa, Pa s, Pa s^2
        self.modulus = bool(modulus)
        self._spectrum, self._spectrum_fits = None, {}  # the Prony spectrum (frf_spectrum)
        self.units = (dict(m="Pa s^2", k="Pa", c="Pa s") if modulus else
                      dict(m="kg", k="N/m", c="N s/m"))
        self.order_tolerance = float(order_tolerance)
        self.whiteness_alpha = float(whiteness_alpha)
        self.conditions = conditions
        self.mass = mass
        self.static_stiffness = static_stiffness
        self.elements = elements
        self.max_elements = int(max_elements)
        self.omega, self.observations = pool_conditions(conditions, covariates)
        self.reference = self._reference_condition()
        self._setup = None
        self._stack: list[Term] = []  # effects added by the loop's earlier steps
        self._stack_params: list[ParamSpec] = []
        self._term_of: dict = {}

    # --- data helpers ----------------------------------------------------------------------
    def _varying(self) -> dict:
        """Covariates whose condition levels differ (a drift within one sweep is not a
        level change)."""
        g = self.observations.groups
        out = {}
        for n, c in self.observations.covariates.items():
            means = np.array([c[g == label].mean() for label in np.unique(g)])
            if np.ptp(means) > 0:
                out[n] = c
        return out

    def _reference_condition(self) -> int:
        """The condition at the median level of the first varying covariate (else the first)."""
        varying = self._varying()
        if not varying:
            return 0
        col = next(iter(varying.values()))
        per = np.array([col[self.observations.groups == g].mean()
                        for g in range(len(self.conditions))])
        return int(np.argmin(np.abs(per - np.median(per))))

    def _mass_and_stiffness(self):
        """(m, k) given or estimated from the reference condition, and whether each is free."""
        ref = self.conditions[self.reference]
        w = ref.omega_rad_s
        free_m = self.mass is None and self.quantity != "stiffness"
        if self.quantity == "stiffness":
            stiff = ref.values
        else:
            m_guess = self.mass
            rec = ref.values if self.quantity == "receptance" else ref.values / -(w**2)
            if m_guess is None:
                top = w >= np.quantile(w, 0.9)
                m_guess = float(np.median(np.real(-1.0 / (w[top] ** 2 * rec[top]))))
                if not m_guess > 0:
                    raise DataError("cannot estimate the mass from the FRF (its high-frequency "
                                    "end is not mass-like); give --mass")
            stiff = 1.0 / rec + m_guess * w**2
        k = self.static_stiffness
        if k is None:
            k = positive(np.real(stiff[0]), 1e-12)
        if self.quantity == "stiffness":
            if self.mass is not None:
                m = self.mass
            else:  # nominal mass: resonance at the band's geometric centre (constraint only)
                i = w.size // 2
                m = float(np.abs(stiff[i])) / w[i] ** 2
        else:
            m = m_guess
        return float(m), float(k), free_m, self.static_stiffness is None

    def _modal_estimate(self, m: float):
        """w_n [rad/s] and zeta of the reference condition (isolator estimate, or a fallback)."""
        ref = self.conditions[self.reference]
        if self.quantity == "stiffness":
            w_ref, rec_ref = ref.omega_rad_s, 1.0 / (ref.values - m * ref.omega_rad_s**2)
        else:
            w_ref, rec_ref = to_receptance(ref, m)
        try:
            est = estimate_modal(w_ref, rec_ref)
            wn, zeta = est.natural_frequency_rad_s, est.damping_ratio
            if not (0 < zeta < 0.9):
                raise ValueError("damping ratio estimate out of range")
        except ValueError:
            wn, zeta = float(w_ref[np.argmax(np.abs(rec_ref))]), 0.1
        return float(wn), float(zeta)

    def _isolator_models(self, train: np.ndarray, m: float, k: float, wn: float, zeta: float):
        """The isolator tool's model per order (order selection or the fixed order).

        Returns a dict order -> MaxwellModel (with mass m and stiffness k) and the
        :class:`OrderSelection` (None when the order is fixed).
        """
        omega, h = self.omega[train], self.observations.values[train]
        c0 = 2.0 * m * zeta * wn
        models = {0: MaxwellModel(m, k, c0)}
        sel = None
        orders = range(1, self.max_elements + 1) if self.elements is None else (
            [self.elements] if self.elements > 0 else [])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitWarning)
            warnings.simplefilter("ignore", RuntimeWarning)
            if self.elements is None:
                try:
                    sel = select_model_order(omega, h, m, k, wn, zeta, self.quantity,
                                             max_elements=self.max_elements, max_iter=15)
                    for order, model in zip(sel.orders, sel.models):
                        if order > 0:
                            models[order] = model
                except (ValueError, np.linalg.LinAlgError):
                    sel = None
            else:
                for n in orders:
                    try:
                        models[n] = fit_maxwell_model(omega, h, m, k, n, wn, zeta,
                                                      self.quantity, max_iter=15).model
                    except (ValueError, np.linalg.LinAlgError):
                        pass
        for n in orders:  # a failed fit: the study's initial-guess rule (section 4.3.2)
            if n not in models:
                taus = np.logspace(-0.5, 1.0, n) / wn
                ks = np.full(n, positive(m * wn**2 - k, 0.1 * k) / n)
                models[n] = MaxwellModel(m, k, c0, tuple(ks), tuple(taus * ks))
        return {n: MaxwellModel(m, k, mod.c, mod.maxwell_k, mod.maxwell_c)
                for n, mod in models.items()}, sel

    # --- model evaluation ------------------------------------------------------------------
    def _unpack(self, v, n=None):
        """(m, k, c, k_i, c_i, effect parameters) from a parameter vector."""
        s = self._setup
        n = s["n"] if n is None else n
        i = 0
        m, k = s["m"], s["k"]
        if s["free_m"]:
            m = v[i]
            i += 1
        if s["free_k"]:
            k = v[i]
            i += 1
        c = v[i]
        ks = v[i + 1: i + 1 + n]
        cs = v[i + 1 + n: i + 1 + 2 * n]
        return m, k, c, ks, cs, v[i + 1 + 2 * n:]

    def _stiffness(self, k, c, ks, cs, omega=None, parts=False):
        """K(w) of eq. 4.8, as :func:`~dva_offline.isolator.maxwell_model.dynamic_stiffness`
        (tested equal) without its input validation, which dominates inside the fits; its
        real and imaginary parts with ``parts``."""
        w = self.omega if omega is None else omega
        return maxwell_parts(w, k, c, ks, cs) if parts else maxwell_stiffness(w, k, c, ks, cs)

    def _evaluate(self, v, n, terms):
        """Model values of parameter vector v: Maxwell order n with ``terms`` (in stack order,
        their parameters after the Maxwell ones), see :mod:`.frf_terms`."""
        m, k, c, ks, cs, rest = self._unpack(v, n)
        vals, i = [], 0
        for t in terms:
            vals.append(rest[i:i + t.size])
            i += t.size
        return compose(partial(self._stiffness, k, c, ks, cs), terms, vals, self.omega, m,
                       self.quantity)

    def _base_predict(self, v, n=None):
        """The current baseline: Maxwell order n with the effects added so far."""
        n = self._setup["n"] if n is None else n
        return self._evaluate(v, n, self._stack)

    def _maxwell_params(self, model: MaxwellModel) -> tuple[ParamSpec, ...]:
        s = self._setup
        c_ref = s["c_ref"]
        params = []
        u = self.units
        if s["free_m"]:
            params.append(ParamSpec("m", u["m"], model.mass, model.mass * 1e-2, model.mass * 1e2,
                                    log=True))
        if s["free_k"]:
            params.append(ParamSpec("k", u["k"], model.k, model.k * 1e-3, model.k * 1e3,
                                    log=True))
        params.append(ParamSpec("c", u["c"], model.c, -s["c_abs"], s["c_abs"], scale=c_ref))
        dormant = "a dormant element (the data do not need it in the band)"
        for i, ki in enumerate(model.maxwell_k):
            params.append(ParamSpec(f"k_{i + 1}", u["k"], ki, s["k_lo"], s["k_hi"], log=True,
                                    at_lower=dormant, at_upper=dormant))
        below, above = self._reduced_span()
        for i, ci in enumerate(model.maxwell_c):
            params.append(ParamSpec(f"c_{i + 1}", u["c"], ci, s["c_lo"] / 10**above,
                                    s["c_hi"] * 10**below, log=True, at_lower=dormant,
                                    at_upper=dormant))
        return tuple(params)

    def _data_span(self, m: float) -> dict:
        """Ranges of the stiffness and damping parameters that follow the data's magnitude.

        The nominal k_ref = m w_n^2 and c_ref = m w_n come from a resonance, which a material's
        modulus (or a mount measured far from its resonance) does not have: the bounds are
        widened until they reach at least a decade beyond the largest apparent stiffness
        |K_app| in the data and the damper that gives it at the lowest frequency, so no
        element is held below the data by a ceiling in SI units.
        """
        s = self._setup
        w, kapp, _ = self._apparent_stiffness(m, np.ones(self.omega.size, dtype=bool))
        mag = np.abs(kapp[np.isfinite(kapp)])
        mag = mag[mag > 0]
        k_ref, c_ref = s["k_ref"], s["c_ref"]
        if mag.size == 0:
            return dict(k_lo=1e-3 * k_ref, k_hi=1e3 * k_ref, c_lo=1e-3 * c_ref, c_hi=1e3 * c_ref,
                        c_abs=100 * c_ref)
        k_max, k_min = float(mag.max()), float(mag.min())
        c_max = k_max / float(w.min())
        return dict(k_lo=min(1e-3 * k_ref, 0.1 * k_min), k_hi=max(1e3 * k_ref, 10 * k_max),
                    c_lo=min(1e-3 * c_ref, 0.1 * k_min / float(w.max())),
                    c_hi=max(1e3 * c_ref, c_max), c_abs=max(100 * c_ref, c_max))

    def _reduced_span(self) -> tuple[float, float]:
        """Decades by which the material's reduced frequency w a_T reaches below the lowest
        and above the highest measured frequency, under the shifts added so far (the element
        time constants must be free to cover it; 0, 0 without a shift)."""
        shifts = [(t, i) for t, i in zip(self._stack, self._stack_offsets()) if t.stage == "shift"]
        if not shifts or getattr(self, "_base_values", None) is None:
            return 0.0, 0.0
        start = len(self._base_values) - self._stack_size()
        total = np.zeros(self.omega.size)
        for t, i in shifts:
            total = total + log_shift(t, self._base_values[start + i: start + i + t.size])
        return float(max(0.0, -total.min())), float(max(0.0, total.max()))

    def _stack_offsets(self) -> list[int]:
        return list(np.cumsum([0] + [t.size for t in self._stack])[:-1])

    def _order_spec(self, model: MaxwellModel, previous: np.ndarray | None,
                    extra_starts=()) -> ModelSpec:
        """Spec of an order-n Maxwell model started at the isolator's fit, at
        ``extra_starts`` and, when given, at the refined order n - 1 plus a new element at a
        few time constants (nested starts)."""
        n = model.n_elements
        params = self._maxwell_params(model)
        starts = [v for v in extra_starts if v is not None]
        if previous is not None and n > 0:
            pm, pk, pc, pks, pcs, _ = self._unpack(previous, n - 1)
            head = [v for v, free in ((pm, self._setup["free_m"]), (pk, self._setup["free_k"]))
                    if free]
            f = self.observations.axis
            wn = self._setup["wn"]
            for fc in np.geomspace(f.min(), f.max(), 8):
                for r in (0.3, 1.0, 3.0):
                    ke = r * self._setup["k"]
                    ce = ke / (2 * np.pi * fc)
                    # the primary damper gives up the damping the new element adds at w_n
                    c_new = pc - float(np.imag(
                        maxwell_element_stiffness([ke], [ce], [1j * wn])[0, 0])) / wn
                    starts.append(np.array([*head, c_new, *pks, ke, *pcs, ce]))
        name = "voigt" if n == 0 else f"maxwell(n={n})"
        predict = partial(self._base_predict, n=n)
        return ModelSpec(name, None, params, 0, predict, tuple(starts),
                         batch_predict=_rows(predict))

    # --- Domain protocol -------------------------------------------------------------------
    def baseline(self, train: np.ndarray) -> ModelSpec:
        """The Maxwell model of the isolator tool, refined without the w_n/zeta constraint.

        Each order's isolator fit (on the training points) is refitted by weighted least
        squares on 3/4 of the training points and scored on the other 1/4 (every 4th point,
        the isolator's own held-out rule). The selected order is the smallest whose squared
        error exceeds the best order's by less than ``order_tolerance`` x the squared noise
        floor (an extra element must buy more than noise); with a fixed order only that order
        is refitted. The returned spec starts at the refined model of the selected order.
        """
        train = np.asarray(train, dtype=bool)
        self._train = train
        self._stack, self._stack_params, self._term_of = [], [], {}
        self._spectrum, self._spectrum_fits = None, {}
        self._law_inputs, self.trends = None, []
        m, k, free_m, free_k = self._mass_and_stiffness()
        wn, zeta = self._modal_estimate(m)
        self._setup = dict(m=m, k=k, free_m=free_m, free_k=free_k, n=0, k_ref=m * wn**2,
                           c_ref=m * wn, wn=wn, order=None, order_errors=None, refined={})
        self._setup.update(self._data_span(m))
        models, sel = self._isolator_models(train, m, k, wn, zeta)
        self._setup["order"] = sel
        idx = np.nonzero(train)[0]
        inner_held = np.zeros_like(train)
        inner_held[idx[2::4]] = True
        inner = HoldoutSplit(train & ~inner_held, inner_held, "every 4th training point")
        refined, errors, residuals = {}, {}, {}
        for n in sorted(models):
            spec = self._order_spec(models[n], refined.get(n - 1))
            fit = fit_model(spec, self.observations, inner, n_screen=4)
            refined[n], errors[n] = np.array([e.value for e in fit.estimates]), fit.error
            residuals[n] = fit.residual
        best_n = min(errors, key=errors.get)
        groups = self.observations.groups
        sigma = noise_floor(residuals[best_n], groups).sigma
        limit = errors[best_n] ** 2 + self.order_tolerance * sigma**2
        within = sorted(n for n, e in errors.items() if e**2 <= limit)
        # An order within the tolerance whose residual is still correlated misses structure
        # that a higher order within the tolerance captures down to white noise (a clean
        # M-M-V mount fitted as M-V): prefer the smallest order with a white residual.
        lags = max(1, min(10, min(np.bincount(groups)[np.unique(groups)]) // 4))
        white = [n for n in within
                 if ljung_box(residuals[n], groups, lags).p_value >= self.whiteness_alpha]
        chosen = (self.elements if self.elements is not None else
                  (white or within)[0])
        self._setup["n"] = chosen
        self._setup["order_errors"] = errors
        self._setup["refined"] = refined
        m_c, k_c, c_c, ks_c, cs_c, _ = self._unpack(refined[chosen], chosen)
        model = MaxwellModel(float(m_c), float(k_c), float(c_c), tuple(ks_c), tuple(cs_c))
        self._base_params = self._maxwell_params(model)
        name = "voigt" if chosen == 0 else f"maxwell(n={chosen})"
        return ModelSpec(name, None, self._base_params, 0, self._base_predict,
                         batch_predict=_rows(self._base_predict))

    @property
    def order_selection(self):
        """The isolator's :class:`OrderSelection` (None when the order was fixed)."""
        return None if self._setup is None else self._setup["order"]

    @property
    def order_errors(self) -> dict:
        """Order -> held-out error of the refined model on the training split (after
        :meth:`baseline`)."""
        if self._setup is None:
            raise ValueError("baseline() has not been called")
        return dict(self._setup["order_errors"])

    @property
    def baseline_order(self) -> int:
        """Number of Maxwell elements of the baseline (after :meth:`baseline`)."""
        if self._setup is None:
            raise ValueError("baseline() has not been called")
        return self._setup["n"]

    def _spec(self, effect, added, term, bases, n, starts=(), label="", extra=0,
              priority=()):
        """Spec of baseline order n + effect; starts = every base vector x every effect start
        (the first base with the effect's initial values is the initial point); ``priority``:
        informed starts, effect values on the first base or full parameter vectors."""
        m, k, c, ks, cs, _ = self._unpack(bases[0], n)
        model = MaxwellModel(float(m), float(k), float(c), tuple(ks), tuple(cs))
        params = self._maxwell_params(model) + tuple(self._stack_params) + tuple(added)
        terms = [*self._stack, term]

        def predict(v, n=n, terms=terms):
            return self._evaluate(v, n, terms)

        effect_starts = [np.array([a.initial for a in added]), *starts]
        full_starts = tuple(np.concatenate([b, e]) for b in bases for e in effect_starts)[1:]
        informed = tuple(e if e.size == bases[0].size + len(added)
                         else np.concatenate([bases[0], e]) for e in priority)
        full_starts = informed + full_starts
        name = self._model_name(n) + f" + {effect}" + (f"({label})" if label else "")
        spec = ModelSpec(name, effect, params, len(added) + extra, predict, full_starts,
                         SIGNATURES[effect], label, len(informed), _rows(predict))
        self._term_of[name] = (term, n, tuple(added))
        return spec

    def _stack_size(self) -> int:
        return sum(t.size for t in self._stack)

    def _model_name(self, n):
        head = "voigt" if n == 0 else f"maxwell(n={n})"
        return head + "".join(f" + {t.effect}" + (f"({t.label})" if t.label else "")
                              for t in self._stack)

    def augment(self, spec: ModelSpec, fit: ModelFit) -> None:
        """Make the chosen candidate the baseline of the next step (the loop's iteration):
        its effect joins the stack, its fitted values start the next candidates (a Prony
        spectrum replaces the Maxwell elements and the shift, :mod:`.frf_spectrum`)."""
        if self._augment_spectrum(spec):
            return
        term, n, added = self._term_of[spec.name]
        extra = spec.n_added - len(added)
        if extra:  # the one-more-element variant: the order grows
            self._setup["n"] = n
        self._stack.append(term)
        self._stack_params.extend(added)

    def candidates(self, baseline: ModelFit, features: ResidualFeatures):
        """The candidate library (module docstring), started from the fitted baseline."""
        self._features = features
        self._base_residual = baseline.residual
        self._base_values = np.array([e.value for e in baseline.estimates])
        self._reference_values = None
        spectrum = self._spectrum_library(len(baseline.estimates)) if self.modulus else []
        if self._spectrum:  # a master curve: only the spectrum and its shift are refined
            return [NotApplicable(e, "not offered on the Prony spectrum of a master curve")
                    for e in ("sensor_delay", "foundation_mode")] + spectrum
        if self._varying() and not self._stack:
            # The covariate candidates' baseline is the model at the reference condition:
            # start them also from a fit to that condition's training points alone. The
            # pooled baseline is bent by the covariate's effect; from it alone, this fit can
            # end with a dormant element, so it is also started from a corner-grid search.
            ref = self._train & (self.observations.groups == self.reference)
            split = HoldoutSplit(ref, ~ref, "reference condition")
            n = self._setup["n"]
            mm, mk, mc, mks, mcs, _ = self._unpack(self._base_values, n)
            model = MaxwellModel(float(mm), float(mk), float(mc), tuple(mks), tuple(mcs))
            spec = self._order_spec(model, self._setup["refined"].get(n - 1),
                                    [self._grid_start(ref, n, float(mm))])
            fit = fit_model(spec, self.observations, split, n_screen=4)
            self._reference_values = np.array([e.value for e in fit.estimates])
        return self._library([self._base_values], self._setup["n"]) + spectrum


def _rows(predict):
    """``predict`` for many parameter vectors, (S, P) -> (S, N): every parameter becomes an
    (S, 1) column, so the same arithmetic broadcasts over the points and the vectors."""
    return lambda values: predict(np.asarray(values, dtype=float).T[..., None])
