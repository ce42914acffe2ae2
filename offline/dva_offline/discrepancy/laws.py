"""The law a covariate effect follows, found from the per-condition fits.

An expert traces an effect outside any catalogue in three steps: fit each condition alone,
see which parameters move with the covariate, find the law they follow. Here:

1. **Per condition.** A domain turns the baseline fitted to each condition alone (the
   saturated reference, :mod:`.saturated`) into the effect's *coordinates*, positive
   factors with a standard error per condition: a mode's stiffness w_r^2 and damping ratio,
   a mount's storage and loss parts, a shift factor a_T of the frequency axis.
2. **Moving.** A coordinate moves with the covariate when its per-condition values differ
   from one constant beyond their errors: chi^2 = sum_g (ln y_g - m)^2 / s_g^2 (m the
   weighted mean, s_g the standard error of ln y_g) exceeds the chi^2 quantile with G - 1
   degrees of freedom at ``alpha`` (default 1e-3, the loop's significance).
3. **Law.** Each moving coordinate's trend ln y_g = ln A + ln F(x_g; theta) is fitted with
   every law of :data:`LAWS` that applies to the covariate (A free: the level at the
   reference is the baseline's), and the law is chosen by a held-out score: each condition
   left out in turn, the law fitted to the others predicts it, z_g^2 = (ln y_g - pred)^2 /
   (s_g^2 + var(pred)); the score is sum z_g^2. A law with fewer parameters is preferred
   while its score is within two standard errors of the best's (paired over the
   conditions, the rule of :mod:`.model_order`). When even that law predicts the left-out
   conditions worse than their errors allow (score above the chi^2 quantile with G degrees
   of freedom at ``alpha``), or there are too few conditions to leave one out, the
   coordinate is ``free`` per level of the covariate (a jump no smooth law follows, e.g. a
   joint that slips).

The family (every law F(x0) = 1 at the reference level x0):

============  ===========================================  ===========================
law           F(x)                                         applies to
============  ===========================================  ===========================
constant      1                                            any covariate
linear        1 + s (x - x0)                               any
exponential   exp(s (x - x0))                              any
power         (x / x0)^p                                   positive x (kelvin for T)
power_change  1 + d ((x / x0)^e - 1): the change ~ x^e     positive x (kelvin for T)
logarithmic   1 + s ln(x / x0)                             positive x (kelvin for T)
arrhenius     exp(E_a / R (1/T - 1/T0)), T in kelvin       temperatures
wlf           10^(-C1 (T - T0) / (C2 + T - T0))            temperatures
free          F_k per level of the covariate               any (>= 2 levels)
============  ===========================================  ===========================

The domain then builds the named effect's model from the chosen laws (the library's names
stay the vocabulary, the law is the form) and the loop fits it to the whole data and scores
it on held-out points like any candidate. Pure numerics: no file access.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from dva_offline.discrepancy.fitting import ParamSpec

R_GAS = 8.314462618  # J/(mol K)
LN10 = float(np.log(10.0))
SMOOTH = ("linear", "exponential", "power", "power_change", "logarithmic", "arrhenius", "wlf")
LAWS = ("constant", *SMOOTH, "free")
# shape parameters of each law: (name, unit kind) -- "inv" is 1/covariate unit
PARAM_NAMES = {
    "constant": (), "linear": (("s", "inv"),), "exponential": (("s", "inv"),),
    "power": (("p", "-"),), "power_change": (("d", "-"), ("e", "-")),
    "logarithmic": (("s", "-"),), "arrhenius": (("E_a", "J/mol"),),
    "wlf": (("C1", "-"), ("C2", "K")),
}


@dataclass(frozen=True)
class Covariate:
    """What the laws need to know about a covariate.

    Attributes
    ----------
    name : str
    x0 : float
        Reference level (the reference condition's mean), in the covariate's unit.
    kelvin_offset : float or None
        Added to the covariate to make an absolute temperature (273.15 for Celsius, 0 for
        kelvin); None when it is no temperature.
    levels : tuple of float
        The distinct levels of the covariate (conditions' means, close ones merged), the
        reference among them; ``free`` has one factor per level but the reference.
    lo, hi : float
        Range of the covariate over the data (per point).
    """

    name: str
    x0: float
    kelvin_offset: float | None
    levels: tuple
    lo: float
    hi: float

    @property
    def positive(self) -> bool:
        return self.lo + (self.kelvin_offset or 0.0) > 0

    def absolute(self, x):
        return np.asarray(x, float) + (self.kelvin_offset or 0.0)

    def level_index(self, x) -> np.ndarray:
        """Index of the nearest level of each x among the levels other than the reference
        (-1 at the reference level)."""
        lv = np.asarray(self.levels, float)
        near = np.argmin(np.abs(np.asarray(x, float)[..., None] - lv), axis=-1)
        ref = int(np.argmin(np.abs(lv - self.x0)))
        return np.where(near == ref, -1, near - (near > ref))

    @property
    def n_free(self) -> int:
        return len(self.levels) - 1


def applicable(law: str, cov: Covariate) -> bool:
    """Whether ``law`` is in the family for this covariate."""
    if law in ("power", "power_change", "logarithmic"):
        return cov.positive
    if law in ("arrhenius", "wlf"):
        return cov.kelvin_offset is not None and cov.positive
    if law == "free":
        return cov.n_free >= 1
    return law in LAWS


def n_params(law: str, cov: Covariate) -> int:
    """Shape parameters of ``law`` (without the level at the reference)."""
    return cov.n_free if law == "free" else len(PARAM_NAMES[law])


def log_factor(law: str, theta: Sequence, x, cov: Covariate, level_index=None):
    """ln F(x; theta); ``theta`` entries may be arrays that broadcast against ``x`` (many
    parameter vectors at once); NaN where the law is not positive. ``level_index``: each
    x's level (:meth:`Covariate.level_index`), for ``free``."""
    x = np.asarray(x, float)
    with np.errstate(all="ignore"):
        if law == "constant":
            return np.zeros_like(x)
        if law == "linear":
            return np.log(1.0 + theta[0] * (x - cov.x0))
        if law == "exponential":
            return theta[0] * (x - cov.x0)
        ratio = cov.absolute(x) / cov.absolute(cov.x0)
        if law == "power":
            return theta[0] * np.log(ratio)
        if law == "power_change":
            return np.log(1.0 + theta[0] * (ratio ** theta[1] - 1.0))
        if law == "logarithmic":
            return np.log(1.0 + theta[0] * np.log(ratio))
        t, t0 = cov.absolute(x), cov.absolute(cov.x0)
        if law == "arrhenius":
            return theta[0] / R_GAS * (1.0 / t - 1.0 / t0)
        if law == "wlf":
            dt = t - t0
            return -LN10 * theta[0] * dt / (theta[1] + dt)
        if law == "free":
            idx = cov.level_index(x) if level_index is None else np.asarray(level_index)
            out = np.zeros(np.broadcast_shapes(np.shape(theta[0]), x.shape)) if theta else \
                np.zeros_like(x)
            for k, f in enumerate(theta):
                out = np.where(idx == k, np.log(f), out)
            return out
    raise ValueError(f"law must be one of {LAWS}, got {law!r}")


def param_specs(law: str, cov: Covariate, start: Sequence, prefix: str,
                covariate_unit: str = "") -> tuple[ParamSpec, ...]:
    """The law's shape parameters as :class:`ParamSpec` (names ``prefix.name``), with
    bounds that keep F positive and finite over the covariate's range where the law allows
    it; started at ``start``."""
    unit_inv = f"1/{covariate_unit or cov.name}"
    lo, hi = cov.lo - cov.x0, cov.hi - cov.x0  # lo <= 0 <= hi
    span = max(hi - lo, 1e-12)
    out = []

    def add(name, unit, value, lower, upper, scale=1.0, log=False):
        value = float(np.clip(value, lower, upper)) if not log else float(
            np.clip(value, lower * 1.0001, upper / 1.0001))
        out.append(ParamSpec(f"{prefix}.{name}", unit, value, lower, upper, log=log,
                             scale=scale))

    if law in ("linear", "logarithmic"):
        if law == "linear":
            d_lo, d_hi, unit = lo, hi, unit_inv
        else:
            r_lo = np.log(cov.absolute(cov.lo) / cov.absolute(cov.x0))
            r_hi = np.log(cov.absolute(cov.hi) / cov.absolute(cov.x0))
            d_lo, d_hi, unit = r_lo, r_hi, "-"
        reach = max(d_hi - d_lo, 1e-12)
        upper = 0.98 / -d_lo if d_lo < 0 else 100.0 / reach
        lower = -0.98 / d_hi if d_hi > 0 else -100.0 / reach
        add("s", unit, start[0], lower, upper, scale=0.1 / reach)
    elif law == "exponential":
        add("s", unit_inv, start[0], -20.0 / span, 20.0 / span, scale=0.1 / span)
    elif law == "power":
        add("p", "-", start[0], -6.0, 6.0, scale=0.1)
    elif law == "power_change":
        add("d", "-", start[0], -3.0, 0.99, scale=0.1)
        add("e", "-", start[1], 0.2, 6.0, scale=0.1)
    elif law == "arrhenius":
        add("E_a", "J/mol", start[0], -2e6, 2e6, scale=1e4)
    elif law == "wlf":
        c2_min = max(-lo, 0.0) + 1.0
        add("C1", "-", start[0], -300.0, 300.0, scale=1.0)
        add("C2", "K", start[1], c2_min, 1e4, log=True)
    elif law == "free":
        for k in range(cov.n_free):
            add(f"F_{k + 1}", "-", start[k] if k < len(start) else 1.0, np.exp(-6.0),
                np.exp(6.0), log=True)
    return tuple(out)


def _bounds(law: str, cov: Covariate):
    specs = param_specs(law, cov, _starts(law, cov)[0] if law != "free" else
                        [1.0] * cov.n_free, "t")
    return (np.array([p.lower for p in specs]), np.array([p.upper for p in specs]))


def _starts(law: str, cov: Covariate) -> list[list[float]]:
    span = max(cov.hi - cov.lo, 1e-12)
    if law == "constant":
        return [[]]
    if law in ("linear", "exponential"):
        return [[a / span] for a in (-0.3, -0.03, 0.03, 0.3)]
    if law == "power":
        return [[p] for p in (-1.0, -0.1, 0.1, 1.0)]
    if law == "power_change":
        return [[d, e] for d in (-0.1, 0.1) for e in (0.5, 1.5, 3.0)]
    if law == "logarithmic":
        return [[s] for s in (-0.1, -0.01, 0.01, 0.1)]
    if law == "arrhenius":
        return [[e] for e in (-1e5, -1e4, 1e4, 1e5)]
    if law == "wlf":
        c2 = max(cov.x0 - cov.lo, 0.0) + 50.0
        return [[c1, c2 * m] for c1 in (-10.0, -1.0, 1.0, 10.0) for m in (1.0, 4.0)][::2]
    return [[1.0] * cov.n_free]


@dataclass(frozen=True)
class LawScore:
    """One law fitted to a coordinate's trend.

    ``loco`` is the held-out score (sum of z_g^2 with each condition left out; NaN when
    the law has too many parameters to leave one out); ``chi2`` the in-sample weighted sum
    of squares; ``theta`` / ``theta_std`` the shape parameters fitted to all conditions."""

    law: str
    n_params: int
    loco: float
    loco_terms: tuple
    chi2: float
    theta: tuple
    theta_std: tuple
    log_scale: float


@dataclass(frozen=True)
class Trend:
    """A coordinate of an effect across the conditions, whether it moves, and its law.

    Attributes
    ----------
    effect, covariate, coordinate : str
        E.g. ``amplitude_dependence``, ``force_n``, ``mode 3 stiffness``.
    key : tuple
        The domain's handle of the coordinate.
    x, values, std : numpy.ndarray
        Per condition: the covariate's mean, the coordinate, its standard error.
    chi2, dof, p_value : float, int, float
        The moving test (chi^2 of ln values against one constant).
    moving : bool
    scores : tuple of LawScore
    law : str
        The chosen law (``constant`` when not moving and not offered).
    reason : str
        Why that law.
    offered : bool
        Not moving, but its law fitted all the same (``find_law(..., offer=True)``): the
        domain offers it in the effect's full form, which the loop keeps only when its
        held-out score beats the moving coordinates' form by the ambiguity margin.
    """

    effect: str
    covariate: str
    coordinate: str
    key: tuple
    x: np.ndarray
    values: np.ndarray
    std: np.ndarray
    chi2: float
    dof: int
    p_value: float
    moving: bool
    scores: tuple
    law: str
    reason: str
    offered: bool = False

    @property
    def chosen(self) -> LawScore | None:
        return next((s for s in self.scores if s.law == self.law), None)


def _fit_trend(law, cov, x, u, su, level_index, starts=None):
    """Weighted least squares of ln y = ln A + ln F(x; theta) from the law's starts (or
    ``starts``, full vectors); the best scipy result, None when none is finite."""
    lo, hi = _bounds(law, cov) if law != "constant" else (np.zeros(0), np.zeros(0))
    span_u = max(np.ptp(u), 1.0)
    lo = np.r_[u.min() - 10 * span_u, lo]
    hi = np.r_[u.max() + 10 * span_u, hi]

    def resid(v):
        with np.errstate(all="ignore"):
            r = (v[0] + log_factor(law, v[1:], x, cov, level_index) - u) / su
        return np.where(np.isfinite(r), r, 1e6)

    best = None
    la = np.average(u, weights=su**-2)
    for v0 in (starts if starts is not None else [np.r_[la, s] for s in _starts(law, cov)]):
        v0 = np.clip(v0, lo, hi)
        try:
            r = least_squares(resid, v0, bounds=(lo, hi) if len(lo) else (-np.inf, np.inf),
                              x_scale="jac", max_nfev=200)
        except ValueError:
            continue
        if np.all(np.abs(r.fun) < 1e6) and (best is None or r.cost < best.cost):
            best = r
    return best


def _fit_free(cov, x, u, su, level_index):
    """The free law fitted exactly in closed form: ln A at the reference level, ln F_k the
    weighted mean of each level's values minus it."""
    ref = level_index == -1
    if not ref.any():
        return None
    la = np.average(u[ref], weights=su[ref] ** -2)
    theta, std = [], []
    for k in range(cov.n_free):
        sel = level_index == k
        if not sel.any():
            theta.append(1.0)
            std.append(np.nan)
            continue
        w = su[sel] ** -2
        m = np.average(u[sel], weights=w)
        theta.append(float(np.exp(m - la)))
        std.append(float(np.exp(m - la) * np.sqrt(1 / w.sum() + 1 / np.sum(su[ref] ** -2))))
    resid = np.zeros_like(u)
    resid[ref] = u[ref] - la
    for k in range(cov.n_free):
        sel = level_index == k
        if sel.any():
            resid[sel] = u[sel] - la - np.log(theta[k])
    return la, tuple(theta), tuple(std), float(np.sum((resid / su) ** 2))


def _std(res, n_par):
    j = res.jac
    try:
        cov = np.linalg.pinv(j.T @ j)
    except np.linalg.LinAlgError:
        return np.full(n_par, np.nan), None
    return np.sqrt(np.clip(np.diag(cov), 0, None)), cov


def _score(law, cov, x, u, su, level_index) -> LawScore | None:
    """Fit to all conditions and the leave-one-condition-out score."""
    k = n_params(law, cov)
    if law == "free":
        fit = _fit_free(cov, x, u, su, level_index)
        if fit is None:
            return None
        la, theta, std, chi2 = fit
        return LawScore(law, k, np.nan, (), chi2, theta, std, la)
    full = _fit_trend(law, cov, x, u, su, level_index)
    if full is None:
        return None
    std, _ = _std(full, k + 1)
    terms = []
    g = x.size
    if g - 1 >= k + 1:
        for i in range(g):
            keep = np.arange(g) != i
            part = _fit_trend(law, cov, x[keep], u[keep], su[keep], level_index[keep],
                              [full.x])
            if part is None:
                terms = []
                break
            _, c = _std(part, k + 1)
            v = part.x

            def pred(vv, i=i):
                with np.errstate(all="ignore"):
                    return float(vv[0] + log_factor(law, vv[1:], x[i:i + 1], cov,
                                                    level_index[i:i + 1])[0])

            p0 = pred(v)
            grad = np.zeros(v.size)
            for j in range(v.size):
                h = 1e-6 * max(1.0, abs(v[j]))
                vv = v.copy()
                vv[j] += h
                grad[j] = (pred(vv) - p0) / h
            var = float(grad @ c @ grad) if c is not None else 0.0
            if not np.isfinite(p0) or not np.isfinite(var):
                terms = []
                break
            terms.append((u[i] - p0) ** 2 / (su[i] ** 2 + max(var, 0.0)))
    loco = float(np.sum(terms)) if terms else np.nan
    return LawScore(law, k, loco, tuple(terms), float(2 * full.cost), tuple(full.x[1:]),
                    tuple(std[1:]), float(full.x[0]))


def find_law(effect: str, covariate: Covariate, coordinate: str, key: tuple, x, values, std,
             alpha: float = 1e-3, offer: bool = False) -> Trend | None:
    """The moving test and the law of one coordinate (module docstring); with ``offer``, a
    coordinate that does not move gets its law too, marked ``offered`` (a test of each
    parameter alone misses parameters that move together: their errors are correlated).

    ``x``, ``values``, ``std``: per condition (covariate mean, coordinate > 0, standard
    error). Conditions whose value is not positive or whose standard error is not finite
    are left out (a fit on a bound); None with fewer than two left."""
    x, y, s = (np.asarray(a, float) for a in (x, values, std))
    ok = np.isfinite(x) & np.isfinite(y) & (y > 0) & np.isfinite(s) & (s > 0)
    x, y, s = x[ok], y[ok], s[ok]
    if x.size < 2:
        return None
    u, su = np.log(y), s / y
    w = su**-2
    m = np.average(u, weights=w)
    chi2 = float(np.sum((u - m) ** 2 * w))
    dof = x.size - 1
    p = float(stats.chi2.sf(chi2, dof))
    level_index = covariate.level_index(x)
    still = (f"does not move beyond its errors (chi2 = {chi2:.3g}, {dof} dof, p = {p:.2g})")
    if p >= alpha and not offer:
        return Trend(effect, covariate.name, coordinate, key, x, y, s, chi2, dof, p, False, (),
                     "constant", still)
    scores = [sc for law in LAWS if law != "constant" and applicable(law, covariate)
              for sc in [_score(law, covariate, x, u, su, level_index)] if sc is not None]
    law, reason = _choose(scores, x.size, alpha)
    if p >= alpha:
        return Trend(effect, covariate.name, coordinate, key, x, y, s, chi2, dof, p, False,
                     tuple(scores), law, f"{still}; offered in the effect's full form: "
                                         f"{reason}", True)
    return Trend(effect, covariate.name, coordinate, key, x, y, s, chi2, dof, p, True,
                 tuple(scores), law, reason)


def _choose(scores, g, alpha) -> tuple[str, str]:
    """The chosen law and why (module docstring, step 3)."""
    held = [sc for sc in scores if np.isfinite(sc.loco)]
    if not held:
        return "free", (f"{g} conditions: too few to leave one out for a smooth law; free "
                        "per level")
    best = min(held, key=lambda sc: sc.loco)
    limit = float(stats.chi2.ppf(1 - alpha, g))
    if best.loco > limit:
        return "free", (f"no smooth law predicts the left-out conditions within their errors "
                        f"(best {best.law}: held-out chi2 {best.loco:.3g} > {limit:.3g}); "
                        "free per level")
    good = []
    for sc in held:
        d = np.asarray(sc.loco_terms) - np.asarray(best.loco_terms)
        se = d.std(ddof=1) / np.sqrt(d.size) if d.size > 1 else 0.0
        if sc.loco <= limit and d.mean() <= 2.0 * se + 1e-12:
            good.append(sc)
    chosen = min(good, key=lambda sc: (sc.n_params, sc.loco))
    return chosen.law, (f"held-out chi2 {chosen.loco:.3g} over {g} conditions left out in "
                        f"turn (best {best.law} {best.loco:.3g}; the fewest parameters within "
                        "2 standard errors of the best)")


def describe(law: str, names_values: Sequence, cov: Covariate, coordinate: str) -> str:
    """One line of a fitted law: ``names_values`` = [(name, value, std), ...] of its shape
    parameters (as fitted in the joint model)."""
    def pm(i, fmt=".3g"):
        _, v, s = names_values[i]
        return f"{v:{fmt}} +- {s:.2g}" if np.isfinite(s) else f"{v:{fmt}} (on a bound)"

    c, x0 = cov.name, cov.x0
    if law == "constant":
        return f"{coordinate} constant"
    if law == "linear":
        return f"{coordinate} ~ 1 + s ({c} - {x0:.4g}), s = {pm(0)} per unit"
    if law == "exponential":
        return f"{coordinate} ~ exp(s ({c} - {x0:.4g})), s = {pm(0)} per unit"
    if law == "power":
        return f"{coordinate} ~ {c}^({pm(0)})"
    if law == "power_change":
        return (f"{coordinate} change ~ {c}^({pm(1)}) ({coordinate} = F0 (1 + d (({c}/"
                f"{x0:.4g})^e - 1)), d = {pm(0)})")
    if law == "logarithmic":
        return f"{coordinate} ~ 1 + s ln({c}/{x0:.4g}), s = {pm(0)}"
    if law == "arrhenius":
        return f"{coordinate} ~ exp(E_a/R (1/T - 1/T0)), E_a = {pm(0)} J/mol"
    if law == "wlf":
        return (f"{coordinate}: log10 factor = -C1 (T - T0)/(C2 + T - T0), C1 = {pm(0)}, "
                f"C2 = {pm(1)} K")
    if law == "free":
        lv = [lv for lv in cov.levels if abs(lv - x0) > 0]
        return f"{coordinate} free per level: " + ", ".join(
            f"{level:.4g}: {pm(i, '.4g')}" for i, level in enumerate(sorted(lv)))
    raise ValueError(law)


def covariate_info(name: str, col, groups, reference: int, kelvin_offset: float | None,
                   merge: float = 0.01) -> Covariate:
    """A :class:`Covariate` from its per-point column: the reference condition's mean as
    x0, the conditions' means merged into levels when closer than ``merge`` x the range of
    the means (a covariate measured with scatter: sweeps at one nominal level are one
    level)."""
    col = np.asarray(col, float)
    means = np.array([col[groups == g].mean() for g in np.unique(groups)])
    x0 = float(col[groups == reference].mean())
    tol = merge * max(np.ptp(means), 1e-300)
    levels = []
    for m in np.sort(means):
        if levels and m - levels[-1][-1] <= tol:
            levels[-1].append(m)
        else:
            levels.append([m])
    centres = [float(np.mean(lv)) for lv in levels]
    # the reference level is exactly x0 (so F(x0) = 1 there)
    i = int(np.argmin(np.abs(np.array(centres) - x0)))
    centres[i] = x0
    return Covariate(name, x0, kelvin_offset, tuple(centres), float(col.min()),
                     float(col.max()))


def kelvin_offset(name: str) -> float | None:
    """What makes the covariate an absolute temperature, by its name (``*_k`` kelvin: 0;
    other temperature names Celsius: 273.15), None for no temperature (the rule of
    :func:`~.frf_terms.absolute_temperature`)."""
    low = name.lower()
    if not (low.startswith("temp") or low in ("t", "t_c", "t_k")):
        return None
    return 0.0 if low.endswith("_k") else 273.15


@dataclass(frozen=True)
class LawPart:
    """One coordinate of an effect's model and its law: the parameters named ``names`` in
    the model (in that order)."""

    coordinate: str
    law: str
    names: tuple


@dataclass(frozen=True)
class LawModel:
    """The laws a covariate effect's model is built from (carried by its spec and fit, to
    print and to check the fitted law).

    ``parts``: the coordinates and their laws; ``constant``: the coordinates held constant;
    ``offered``: those of ``parts`` that did not move alone (the effect's full form)."""

    effect: str
    covariate: Covariate
    parts: tuple
    constant: tuple = ()
    offered: tuple = ()

    def _values(self, fit, part):
        by_name = {e.name: e for e in fit.estimates}
        return [(n, by_name[n].value, by_name[n].std) for n in part.names]

    def describe(self, fit) -> str:
        """``amplitude_dependence (force_n): mode 3 stiffness change ~ force_n^(2.01 +- 0.04)
        (...); constant: mode 3 damping, ...``"""
        text = "; ".join(describe(p.law, self._values(fit, p), self.covariate, p.coordinate)
                         for p in self.parts)
        if self.constant:
            text += "; constant: " + ", ".join(self.constant)
        return f"{self.effect} ({self.covariate.name}): {text}"

    def to_dict(self, fit) -> dict:
        return {"covariate": self.covariate.name, "reference_level": self.covariate.x0,
                "laws": [{"coordinate": p.coordinate, "law": p.law,
                          "parameters": [{"name": n, "value": v, "std": s}
                                         for n, v, s in self._values(fit, p)]}
                         for p in self.parts],
                "constant": list(self.constant), "offered": list(self.offered),
                "text": self.describe(fit)}

    def implausible(self, fit) -> str:
        """Why the fitted laws mean nothing physically ('' when they do): a factor (a
        stiffness, a damping, a modal constant, a shift) that is not positive and finite
        somewhere over the measured range of the covariate."""
        cov = self.covariate
        grid = np.unique(np.r_[np.linspace(cov.lo, cov.hi, 101), cov.levels])
        for p in self.parts:
            if p.law == "free":
                continue
            theta = [v for _, v, _ in self._values(fit, p)]
            lf = log_factor(p.law, theta, grid, cov)
            bad = ~np.isfinite(lf) | (np.abs(lf) > np.log(1e6))
            if bad.any():
                return (f"the {p.law} law of the {p.coordinate} is not a positive factor at "
                        f"{cov.name} = {grid[bad][0]:.4g} (within the measured range "
                        f"{cov.lo:.4g}..{cov.hi:.4g})")
        return ""
