"""Structures: frequency responses of a vibration test (force in, response out, several modes).

Baseline: N modes with real modal constants and residual terms (the usual modal model of a
driving-point or transfer FRF of a lightly, proportionally damped structure), in receptance:

    H(w) = sum_r A_r / (w_r^2 - w^2 + 2 j z_r w_r w) + U - L / w^2

(U: modes above the band, L: modes below it / rigid-body mass line), with real or complex
modal constants: complex ones in the pole-pair form of EMA tools (LSFD, as sdypy-EMA fits
them), A_r + j (w / w_r) B_r with complex residuals U + j U'', L + j L'' (a real impulse
response; B_r / A_r is the phase of mode r at resonance: non-proportional damping, or a
constant phase of the measurement chain). Each form gets its order by the rule below; complex
is kept when it beats real significantly in the same paired held-out test and one delay of
the channel does not explain the phase as well (to first order a delay is a set of complex
constants, B_r = -w_r tau A_r: 1 parameter against N + 2). Mobility and accelerance
data are converted to receptance on input (H_rec = H_mob / (j w) = -H_acc / w^2): the relative
residual of every point is the same in each form. N: 1..N_max modes started at the
strongest peaks of |H| (frequencies and damping refined by variable projection), each fitted
on 3/4 of the training points and scored on the other 1/4; the smallest N whose held-out
error is not significantly above the best one's in a paired test, a doublet only when it
beats the next smaller order significantly, a white residual preferred
(:mod:`~dva_offline.discrepancy.model_order`).

Candidate library (each reduces to the baseline at a null value; added effects stack, the
loop's later steps build on the model with the effects found so far):

====================  ===============================================================  ======
effect                model                                                            params
====================  ===============================================================  ======
amplitude_dependence  mode r: f_r (1 + s_f L), z_r (1 + s_z L), L = ln(a / a_0)          2
covariate_shift       every f_r x 10^(-b (c - c_0)) (form "exponential"; stiffness        1
                      changing with the covariate, e.g. temperature)
sensor_delay          H exp(-j w tau)                                                    1
complex_modes         A_r + j (w / w_r) B_r, U + j U'', L + j L'' (the baseline's      N + 2
                      constants were real; the phase shows once other effects are in)
====================  ===============================================================  ======

``amplitude_dependence`` is offered per mode (label ``COVARIATE, mode r (f Hz)``): a joint or
a rubber part softens one mode, not all. The isolator effects (Maxwell element, fixture mass,
foundation) are not applicable: the modal model has no mount.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

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
from dva_offline.discrepancy.model_order import choose_order, has_doublet, paired_excess
from dva_offline.discrepancy.pooling import pool_conditions
from dva_offline.discrepancy.residual import ResidualFeatures, ljung_box
from dva_offline.isolator.frf_data import FrfData

MODAL_QUANTITIES = ("receptance", "mobility", "accelerance")
MODAL_CONSTANTS = ("auto", "real", "complex")
SIGNATURES = {
    "amplitude_dependence": "one resonance moves (and its damping changes) with the excitation "
                            "level; the residual grows with the level near that mode",
    "covariate_shift": "every resonance moves by the same factor with the covariate",
    "sensor_delay": "phase of H_meas / H_model falls linearly with frequency, magnitude "
                    "unchanged",
    "complex_modes": "each mode's contribution turned by its own phase near its resonance "
                     "(non-proportional damping, a constant phase of the channel); unlike a "
                     "delay's, the phase does not grow with frequency",
}


@dataclass(frozen=True)
class ModalTerm:
    """An effect in the modal model: ``kind`` level (one mode), level_all (every mode, one
    log-level law), per_level (every mode, a free factor per level), shift (all modes) or
    delay."""

    effect: str
    label: str
    kind: str
    size: int
    mode: int = -1
    data: dict = field(default_factory=dict)


def to_receptance(frequency_hz, values, quantity: str) -> np.ndarray:
    """Receptance from receptance, mobility or accelerance values (frequencies > 0)."""
    w = 2 * np.pi * np.asarray(frequency_hz, float)
    y = np.asarray(values, complex)
    if quantity == "receptance":
        return y
    if np.any(w <= 0):
        raise ValueError(f"{quantity} needs frequencies > 0 Hz (drop the 0 Hz point)")
    if quantity == "mobility":
        return y / (1j * w)
    if quantity == "accelerance":
        return -y / w**2
    raise ValueError(f"quantity must be one of {MODAL_QUANTITIES}, got {quantity!r}")


def model_name(n: int, cplx: bool) -> str:
    """``modal(N=3)`` (real modal constants) or ``modal(N=3, complex)``."""
    return f"modal(N={n}{', complex' if cplx else ''})"


def find_peaks(f, h, count: int) -> list[float]:
    """Frequencies [Hz] of the ``count`` most prominent local maxima of |h| (3-point smoothed,
    prominence in log magnitude over the neighbouring minima)."""
    mag = np.log(np.convolve(np.abs(h), np.ones(3) / 3, mode="same") + 1e-300)
    mag[0], mag[-1] = np.log(abs(h[0])), np.log(abs(h[-1]))
    peaks = []
    for i in range(1, mag.size - 1):
        if mag[i] >= mag[i - 1] and mag[i] > mag[i + 1]:
            left = mag[:i + 1][::-1]
            right = mag[i:]
            # prominence: drop to the lowest point before a higher value on each side
            lmin = left[:np.argmax(left > mag[i]) or left.size].min()
            rmin = right[:np.argmax(right > mag[i]) or right.size].min()
            peaks.append((mag[i] - max(lmin, rmin), f[i]))
    peaks.sort(reverse=True)
    return [freq for _, freq in peaks[:count]]


class ModalDomain:
    """Vibration-test FRFs of a structure for :func:`dva_offline.discrepancy.loop.run`.

    Parameters
    ----------
    conditions : sequence of FrfData
        Receptance sweeps (convert mobility / accelerance with :func:`to_receptance`), one
        per excitation level / temperature; covariate values per point.
    modes : int, optional
        Fixed number of modes (default: the order rule, 1..``max_modes``).
    max_modes : int
    covariates : sequence of str, optional
        Covariates to analyse (default: every covariate whose level differs between sweeps).
    quantity : str
        What the input was (reported; the model works in receptance).
    constants : str
        Modal constants of the baseline: ``real``, ``complex`` or ``auto`` (module docstring).
    order_z, doublet_bandwidths, whiteness_alpha : float
        The order rule (:func:`~dva_offline.discrepancy.model_order.choose_order`): standard
        errors of the paired held-out excess within which an order is as good as the best,
        the spacing (in half-power bandwidths) below which two modes are a doublet, and the
        Ljung-Box p-value of a white residual (preferred).
    """

    name = "modal"

    def __init__(self, conditions: Sequence[FrfData], modes: int | None = None,
                 max_modes: int = 8, covariates: Sequence[str] | None = None,
                 quantity: str = "receptance", order_z: float = 2.0,
                 doublet_bandwidths: float = 3.0, whiteness_alpha: float = 1e-3,
                 constants: str = "auto") -> None:
        conditions = list(conditions)
        if not conditions or not all(isinstance(c, FrfData) for c in conditions):
            raise TypeError("conditions must be a non-empty sequence of FrfData")
        if any(c.quantity != "receptance" for c in conditions):
            raise ValueError("the modal domain takes receptance (convert with to_receptance)")
        if modes is not None and (not isinstance(modes, (int, np.integer)) or modes < 1):
            raise ValueError(f"modes must be an integer >= 1 or None, got {modes!r}")
        if not isinstance(max_modes, (int, np.integer)) or max_modes < 1:
            raise ValueError(f"max_modes must be an integer >= 1, got {max_modes!r}")
        if quantity not in MODAL_QUANTITIES:
            raise ValueError(f"quantity must be one of {MODAL_QUANTITIES}, got {quantity!r}")
        self.conditions, self.modes, self.max_modes = conditions, modes, int(max_modes)
        self.quantity = quantity
        self.order_z, self.doublet_bandwidths = float(order_z), float(doublet_bandwidths)
        self.whiteness_alpha = whiteness_alpha
        if constants not in MODAL_CONSTANTS:
            raise ValueError(f"constants must be one of {MODAL_CONSTANTS}, got {constants!r}")
        self.constants = constants
        self.complex_constants = constants == "complex"  # decided by baseline() for auto
        self._constants_reason, self._form_errors = "", {}
        self.omega, self.observations = pool_conditions(conditions, covariates)
        self.reference = self._reference_condition()
        self._stack: list[ModalTerm] = []
        self._n = None
        self._term_of: dict = {}
        self._order_errors = {}
        self._order_choice = None
        self.trends: list = []  # the per-condition trends and their laws (law_candidates)
        self._law_inputs = None

    # --- helpers ---------------------------------------------------------------------------
    def _varying(self) -> dict:
        g = self.observations.groups
        return {n: c for n, c in self.observations.covariates.items()
                if np.ptp([c[g == lab].mean() for lab in np.unique(g)]) > 0}

    def _reference_condition(self) -> int:
        varying = self._varying()
        if not varying:
            return 0
        col = next(iter(varying.values()))
        g = self.observations.groups
        per = np.array([col[g == lab].mean() for lab in range(len(self.conditions))])
        return int(np.argmin(np.abs(per - np.median(per))))

    def _level(self, name: str) -> float:
        col = self.observations.covariates[name]
        return float(col[self.observations.groups == self.reference].mean())

    def _evaluate(self, v, n, terms, cplx=None):
        """Receptance of parameter vector v = [f_1, z_1, A_1, ..., U, L, (complex parts: B_1,
        ..., B_n, U'', L''), term params...], shape (P,) -> (N,), or of each row of v, shape
        (S, P) -> (S, N). ``cplx``: complex modal constants (default: the baseline's form)."""
        cplx = self.complex_constants if cplx is None else cplx
        w = self.omega
        vs = np.atleast_2d(np.asarray(v, dtype=float))
        fr, zr, ar = (vs[:, k:3 * n:3, None] for k in range(3))  # (S, n, 1) each
        u, low = vs[:, 3 * n, None], vs[:, 3 * n + 1, None]
        k0 = 3 * n + 2
        imag = []  # imaginary parts (B_1..B_n, U'', L'') of the baseline or of a term
        if cplx:
            imag.append(vs[:, k0:k0 + n + 2])
            k0 += n + 2
        rest = vs[:, k0:]
        f_fac = np.ones((vs.shape[0], n, w.size))
        z_fac = np.ones((vs.shape[0], n, w.size))
        a_fac = None
        res_fac = [1.0, 1.0]  # the residual terms U, L (a law's factors)
        delay = np.zeros((vs.shape[0], 1))
        phase = np.zeros((vs.shape[0], 1))
        i = 0
        for t in terms:
            p = rest[:, i:i + t.size]
            i += t.size
            if t.kind == "level":
                f_fac[:, t.mode] = f_fac[:, t.mode] * (1 + p[:, 0, None] * t.data["log_level"])
                z_fac[:, t.mode] = z_fac[:, t.mode] * (1 + p[:, 1, None] * t.data["log_level"])
            elif t.kind == "shift":
                f_fac = f_fac * 10.0 ** (-p[:, 0, None, None] * t.data["dc"])
            elif t.kind == "level_all":  # every mode by one log-level law
                f_fac = f_fac * (1 + p[:, 0, None, None] * t.data["log_level"])
                z_fac = z_fac * (1 + p[:, 1, None, None] * t.data["log_level"])
            elif t.kind == "per_level":  # a free factor per level (k: levels but the ref)
                ind = t.data["indicator"]  # (k, N)
                k = ind.shape[0]
                f_fac = f_fac * (1 + (p[:, :k] @ ind)[:, None, :])
                z_fac = z_fac * (1 + (p[:, k:2 * k] @ ind)[:, None, :])
            elif t.kind == "delay":
                delay = delay + p[:, 0, None]
            elif t.kind == "phase":  # a constant phase of the channel (form choice only)
                phase = phase + p[:, 0, None]
            elif t.kind == "complex":
                imag.append(p)
            elif t.kind == "law":  # each moving coordinate by its law (:mod:`.laws`)
                j = 0
                for r, which, law, k in t.data["coords"]:
                    lf = laws.log_factor(law, [p[:, j + q, None] for q in range(k)],
                                         t.data["x"], t.data["cov"], t.data["level_index"])
                    j += k
                    if which == "stiffness":  # w_r^2
                        f_fac[:, r] = f_fac[:, r] * np.exp(0.5 * lf)
                    elif which == "damping":
                        z_fac[:, r] = z_fac[:, r] * np.exp(lf)
                    elif which == "upper residual":
                        res_fac[0] = res_fac[0] * np.exp(lf)
                    elif which == "lower residual":
                        res_fac[1] = res_fac[1] * np.exp(lf)
                    else:
                        a_fac = np.ones((vs.shape[0], n, w.size)) if a_fac is None else a_fac
                        a_fac[:, r] = a_fac[:, r] * np.exp(lf)
        for p in imag:  # A_r + j (w / w_r) B_r: the pole-pair form, a real impulse response
            ar = ar + 1j * p[:, :n, None] * (w / (2 * np.pi * fr))
            u = u + 1j * p[:, n, None]
            low = low + 1j * p[:, n + 1, None]
        wr = 2 * np.pi * fr * f_fac
        z = zr * z_fac
        ar = ar if a_fac is None else ar * a_fac
        u, low = u * res_fac[0], low * res_fac[1]
        h = np.sum(ar / (wr**2 - w**2 + 2j * z * wr * w), axis=1) + u - low / w**2
        out = h * np.exp(-1j * (w * delay - phase))
        return out if np.ndim(v) == 2 else out[0]

    def _params(self, n, values, cplx=None) -> tuple[ParamSpec, ...]:
        cplx = self.complex_constants if cplx is None else cplx
        f = self.observations.axis
        f_lo, f_hi = float(f.min()), float(f.max())
        h_scale = float(np.median(np.abs(self.observations.values)))
        w_mid = 2 * np.pi * np.sqrt(f_lo * f_hi)
        out = []
        for r in range(n):
            fr, zr, ar = values[3 * r: 3 * r + 3]
            # a modal constant's size: |A| ~ |H| 2 z w_r^2 near its resonance (a start of ~0
            # must not set a vanishing scale)
            a_scale = max(abs(ar), h_scale * 0.02 * (2 * np.pi * fr) ** 2)
            out += [ParamSpec(f"f_{r + 1}", "Hz", fr, 0.5 * f_lo, 2.0 * f_hi, log=True,
                              at_lower="a mode below the band", at_upper="a mode above the band"),
                    ParamSpec(f"zeta_{r + 1}", "-", zr, 1e-4, 0.5, log=True,
                              at_lower="damping below 0.01 %: a resolution limit",
                              at_upper="damping above 50 %: not a mode"),
                    ParamSpec(f"A_{r + 1}", "1/kg", ar, -np.inf, np.inf, scale=a_scale)]
        out += [ParamSpec("U", "m/N", values[3 * n], -np.inf, np.inf, scale=h_scale),
                ParamSpec("L", "m/N rad^2/s^2", values[3 * n + 1], -np.inf, np.inf,
                          scale=h_scale * w_mid**2)]
        if cplx:  # the imaginary parts of the modal constants (at resonance) and residuals
            k0 = 3 * n + 2
            out += [ParamSpec(f"B_{r + 1}", "1/kg", values[k0 + r], -np.inf, np.inf,
                              scale=out[3 * r + 2].scale) for r in range(n)]
            out += [ParamSpec("U_imag", "m/N", values[k0 + n], -np.inf, np.inf, scale=h_scale),
                    ParamSpec("L_imag", "m/N rad^2/s^2", values[k0 + n + 1], -np.inf, np.inf,
                              scale=h_scale * w_mid**2)]
        return tuple(out)

    def n_base_params(self, n, cplx=None) -> int:
        """Parameters of the n-mode model without effects."""
        cplx = self.complex_constants if cplx is None else cplx
        return 3 * n + 2 + (n + 2 if cplx else 0)

    def _linear(self, freqs, zetas, points, cplx=None):
        """Modal constants and residuals by linear least squares for given (f_r, z_r) (with
        complex constants the LSFD of EMA tools: a real and an imaginary part each), and the
        weighted residual of that solution (real and imaginary parts stacked)."""
        cplx = self.complex_constants if cplx is None else cplx
        w = self.omega[points]
        y = self.observations.values[points]
        u = 1.0 / np.abs(y)
        modes = [1.0 / ((2 * np.pi * fr) ** 2 - w**2 + 2j * zr * 2 * np.pi * fr * w)
                 for fr, zr in zip(freqs, zetas)]
        cols = modes + [np.ones_like(w, dtype=complex), -1.0 / w**2 + 0j]
        if cplx:
            cols += [1j * (w / (2 * np.pi * fr)) * m for fr, m in zip(freqs, modes)]
            cols += [1j * np.ones_like(w), -1j / w**2]
        a = np.column_stack(cols) * u[:, None]
        rhs = y * u
        m = np.vstack([a.real, a.imag])
        b = np.concatenate([rhs.real, rhs.imag])
        # normal equations of the column-scaled system: a few columns, hundreds of rows
        norm = np.linalg.norm(m, axis=0)
        norm[norm == 0] = 1.0
        ms = m / norm
        try:
            sol = np.linalg.solve(ms.T @ ms, ms.T @ b) / norm
        except np.linalg.LinAlgError:
            sol = np.linalg.lstsq(m, b, rcond=None)[0]
        return sol, m @ sol - b

    def _projected(self, freqs, zetas, points, cplx=None):
        """Frequencies and damping ratios refined by variable projection: the modal constants
        and residuals solved exactly for each (f_r, z_r), only those 2 N values iterated.
        Started at peaks on a coarse grid of damping ratios, the full fit otherwise lands in
        a local minimum whenever the modes are lighter or closer than the starts assume."""
        f = self.observations.axis
        lo = np.log(np.r_[0.5 * f.min(), 1e-4])
        hi = np.log(np.r_[2.0 * f.max(), 0.5])
        n = len(freqs)
        x0 = np.log(np.ravel(np.column_stack([freqs, zetas])))
        x0 = np.clip(x0, np.tile(lo, n) + 1e-9, np.tile(hi, n) - 1e-9)

        def resid(x):
            e = np.exp(x)
            with np.errstate(all="ignore"):
                r = self._linear(e[0::2], e[1::2], points, cplx)[1]
            return np.where(np.isfinite(r), r, 1e6)

        try:
            sol = least_squares(resid, x0, bounds=(np.tile(lo, n), np.tile(hi, n)),
                                max_nfev=15 * (n + 1), x_scale=1.0)
        except (ValueError, np.linalg.LinAlgError):
            return list(freqs), list(zetas)
        e = np.exp(sol.x)
        return list(e[0::2]), list(e[1::2])

    def _start(self, freqs, zetas, points, cplx=None) -> np.ndarray:
        """Modal constants and residuals by linear least squares for given (f_r, z_r)."""
        sol = self._linear(freqs, zetas, points, cplx)[0]
        n = len(freqs)
        out = []
        for r, (fr, zr) in enumerate(zip(freqs, zetas)):
            out += [fr, zr, sol[r]]
        return np.array(out + list(sol[n:]))

    def _order_spec(self, n, peaks, points, name=None, cplx=None) -> ModelSpec:
        cplx = self.complex_constants if cplx is None else cplx
        ref = points & (self.observations.groups == self.reference)
        ref = ref if ref.sum() >= 10 else points
        chosen = sorted(peaks[:n])
        starts = [self._start(chosen, [z] * n, ref, cplx) for z in (0.005, 0.02, 0.06)]
        best = min(((self._projected(chosen, [z] * n, ref, cplx)) for z in (0.002, 0.02)),
                   key=lambda fz: np.sum(self._linear(*fz, ref, cplx)[1] ** 2))
        projected = self._start(*best, ref, cplx)
        params = self._params(n, projected, cplx)

        def predict(v, n=n):
            return self._evaluate(v, n, [], cplx)

        return ModelSpec(name or model_name(n, cplx), None, params, 0, predict,
                         tuple(starts), batch_predict=predict)

    # --- Domain protocol -------------------------------------------------------------------
    def baseline(self, train: np.ndarray) -> ModelSpec:
        """N modes by the order rule (module docstring), started at the strongest peaks; real
        or complex modal constants (``constants``), each form's order by the rule, complex
        kept only when it beats real significantly in the same paired held-out test."""
        train = np.asarray(train, dtype=bool)
        self._train, self._stack, self._term_of = train, [], {}
        self._stack_params = []
        self._law_inputs, self.trends = None, []
        obs = self.observations
        ref = obs.groups == self.reference
        peaks = find_peaks(obs.axis[ref], obs.values[ref], self.max_modes)
        if not peaks:
            peaks = [float(np.sqrt(obs.axis.min() * obs.axis.max()))]
        self._peaks = peaks
        orders = [self.modes] if self.modes is not None else list(
            range(1, min(self.max_modes, len(peaks)) + 1))
        idx = np.nonzero(train)[0]
        inner_held = np.zeros_like(train)
        inner_held[idx[2::4]] = True
        inner = HoldoutSplit(train & ~inner_held, inner_held, "every 4th training point")
        counts = np.bincount(obs.groups)[np.unique(obs.groups)]
        lags = max(1, min(10, int(counts.min()) // 4))
        forms = {"real": (False,), "complex": (True,), "auto": (False, True)}[self.constants]
        chosen = {}
        for cplx in forms:
            # (complex constants never need more modes than real ones: a real model takes
            # extra modes for the phase complex constants give)
            tried = [n for n in orders if not (cplx and chosen and n > chosen[False][0].order)]
            fits = {n: fit_model(self._order_spec(n, peaks, train & ~inner_held, cplx=cplx),
                                 obs, inner, n_screen=3) for n in tried}

            def white(n, fits=fits):
                return (ljung_box(fits[n].residual, obs.groups, lags).p_value
                        >= self.whiteness_alpha)

            def doublet(n, fits=fits):
                v = np.array([e.value for e in fits[n].estimates])
                return has_doublet(v[0:3 * n:3], v[1:3 * n:3], self.doublet_bandwidths)

            choice = choose_order({n: np.abs(fit.residual[inner_held]) ** 2
                                   for n, fit in fits.items()}, self.order_z,
                                  {n: doublet(n) for n in fits}, white)
            chosen[cplx] = (choice, fits)
        cplx = forms[0]
        self._constants_reason = f"{'complex' if cplx else 'real'} modal constants (as asked)"
        if len(forms) == 2:
            cplx, self._constants_reason = self._choose_constants(
                chosen, peaks, train & ~inner_held, inner)
        self.complex_constants = cplx
        choice, fits = chosen[cplx]
        n = choice.order
        self._n, self._order_choice = n, choice
        self._order_errors = {m: fit.error for m, fit in fits.items()}
        self._form_errors = {model_name(m, c): fit.error
                             for c in forms for m, fit in chosen[c][1].items()}
        values = np.array([e.value for e in fits[n].estimates])
        spec = self._order_spec(n, peaks, train)
        return ModelSpec(spec.name, None, self._params(n, values), 0, spec.predict,
                         (values, *spec.starts), batch_predict=spec.predict)

    def _choose_constants(self, chosen, peaks, train, inner):
        """Real or complex modal constants (both forms fitted, each at its own order).

        Complex constants are kept when they lower the paired held-out squared error of real
        ones by more than ``order_z`` standard errors, unless one delay of the channel explains
        the same phase: to first order in w tau a delay is a set of complex constants, B_r =
        -w_r tau A_r, so complex constants would absorb every delay. The delay counts when
        it is identified (the real model with it beats the real model with a constant phase,
        which in a narrow band fits the same) and complex constants do not beat it."""
        held = inner.held
        real_n, cplx_n = chosen[False][0].order, chosen[True][0].order
        sq = {name: np.abs(chosen[c][1][chosen[c][0].order].residual[held]) ** 2
              for name, c in (("real", False), ("complex", True))}
        z = self.order_z

        def beats(a, b):
            gain, se = paired_excess(sq[b], sq[a])
            return gain > z * se, gain, se

        ok, gain, se = beats("complex", "real")
        head = (f"complex (N={cplx_n}) against real (N={real_n}) constants: paired held-out "
                f"squared error {gain:.3g} +- {se:.2g} lower per point")
        if not ok:
            return False, f"real modal constants: {head}, not more than {z:g} standard errors"
        # the delay on the real model of the complex form's order (a real model of its own
        # order may have taken extra modes for the phase a delay makes)
        real = chosen[False][1][cplx_n]
        f_max = float(self.observations.axis.max())
        base = np.array([e.value for e in real.estimates])
        for kind, param, starts in (
                ("delay", ParamSpec("tau", "s", 0.0, -0.5 / f_max, 2.0 / f_max,
                                    scale=0.1 / f_max), np.linspace(-0.4, 1.9, 24) / f_max),
                ("phase", ParamSpec("phi", "rad", 0.0, -np.pi, np.pi, scale=0.1),
                 np.linspace(-3.0, 3.0, 13))):
            term = ModalTerm("sensor_delay", "", kind, 1)

            def predict(v, term=term):
                return self._evaluate(v, cplx_n, [term], False)

            params = self._params(cplx_n, base, False) + (param,)
            spec = ModelSpec(f"{kind}", None, params, 1, predict,
                             tuple(np.r_[base, t] for t in starts), batch_predict=predict)
            sq[kind] = np.abs(fit_model(spec, self.observations, inner, n_screen=3)
                              .residual[held]) ** 2
        identified, g_d, s_d = beats("delay", "phase")
        over, g_c, s_c = beats("complex", "delay")
        if identified and not over:
            chosen[False] = (replace(chosen[False][0], order=cplx_n), chosen[False][1])
            return False, (f"real modal constants (N={cplx_n}): {head}, but one delay of the "
                           f"channel explains the phase as well (complex {g_c:.3g} +- {s_c:.2g} "
                           f"lower than real with a delay; the delay beats a constant phase by "
                           f"{g_d:.3g} +- {s_d:.2g}): the loop tests the delay")
        return True, (f"complex modal constants: {head}, more than {z:g} standard errors"
                      + ("" if identified else "; a delay is not told from a constant phase "
                         "in this band") + (f"; and {g_c:.3g} +- {s_c:.2g} lower than real "
                                            "with a delay" if identified else ""))

    @property
    def form_errors(self) -> dict:
        """Model name (modes, real or complex constants) -> held-out error on the training
        split, every form tried."""
        return dict(self._form_errors)

    @property
    def constants_reason(self) -> str:
        """Why the baseline's modal constants are real or complex (after :meth:`baseline`)."""
        return self._constants_reason

    @property
    def baseline_order(self) -> int:
        """Number of modes of the baseline (after :meth:`baseline`)."""
        if self._n is None:
            raise ValueError("baseline() has not been called")
        return self._n

    @property
    def order_choice(self):
        """The :class:`~dva_offline.discrepancy.model_order.OrderChoice` of the baseline."""
        return self._order_choice

    @property
    def order_errors(self) -> dict:
        """Modes -> held-out error of the refined model on the training split."""
        return dict(self._order_errors)

    def _model_name(self) -> str:
        return model_name(self._n, self.complex_constants) + "".join(
            f" + {t.effect}" + (f"({t.label})" if t.label else "") for t in self._stack)

    def _spec(self, base_values, stack_params, term, added, starts, label):
        terms = [*self._stack, term]
        n = self._n

        def predict(v, terms=terms):
            return self._evaluate(v, n, terms)

        params = self._params(n, base_values) + tuple(stack_params) + tuple(added)
        init = np.array([p.initial for p in added])
        full = tuple(np.concatenate([base_values[:len(params) - len(added)], s])
                     for s in [init, *starts])
        name = self._model_name() + f" + {term.effect}" + (f"({label})" if label else "")
        spec = ModelSpec(name, term.effect, params, len(added), predict, full[1:],
                         SIGNATURES[term.effect], label, batch_predict=predict)
        self._term_of[name] = (term, tuple(added))
        return spec

    def candidates(self, baseline: ModelFit, features: ResidualFeatures):
        """The candidate library (module docstring), started from the fitted baseline."""
        n = self._n
        values = np.array([e.value for e in baseline.estimates])
        stack_params = list(self._params_of_stack)
        present = {(t.effect, t.label) for t in self._stack}
        levelled = {(t.label.partition(", ")[0], t.mode) for t in self._stack
                    if t.kind == "level"}
        out: list[ModelSpec | NotApplicable] = []
        f_max = float(self.observations.axis.max())
        if ("sensor_delay", "") not in present:
            tau_eq = features.phase.equivalent_delay_s if features.phase is not None else 0.0
            lo_t, hi_t = -0.5 / f_max, 2.0 / f_max
            starts = [np.array([t]) for t in (tau_eq, *np.linspace(lo_t, hi_t, 21)[1:-1])
                      if lo_t < t < hi_t]
            out.append(self._spec(values, stack_params,
                                  ModalTerm("sensor_delay", "", "delay", 1),
                                  (ParamSpec("tau", "s", 0.0, lo_t, hi_t, scale=0.1 / f_max),),
                                  starts, ""))
        out.append(self._complex_candidate(values, stack_params, present))
        varying = self._varying()
        if not varying:
            reason = "needs sweeps at >= 2 levels of a covariate (excitation level, temperature)"
            out += [NotApplicable("amplitude_dependence", reason),
                    NotApplicable("covariate_shift", reason)]
        for name, col in varying.items():
            ref = self._level(name)
            if np.all(col > 0):
                lev = np.log(col / ref)
                bound = 0.5 / float(np.max(np.abs(lev)))
                for r in range(n):
                    label = f"{name}, mode {r + 1} ({values[3 * r]:.4g} Hz)"
                    if (name, r) in levelled:
                        continue
                    out.append(self._spec(
                        values, stack_params,
                        ModalTerm("amplitude_dependence", label, "level", 2, r,
                                  {"log_level": lev}),
                        (ParamSpec("s_f", "-", 0.0, -bound, bound, scale=0.01),
                         ParamSpec("s_z", "-", 0.0, -1.5 * bound, 1.5 * bound, scale=0.1)),
                        [np.array([a, b]) for a in (-0.03, -0.01, 0.01, 0.03)
                         for b in (-0.3, 0.0, 0.3)], label))
            else:
                out.append(NotApplicable("amplitude_dependence",
                                         f"covariate {name!r} has values <= 0 (not a level)",
                                         name))
            if is_level(name) and np.all(col > 0):
                out += self._level_laws(name, col, ref, values, stack_params, present)
            elif ("covariate_shift", f"{name}, exponential") not in present:
                dc = col - ref
                span = float(np.max(np.abs(dc))) or 1.0
                out.append(self._spec(
                    values, stack_params,
                    ModalTerm("covariate_shift", f"{name}, exponential", "shift", 1,
                              data={"dc": dc}),
                    (ParamSpec("b", f"1/({name})", 0.0, -0.5 / span, 0.5 / span,
                               scale=0.01 / span),),
                    [np.array([s / span]) for s in (-0.03, -0.01, 0.01, 0.03)],
                    f"{name}, exponential"))
        for effect in ("maxwell_element", "fixture_mass", "foundation_mode"):
            out.append(NotApplicable(effect, "an isolator effect; the modal baseline of a "
                                             "structure has no mount"))
        return out

    def _level_laws(self, name, col, ref, values, stack_params, present):
        """A level covariate shifts every mode: the smooth log-level law, and a free
        frequency and damping factor per level (follows a jump between levels, e.g. a joint
        that slips above some force), each an ``amplitude_dependence`` of all modes."""
        out = []
        lev = np.log(col / ref)
        bound = 0.5 / float(np.max(np.abs(lev)))
        label = f"{name}, all modes"
        if ("amplitude_dependence", label) not in present:
            out.append(self._spec(
                values, stack_params,
                ModalTerm("amplitude_dependence", label, "level_all", 2,
                          data={"log_level": lev}),
                (ParamSpec("s_f", "-", 0.0, -bound, bound, scale=0.01),
                 ParamSpec("s_z", "-", 0.0, -1.5 * bound, 1.5 * bound, scale=0.1)),
                [np.array([a, b]) for a in (-0.03, -0.01, 0.01, 0.03) for b in (-0.3, 0.0, 0.3)],
                label))
        groups = self.observations.groups
        levels = [g for g in np.unique(groups) if g != self.reference]
        label = f"{name}, per level, all modes"
        if levels and ("amplitude_dependence", label) not in present:
            ind = np.array([(groups == g).astype(float) for g in levels])
            k = len(levels)
            params = tuple(ParamSpec(f"df_{i + 1}", "-", 0.0, -0.5, 0.5, scale=0.01)
                           for i in range(k)) + tuple(
                ParamSpec(f"dz_{i + 1}", "-", 0.0, -0.9, 5.0, scale=0.1) for i in range(k))
            out.append(self._spec(
                values, stack_params,
                ModalTerm("amplitude_dependence", label, "per_level", 2 * k,
                          data={"indicator": ind}),
                params, [np.concatenate([np.full(k, a), np.full(k, b)])
                         for a in (-0.02, 0.02) for b in (0.0, 0.5)], label))
        return out

    def _complex_candidate(self, values, stack_params, present):
        """Complex modal constants on the current model (the baseline's form was real): the
        imaginary parts B_r, U'', L'' enter linearly, so their start is the linear least
        squares solution on the training points (the LSFD of EMA tools, the poles held)."""
        if self.complex_constants or ("complex_modes", "") in present:
            return NotApplicable("complex_modes", "the model's modal constants are complex")
        n = self._n
        term = ModalTerm("complex_modes", "", "complex", n + 2)
        real = self._params(n, values[:3 * n + 2], False)
        added = tuple(ParamSpec(p.name, p.unit, 0.0, -np.inf, np.inf, scale=p.scale) for p in
                      self._params(n, np.r_[values[:3 * n + 2], np.zeros(n + 2)], True)
                      [len(real):])
        spec = self._spec(values, stack_params, term, added, [], "")
        obs, train = self.observations, self._train
        full = np.r_[values, np.zeros(n + 2)]
        scales = np.array([p.scale for p in added])
        base = spec.predict(full)
        cols = np.column_stack([(spec.predict(full + np.r_[np.zeros(values.size), e]) - base)
                                for e in np.diag(scales)])
        a = (cols * obs.weights[:, None])[train]
        b = ((obs.values - base) * obs.weights)[train]
        sol = np.linalg.lstsq(np.vstack([a.real, a.imag]), np.r_[b.real, b.imag],
                              rcond=None)[0] * scales
        return replace(spec, starts=(np.r_[values, sol], *spec.starts))

    def _law_trends(self, reference) -> list:
        """Per covariate: each mode's stiffness w_r^2, damping ratio and modal constant, and
        the residual terms U and L, in every condition, from the baseline fitted to that
        condition alone, and their laws (:func:`.laws.find_law`; every coordinate gets one,
        those that do not move are ``offered``); computed once (the per-condition fits do
        not change)."""
        if self._law_inputs is not None:
            return self._law_inputs
        obs, n = self.observations, self._n
        g = obs.groups
        own = reference.per_condition if reference is not None else {}
        labels = sorted(own)
        out = []
        if len(labels) >= 2 and self.reference in own:
            est = {lab: {e.name: e for e in own[lab]} for lab in labels}
            for name, col in self._varying().items():
                effect = ("amplitude_dependence" if is_level(name) and np.all(col > 0)
                          else "covariate_shift")
                cov = laws.covariate_info(name, col, g, self.reference,
                                          laws.kelvin_offset(name))
                x = np.array([col[g == lab].mean() for lab in labels])
                trends = []
                for r in range(n):
                    f = np.array([est[lab][f"f_{r + 1}"].value for lab in labels])
                    sf = np.array([est[lab][f"f_{r + 1}"].std for lab in labels])
                    z = np.array([est[lab][f"zeta_{r + 1}"].value for lab in labels])
                    sz = np.array([est[lab][f"zeta_{r + 1}"].std for lab in labels])
                    a = np.array([est[lab][f"A_{r + 1}"].value for lab in labels])
                    sa = np.array([est[lab][f"A_{r + 1}"].std for lab in labels])
                    coords = [("stiffness", f**2, 2 * f * sf), ("damping", z, sz)]
                    if f"B_{r + 1}" in est[labels[0]]:  # complex: its size at resonance
                        b = np.array([est[lab][f"B_{r + 1}"].value for lab in labels])
                        sb = np.array([est[lab][f"B_{r + 1}"].std for lab in labels])
                        size = np.hypot(a, b)
                        coords.append(("modal constant", size,
                                       np.hypot(a * sa, b * sb) / np.maximum(size, 1e-300)))
                    elif np.all(a > 0) or np.all(a < 0):  # a sign change is no factor
                        coords.append(("modal constant", np.abs(a), sa))
                    for which, y, s in coords:
                        t = laws.find_law(effect, cov, f"mode {r + 1} {which}",
                                          (r, which), x, y, s, offer=True)
                        if t is not None:
                            trends.append(t)
                # the residual terms (the modes outside the band) as factors
                for p, which in (("U", "upper residual"), ("L", "lower residual")):
                    y = np.array([est[lab][p].value for lab in labels])
                    s = np.array([est[lab][p].std for lab in labels])
                    if np.all(y > 0) or np.all(y < 0):
                        t = laws.find_law(effect, cov, which, (None, which), x, np.abs(y), s,
                                          offer=True)
                        if t is not None:
                            trends.append(t)
                out.append((name, effect, cov, trends))
        self._law_inputs = out
        self.trends = [t for *_, ts in out for t in ts]
        return out

    def law_candidates(self, baseline: ModelFit, reference) -> list:
        """Each covariate's effect with the laws its moving coordinates follow (label
        ``COVARIATE, law``), started at the reference condition's own fit with the laws
        fitted to the per-condition values; the joint fit refines all of it."""
        out = []
        values = np.array([e.value for e in baseline.estimates])
        stack_params = list(self._params_of_stack)
        present = {(t.effect, t.label) for t in self._stack}
        own = reference.per_condition if reference is not None else {}
        for name, effect, cov, trends in self._law_trends(reference):
            label = f"{name}, law"
            if any((effect, lab) in present
                   for lab in (label, f"{label}, all coordinates")):
                continue
            moving = [t for t in trends if t.moving]
            if not moving:
                out.append(NotApplicable(effect, f"no mode's stiffness, damping or modal "
                                                 f"constant moves with {name} beyond its "
                                                 "errors", label))
                continue
            # the effect as its moving coordinates carry it, and its full form with every
            # coordinate (the loop keeps it only when it beats the first by the ambiguity
            # margin: parameters that move together can each pass for constant alone)
            offered = [t for t in trends if t.offered]
            forms = [(label, moving)] + ([(f"{label}, all coordinates", moving + offered)]
                                         if offered else [])
            for lab, used in forms:
                out.append(self._law_spec(name, effect, cov, trends, used, lab, values,
                                          stack_params, own))
        return out

    def _law_spec(self, name, effect, cov, trends, used, label, values, stack_params, own):
        """The effect whose coordinates ``used`` follow their laws (the others constant)."""
        g = self.observations.groups
        coords, added, parts = [], [], []
        short = {"stiffness": "k", "damping": "z", "modal constant": "A",
                 "upper residual": "U", "lower residual": "L"}
        for t in used:
            r, which = t.key
            sc = t.chosen
            theta = sc.theta if sc is not None else ()
            prefix = short[which] + ("" if r is None else f"{r + 1}")
            specs = laws.param_specs(t.law, cov, theta, prefix, name)
            coords.append((r, which, t.law, len(specs)))
            added += specs
            parts.append(laws.LawPart(t.coordinate, t.law, tuple(p.name for p in specs)))
        col = self.observations.covariates[name]
        means = np.array([col[g == lab].mean() for lab in range(len(self.conditions))])
        term = ModalTerm(effect, label, "law", len(added),
                         data={"coords": coords, "x": col, "cov": cov,
                               "level_index": cov.level_index(means[g])})
        spec = self._spec(values, stack_params, term, tuple(added), [], label)
        law = laws.LawModel(effect, cov, tuple(parts),
                            tuple(t.coordinate for t in trends
                                  if all(t is not u for u in used)),
                            tuple(t.coordinate for t in used if t.offered))
        # the reference condition's own fit (the laws are normalised there) first
        starts = list(spec.starts)
        if self.reference in own:
            head = np.array([e.value for e in own[self.reference]])
            init = np.array([p.initial for p in added])
            starts.insert(0, np.concatenate([head, values[head.size:len(values)], init]))
        return replace(spec, starts=tuple(starts), n_priority=1, law=law)

    @property
    def _params_of_stack(self):
        return getattr(self, "_stack_params", [])

    def augment(self, spec: ModelSpec, fit: ModelFit) -> None:
        """The chosen candidate becomes the next step's baseline (effects stack)."""
        term, added = self._term_of[spec.name]
        self._stack.append(term)
        self._stack_params = [*self._params_of_stack, *added]
