"""Parametric models and their weighted least-squares fit on training points.

The pieces every discrepancy domain builds on: :class:`ParamSpec` / :class:`ModelSpec` (a
parametric model with bounds and starts), :class:`Observations` (complex values, weights,
ordering axis, groups, covariates), :func:`holdout_split` (training and held-out points) and
:func:`fit_model` (multi-start Levenberg-Marquardt in bounded coordinates, Gauss-Newton standard
errors, held-out errors, and the parameters that ended on a bound).

Error on held-out points (reported as ``error``), with weights w_j (w_j = 1 / |y_j| for FRFs):

    e = sqrt( (1 / N_h) sum_{j in held-out} w_j^2 |yhat_j - y_j|^2 )

i.e. the RMS relative error per point. For noise of RMS sigma (relative), a correct model has
e ~ sigma. ``error_l2`` is the unweighted sqrt(sum |yhat - y|^2 / sum |y|^2) over the same
points (the isolator tool's FRF error), reported for reference.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.special import expit

EFFECT_VOCABULARY = {
    "maxwell_element": "one more Maxwell element (spring in series with a damper) in the mount",
    "sensor_delay": "time delay of the response channel (also in-band anti-alias filter phase)",
    "fixture_mass": "mass error: fixture or accelerometer mass not in the model",
    "foundation_mode": "compliant foundation/fixture with its own resonance, in series",
    "amplitude_dependence": "stiffness and damping depending on the excitation level",
    "covariate_shift": "frequency shift with a covariate (time-temperature superposition)",
    "complex_modes": "complex modal constants (non-proportional damping, or a constant phase "
                     "of the measurement chain), as LSFD fits them",
    "actuator_lag": "lag of the damper actuator (flight domain)",
    "cubic_stiffness": "cubic (hardening) stiffness (flight domain)",
    "unsteady_aero": "unsteady aerodynamic lag (flight domain)",
    "parameter_drift": "drift of a structural parameter (flight domain)",
}
# consistent: the baseline fits within the noise; no_covariate_effect: several conditions
# agree with one model whose misfit (above the noise) is the same in each, nothing to name;
# explained: an effect named; unexplained: a discrepancy nothing in the library explains
STATUSES = ("consistent", "no_covariate_effect", "explained", "unexplained")
ERROR_DEFINITION = (
    "RMS relative error on held-out points: sqrt(mean_j |H_model_j - H_j|^2 / |H_j|^2) over the "
    "held-out points j (not used in any fit); error_l2 = sqrt(sum |H_model - H|^2 / sum |H|^2) "
    "over the same points"
)


class DataError(ValueError):
    """The data cannot be analysed as given, and the user can fix it (a flag, another file):
    the CLI reports it in one line naming the file."""


@dataclass(frozen=True)
class ParamSpec:
    """One free parameter of a model.

    Attributes
    ----------
    name : str
    unit : str
        SI unit (text).
    initial : float
        Starting value [unit].
    lower, upper : float
        Bounds [unit]; for ``log`` parameters 0 < lower.
    log : bool
        Fit ln(value) (positive parameters spanning decades).
    scale : float
        Typical magnitude of a linear parameter (the optimiser works on value / scale).
    at_lower, at_upper : str
        What a fit ending on that bound means physically (reported with the bound hit).
    """

    name: str
    unit: str
    initial: float
    lower: float = -np.inf
    upper: float = np.inf
    log: bool = False
    scale: float = 1.0
    at_lower: str = ""
    at_upper: str = ""

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise ValueError(f"parameter {self.name!r}: lower must be < upper")
        if self.log and not self.lower > 0:
            raise ValueError(f"parameter {self.name!r}: log parameters need lower > 0")
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"parameter {self.name!r}: scale must be finite and > 0")


@dataclass(frozen=True)
class ModelSpec:
    """A parametric model the loop can fit.

    Attributes
    ----------
    name : str
        Human-readable model name, e.g. ``"maxwell(n=2) + sensor_delay"``.
    effect : str or None
        Effect name from :data:`EFFECT_VOCABULARY` (None for the baseline).
    params : tuple of ParamSpec
        All free parameters; the last ``n_added`` belong to the effect.
    n_added : int
        Parameters added to the baseline.
    predict : callable
        ``predict(values)`` maps physical parameter values, shape (P,), to model values at
        all N observation points, shape (N,), complex.
    starts : tuple of numpy.ndarray
        Further starting points (physical values, shape (P,)), besides the initial values.
    signature : str
        What the effect looks like in the residual (documentation, reported).
    label : str
        Extra qualifier, e.g. the covariate a candidate uses.
    n_priority : int
        The first ``n_priority`` of ``starts`` are informed guesses (e.g. from the residual's
        peaks) that always get iterations when the starts are screened.
    batch_predict : callable, optional
        ``batch_predict(values)`` for S parameter vectors at once, shape (S, P) -> (S, N),
        equal to ``predict`` row by row. When given, the fits take their finite-difference
        Jacobians (the bulk of their model evaluations) in one call per iteration.
    """

    name: str
    effect: str | None
    params: tuple[ParamSpec, ...]
    n_added: int
    predict: Callable[[np.ndarray], np.ndarray]
    starts: tuple[np.ndarray, ...] = ()
    signature: str = ""
    label: str = ""
    n_priority: int = 0
    batch_predict: Callable[[np.ndarray], np.ndarray] | None = None
    # the laws of a covariate effect built from its per-condition fits (:mod:`.laws`)
    law: object = None

    def __post_init__(self) -> None:
        if self.effect is not None and self.effect not in EFFECT_VOCABULARY:
            raise ValueError(f"effect must be one of {sorted(EFFECT_VOCABULARY)}, "
                             f"got {self.effect!r}")
        if not 0 <= self.n_added <= len(self.params):
            raise ValueError(f"n_added must be in [0, {len(self.params)}], got {self.n_added}")


@dataclass(frozen=True)
class NotApplicable:
    """A library entry that cannot be fitted to these data, and why."""

    effect: str
    reason: str
    label: str = ""


@dataclass(frozen=True)
class Observations:
    """The data a domain hands to the loop.

    Attributes
    ----------
    values : numpy.ndarray
        Measured values y, shape (N,), complex.
    weights : numpy.ndarray
        w_j > 0, shape (N,); residuals are w_j (yhat_j - y_j) (1 / |y_j| for relative errors).
    axis : numpy.ndarray
        Ordering axis, shape (N,) (frequency [Hz]); points sorted along it within each group.
    groups : numpy.ndarray
        Test condition of each point, shape (N,), int.
    covariates : dict of str to numpy.ndarray
        Condition covariates, each shape (N,).
    axis_name : str
    log_axis : bool
        Bands on a log axis (frequencies) or a linear one.
    """

    values: np.ndarray
    weights: np.ndarray
    axis: np.ndarray
    groups: np.ndarray
    covariates: dict = field(default_factory=dict)
    axis_name: str = "frequency_hz"
    log_axis: bool = True

    def __post_init__(self) -> None:
        y = np.asarray(self.values, dtype=complex)
        w = np.asarray(self.weights, dtype=float)
        x = np.asarray(self.axis, dtype=float)
        g = np.asarray(self.groups, dtype=int)
        if y.ndim != 1 or y.size < 10:
            raise ValueError(f"values must be 1-D with >= 10 points, got shape {y.shape}")
        for name, arr in (("weights", w), ("axis", x), ("groups", g)):
            if arr.shape != y.shape:
                raise ValueError(f"{name} must have shape {y.shape}, got {arr.shape}")
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(w)) and np.all(w > 0)):
            raise ValueError("values must be finite and weights finite and > 0")
        for name, col in self.covariates.items():
            if np.shape(col) != y.shape:
                raise ValueError(f"covariate {name!r} must have shape {y.shape}")
        for label in np.unique(g):
            if np.any(np.diff(x[g == label]) <= 0):
                raise ValueError(f"axis must be strictly increasing within group {label}")
        object.__setattr__(self, "values", y)
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "axis", x)
        object.__setattr__(self, "groups", g)


@dataclass(frozen=True)
class HoldoutSplit:
    """Training and held-out points.

    Attributes
    ----------
    train, held : numpy.ndarray
        Boolean masks, shape (N,), complementary.
    scheme : str
        How the held-out points were chosen.
    """

    train: np.ndarray
    held: np.ndarray
    scheme: str


def holdout_split(groups, every: int = 4, rng: np.random.Generator | None = None) -> HoldoutSplit:
    """Hold out every ``every``-th point of each group (from point ``every // 2``), or, with
    ``rng``, a random 1/``every`` of each group's points.

    Parameters
    ----------
    groups : array_like of int, shape (N,)
        Group of each point (points ordered along the axis within a group).
    every : int
        >= 2.
    rng : numpy.random.Generator, optional
        ``numpy.random.default_rng(seed)`` for a seeded random split.
    """
    g = np.asarray(groups)
    if not isinstance(every, (int, np.integer)) or every < 2:
        raise ValueError(f"every must be an integer >= 2, got {every!r}")
    held = np.zeros(g.size, dtype=bool)
    for label in np.unique(g):
        idx = np.nonzero(g == label)[0]
        if rng is None:
            held[idx[every // 2:: every]] = True
        else:
            held[rng.choice(idx, size=max(1, idx.size // every), replace=False)] = True
    scheme = (f"every {every}th point of each condition, starting at index {every // 2}"
              if rng is None else f"seeded random 1/{every} of each condition's points")
    return HoldoutSplit(~held, held, scheme)


@dataclass(frozen=True)
class Estimate:
    """A fitted parameter with its standard error (Gauss-Newton, from the Jacobian)."""

    name: str
    unit: str
    value: float
    std: float


@dataclass(frozen=True)
class BoundHit:
    """A fitted parameter that ended on (within 0.1 % of the range of) one of its bounds.

    Its standard error is then meaningless (the bounded coordinates have no gradient there):
    the data ask for a value outside the allowed range.
    """

    name: str
    unit: str
    value: float
    bound: float
    side: str  # "lower" or "upper"
    meaning: str
    added: bool  # one of the effect's parameters (not the baseline's)

    def describe(self) -> str:
        return (f"{self.name} = {self.value:.6g} {self.unit} is on its {self.side} bound "
                f"{self.bound:.6g} {self.unit}: {self.meaning}")


BOUND_TOLERANCE = 1e-3  # share of a parameter's range (in fit coordinates) counted as "on it"


def _generic_meaning(p: ParamSpec, side: str) -> str:
    return (f"the data push {p.name} beyond its {side} bound; the estimate and its standard "
            "error are not meaningful")


def bound_hits(params, values, n_added: int) -> tuple[BoundHit, ...]:
    """The parameters whose fitted value sits on a finite bound (see :class:`BoundHit`)."""
    out = []
    first_added = len(params) - n_added
    for i, (p, v) in enumerate(zip(params, values)):
        def conv(x, p=p):
            return np.log(x) if p.log else x / p.scale

        lo = conv(p.lower) if np.isfinite(p.lower) else -np.inf
        hi = conv(p.upper) if np.isfinite(p.upper) else np.inf
        x = conv(v)
        span = hi - lo if np.isfinite(hi - lo) else max(abs(x), 1.0)
        for side, bound, edge, note in (("lower", p.lower, lo, p.at_lower),
                                        ("upper", p.upper, hi, p.at_upper)):
            if np.isfinite(edge) and abs(x - edge) <= BOUND_TOLERANCE * span:
                out.append(BoundHit(p.name, p.unit, float(v), float(bound), side,
                                    note or _generic_meaning(p, side), i >= first_added))
    return tuple(out)


@dataclass(frozen=True)
class ModelFit:
    """A model fitted on the training points and scored on the held-out points.

    Attributes
    ----------
    name, effect, label : str, str or None, str
        From the :class:`ModelSpec`.
    estimates : tuple of Estimate
        All parameters; the last ``n_added`` are the effect's.
    n_added : int
    prediction : numpy.ndarray
        Model values at all points, shape (N,), complex.
    residual : numpy.ndarray
        w (yhat - y) at all points, shape (N,), complex.
    error : float
        Held-out RMS weighted (relative) error [-] (module docstring).
    error_l2 : float
        Held-out unweighted relative L2 error [-].
    train_error : float
        RMS weighted error on the training points [-].
    rss_train, rss_held : float
        Sums of squared weighted residuals on training / held-out points.
    n_train, n_held : int
    success : bool
        Optimiser success of the best start.
    n_starts : int
    bound_hits : tuple of BoundHit
        Parameters that ended on a bound.
    """

    name: str
    effect: str | None
    label: str
    estimates: tuple[Estimate, ...]
    n_added: int
    prediction: np.ndarray
    residual: np.ndarray
    error: float
    error_l2: float
    train_error: float
    rss_train: float
    rss_held: float
    n_train: int
    n_held: int
    success: bool
    n_starts: int
    bound_hits: tuple = ()
    # parameters added over the model before, when not ``n_added`` (a Prony spectrum: the
    # effect's parameters are its shift's, its non-zero moduli count too)
    count_added: int | None = None
    # the spec's laws (:class:`~.laws.LawModel`), to print the fitted law
    law: object = None

    @property
    def n_params(self) -> int:
        """Number of fitted parameters."""
        return len(self.estimates)

    @property
    def added(self) -> tuple[Estimate, ...]:
        """The effect's parameters."""
        return self.estimates[len(self.estimates) - self.n_added:]

    def value(self, name: str) -> float:
        """Fitted value of parameter ``name``."""
        for est in self.estimates:
            if est.name == name:
                return est.value
        raise KeyError(name)


class _Coordinates:
    """Optimiser coordinates z of the parameters.

    x = ln(value) for log parameters, value / scale otherwise; a parameter with two finite
    bounds is mapped smoothly, x = lo + (hi - lo) / (1 + exp(-z)), so the bounds hold without
    clipping (clipping leaves zero gradients and stalls Levenberg-Marquardt at a bound).
    """

    def __init__(self, params):
        self.log = np.array([p.log for p in params], dtype=bool)
        self.scale = np.array([p.scale for p in params], dtype=float)
        self.lo = np.array([self._x(p, p.lower) for p in params], dtype=float)
        self.hi = np.array([self._x(p, p.upper) for p in params], dtype=float)
        self.bounded = np.isfinite(self.lo) & np.isfinite(self.hi)

    @staticmethod
    def _x(p, value):
        if not np.isfinite(value):
            return value
        return float(np.log(value)) if p.log else value / p.scale

    def to_z(self, values) -> np.ndarray:
        v = np.asarray(values, dtype=float)
        with np.errstate(all="ignore"):
            x = np.where(self.log, np.log(np.where(self.log, v, 1.0)), v / self.scale)
        span = np.where(self.bounded, self.hi - self.lo, 1.0)
        # starts on a bound are moved inside, where the mapping still has a gradient
        t = np.clip((x - self.lo) / span, 0.005, 0.995)
        return np.where(self.bounded, np.log(t / (1 - t)), np.clip(x, self.lo, self.hi))

    def to_values(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        span = np.where(self.bounded, self.hi - self.lo, 1.0)
        x = np.where(self.bounded, self.lo + span * expit(z),
                     np.clip(z, self.lo, self.hi))
        with np.errstate(over="ignore"):  # exp of a linear parameter's x is discarded
            return np.where(self.log, np.exp(x), x * self.scale)

    def dvalues_dz(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        span = np.where(self.bounded, self.hi - self.lo, 1.0)
        sig = expit(z)
        dx = np.where(self.bounded, span * sig * (1 - sig), 1.0)
        return np.where(self.log, self.to_values(z) * dx, self.scale * dx)


_FD_STEP = float(np.finfo(float).eps) ** 0.5  # scipy's relative step of '2-point'


def fit_model(spec: ModelSpec, obs: Observations, split: HoldoutSplit,
              max_nfev: int = 60, n_refine: int = 2, n_screen: int = 10) -> ModelFit:
    """Weighted nonlinear least squares on the training points, from every start; best wins.

    Parameters
    ----------
    spec : ModelSpec
    obs : Observations
    split : HoldoutSplit
    max_nfev : int
        Limit on residual evaluations per start, not counting those of the finite-difference
        Jacobian (about the number of Levenberg-Marquardt iterations).
    n_refine, n_screen : int
        With more than ``n_refine`` starts, all are screened by their cost; the initial
        values and the ``n_screen`` cheapest starts get a few iterations, and the
        ``n_refine`` best of those are fitted to convergence.

    Returns
    -------
    ModelFit
    """
    params = spec.params
    n_p = len(params)
    coords = _Coordinates(params)
    train = split.train
    y_tr = obs.values[train]
    w_tr = obs.weights[train]
    big = 1e3 * np.sqrt(train.sum())

    last = [None, None]  # the latest (u, resid(u)): the Jacobian is taken where it was

    def resid(u):
        with np.errstate(all="ignore"):
            pred = spec.predict(coords.to_values(u))[train]
            r = w_tr * (pred - y_tr)
        out = np.concatenate([r.real, r.imag])
        if not np.all(np.isfinite(out)):
            out = np.where(np.isfinite(out), out, big)
        last[:] = u.copy(), out
        return out

    def resid_rows(us):  # resid of each row of us, with spec.batch_predict
        with np.errstate(all="ignore"):
            pred = spec.batch_predict(coords.to_values(us))[:, train]
            r = w_tr * (pred - y_tr)
        out = np.concatenate([r.real, r.imag], axis=1)
        if not np.all(np.isfinite(out)):
            out = np.where(np.isfinite(out), out, big)
        return out

    def forward_jacobian(u):
        # scipy's '2-point' Jacobian (same steps), all columns from one batched evaluation
        h = _FD_STEP * np.where(u >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(u))
        h = (u + h) - u
        f0 = last[1] if last[0] is not None and np.array_equal(last[0], u) else resid(u)
        return ((resid_rows(u + np.diag(h)) - f0) / h[:, None]).T

    jac = "2-point" if spec.batch_predict is None else forward_jacobian

    starts = [np.array([p.initial for p in params], dtype=float), *map(np.asarray, spec.starts)]
    for start in starts:
        if start.shape != (n_p,):
            raise ValueError(f"{spec.name}: a start has shape {start.shape}, expected ({n_p},)")
    internal = list(coords.to_z(np.array(starts).reshape(len(starts), n_p)))
    # a start with no image in the bounded coordinates (not finite, a log parameter <= 0:
    # e.g. an informed start from a negative static modulus) is replaced by a valid one
    valid = [u for u in internal if np.all(np.isfinite(u))]
    if not valid:
        raise ValueError(f"{spec.name}: no start inside the parameter bounds")
    internal = [u if np.all(np.isfinite(u)) else valid[0] for u in internal]
    n_starts = len(internal)
    if n_p and len(internal) > n_refine:
        # Screen a grid of starts: cost at each start, a few iterations from the best
        # n_screen of them (and the initial values), then full fits from the best n_refine.
        if spec.batch_predict is None:
            costs = [float(np.sum(resid(u0) ** 2)) for u0 in internal[1:]]
        else:
            costs = np.sum(resid_rows(np.array(internal[1:])) ** 2, axis=1)
        keep = np.argsort(costs)[:n_screen] + 1
        chosen = sorted({0, *range(1, 1 + spec.n_priority), *keep.tolist()})
        short = [least_squares(resid, internal[i], jac=jac, method="lm", x_scale="jac",
                               max_nfev=15 if 1 <= i <= spec.n_priority else 6)
                 for i in chosen]
        short.sort(key=lambda r: r.cost)
        internal = [r.x for r in short[:n_refine]]
    best = None
    for u0 in internal:
        if n_p == 0:
            break
        # Levenberg-Marquardt (MINPACK) on the optimiser coordinates (bounds built in).
        res = least_squares(resid, u0, jac=jac, method="lm", x_scale="jac", ftol=1e-7,
                            xtol=1e-7, max_nfev=max_nfev)
        if best is None or res.cost < best.cost:
            best = res
    if n_p == 0:
        u = np.zeros(0)
        jac = np.zeros((2 * int(train.sum()), 0))
        success = True
    else:
        u, jac, success = best.x, best.jac, bool(best.success)
    values = coords.to_values(u)
    with np.errstate(all="ignore"):
        pred = spec.predict(values)
    residual = obs.weights * (pred - obs.values)
    if not np.all(np.isfinite(residual)):
        raise ValueError(f"{spec.name}: model is not finite at the fitted parameters")
    held = split.held
    rss_tr = float(np.sum(np.abs(residual[train]) ** 2))
    rss_h = float(np.sum(np.abs(residual[held]) ** 2))
    n_tr, n_h = int(train.sum()), int(held.sum())
    hits = bound_hits(params, values, spec.n_added)
    std = _standard_errors(params, values, coords, u, jac, rss_tr, 2 * n_tr,
                           {h.name for h in hits})
    dy = pred[held] - obs.values[held]
    return ModelFit(
        name=spec.name, effect=spec.effect, label=spec.label,
        estimates=tuple(Estimate(p.name, p.unit, float(v), float(s))
                        for p, v, s in zip(params, values, std)),
        n_added=spec.n_added, prediction=pred, residual=residual,
        error=float(np.sqrt(rss_h / n_h)),
        error_l2=float(np.linalg.norm(dy) / np.linalg.norm(obs.values[held])),
        train_error=float(np.sqrt(rss_tr / n_tr)), rss_train=rss_tr, rss_held=rss_h,
        n_train=n_tr, n_held=n_h, success=success, n_starts=n_starts,
        bound_hits=hits, law=spec.law,
    )


def _standard_errors(params, values, coords, u, jac, rss, n_res, at_bound) -> np.ndarray:
    """Gauss-Newton standard errors of the parameter values (delta method).

    The Jacobian is taken back from the bounded optimiser coordinates z to x = ln(value) or
    value / scale (dividing each column by dx/dz), so a parameter that saturated the logistic
    map does not wipe out the others' covariance; parameters on a bound are held fixed
    (standard error NaN). Columns are normalised before the pseudo-inverse.
    """
    n_p = len(params)
    std = np.full(n_p, np.nan)
    free = np.array([p.name not in at_bound for p in params], dtype=bool)
    dof = n_res - int(free.sum())
    if not n_p or dof <= 0 or not free.any():
        return std
    span = np.where(coords.bounded, coords.hi - coords.lo, 1.0)
    sig = expit(u)
    dxdz = np.where(coords.bounded, span * sig * (1 - sig), 1.0)
    with np.errstate(all="ignore"):
        jx = jac[:, free] / dxdz[free]
    if not np.all(np.isfinite(jx)):
        return std
    norm = np.linalg.norm(jx, axis=0)
    norm[norm == 0] = 1.0
    cov = np.linalg.pinv((jx / norm).T @ (jx / norm)) / np.outer(norm, norm) * (rss / dof)
    std_x = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    v = np.asarray(values, float)[free]
    log = np.array([p.log for p in params])[free]
    scale = np.array([p.scale for p in params])[free]
    std[free] = np.where(log, np.abs(v), scale) * std_x
    return std

