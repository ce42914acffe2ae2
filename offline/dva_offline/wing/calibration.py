"""Calibration of the reference wing toward the study's chapter-6 critical-airspeed ratios.

The study prints no wing parameters, only ratios ``U / U_cr`` of tuned and constant absorbers
(tables 6.1-6.3, section 6.3.2) and their trends. This module searches wing *shapes* for the
ones that reproduce them:

- :data:`BOUNDS`: eight free parameters in physically sensible ranges (edges of the chord
  around the study's DVA positions, elastic axis, radius of gyration, frequency ratio, wind-off
  damping, effective span, lift slope), plus the pitch-damping reading of eq. 6.2/6.4 as a
  categorical choice (:data:`PITCH_DAMPING_VARIANTS`);
- :func:`build_wing`: a shape -> :class:`WingParameters` whose stiffnesses are scaled so that
  the bare wing flutters at exactly ``U_cr = 100 m/s`` (``K -> s^2 K``, ``beta -> beta / s``
  scales every eigenvalue and ``U_cr`` by ``s``; the mass, 1000 kg, and the DVA masses and
  positions stay the study's);
- :func:`study_ratios`: the thirteen ratios of the study on that wing (fast settings by default,
  the exact ``dva wing design`` settings with ``fast=False``);
- :func:`calibration_cost`: squared errors in units of 0.01 plus a hinge penalty on every
  ordering the study states (table 6.1 front tip > front middle > rear tip > rear middle, table
  6.2 heavier is better, table 6.3 tuned > DVA(2) > DVA(3) > DVA(1) > 1, Maxwell design 2 >
  tuned passive > Maxwell design 1), so that a wing with small errors but a wrong trend does
  not win;
- :func:`search`: seeded random search in the unit cube, then Nelder-Mead restarts from the
  best points found, with a time / evaluation budget, a callback per evaluation (progress,
  checkpoint) and a memo of earlier evaluations so that a resumed run replays them for free.

Pure numerics: no file I/O here (``scripts/calibrate_reference_wing.py`` is the command with
the checkpoint file).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, minimize

from aero_dva.control import dva_design as dd
from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.aerodynamics import QuasiSteadyAero
from aero_dva.wing.flutter import bare_critical_airspeed, bare_flutter, flutter_speed
from aero_dva.wing.model import AeroelasticModel, WingParameters

__all__ = [
    "BOUNDS",
    "ORDERINGS",
    "PITCH_DAMPING_VARIANTS",
    "STUDY_TARGETS",
    "Bound",
    "Cost",
    "Evaluation",
    "build_wing",
    "calibration_cost",
    "evaluate",
    "from_unit",
    "params_from_wing",
    "search",
    "study_ratios",
    "to_unit",
]

WING_MASS = 1000.0  # [kg] seed: DVA masses 10-40 kg are m1/m = 0.01-0.04
AIR_DENSITY = 1.2  # [kg/m^3]
TARGET_UCR = 100.0  # [m/s] DESIGN.md / section 7.1.1
FRONT_TIP = dd.STUDY_POSITIONS["front_tip"]
REAR_TIP = dd.STUDY_POSITIONS["rear_tip"]
FLUTTER_BAND = (5.0, 20.0)  # [Hz] the study's spectra (ch. 7)
UNIT = 0.01  # errors are counted in units of 0.01 of U / U_cr
RANK_MARGIN = 0.003  # an ordering counts as right only with this margin
RANK_WEIGHT = 10.0
NAN_PENALTY = 400.0  # per missing ratio (no flutter found): as bad as an error of 0.2


@dataclass(frozen=True)
class Bound:
    """One free parameter: range, whether it is searched in log scale, meaning."""

    name: str
    low: float
    high: float
    log: bool
    doc: str


BOUNDS = (
    Bound("le_ext", 0.0, 1.0, False, "leading edge ahead of the front-tip DVA (1.53 m) [m]"),
    Bound("te_ext", 0.0, 3.0, False, "trailing edge behind the rear-tip DVA (-0.27 m) [m]"),
    Bound("ea_frac", 0.15, 0.65, False, "elastic axis behind the leading edge [chord]"),
    Bound("r_frac", 0.15, 0.5, False, "radius of gyration about the gravity centre [chord]"),
    Bound("freq_ratio", 0.3, 4.0, True,
          "uncoupled plunge / pitch frequency, sqrt(k/m) / sqrt(k_alpha/I_ea)"),
    Bound("zeta_pitch", 0.0, 0.15, False, "wind-off damping ratio beta omega_alpha / 2"),
    Bound("span", 10.0, 400.0, True, "effective span multiplying the aerodynamic forces [m]"),
    Bound("lift_slope", 2.5, 2.0 * math.pi, False, "dC_L/dalpha [1/rad]"),
)
NAMES = tuple(b.name for b in BOUNDS)

PITCH_DAMPING_VARIANTS = ("thin_airfoil", "printed_6_2")

STUDY_TARGETS = {
    "6.1 rear_tip": 1.07,
    "6.1 rear_middle": 1.06,
    "6.1 front_middle": 1.09,
    "front_tip m1/m=0.04 (tables 6.1-6.3)": dd.STUDY_TUNED_RATIO,
    "6.2 m1/m=0.01": 1.08,
    "6.2 m1/m=0.02": 1.10,
    "6.2 m1/m=0.03": 1.12,
    "6.3 DVA(1)": dd.STUDY_TABLE_6_3[0][2],
    "6.3 DVA(2)": dd.STUDY_TABLE_6_3[1][2],
    "6.3 DVA(3)": dd.STUDY_TABLE_6_3[2][2],
    "Maxwell design 1": dd.STUDY_MAXWELL_DESIGNS[0][3],
    "Maxwell design 2": dd.STUDY_MAXWELL_DESIGNS[1][3],
}
"""The study's ratios ``U / U_cr`` (the front-tip, ``m1/m = 0.04`` tuned value is shared by the
three tables and the text: 1.14 / 1.141)."""

_TIP = "front_tip m1/m=0.04 (tables 6.1-6.3)"
ORDERINGS = (
    ("6.1", _TIP, "6.1 front_middle"),
    ("6.1", "6.1 front_middle", "6.1 rear_tip"),
    ("6.1", "6.1 rear_tip", "6.1 rear_middle"),
    ("6.2", _TIP, "6.2 m1/m=0.03"),
    ("6.2", "6.2 m1/m=0.03", "6.2 m1/m=0.02"),
    ("6.2", "6.2 m1/m=0.02", "6.2 m1/m=0.01"),
    ("6.3", _TIP, "6.3 DVA(2)"),
    ("6.3", "6.3 DVA(2)", "6.3 DVA(3)"),
    ("6.3", "6.3 DVA(3)", "6.3 DVA(1)"),
    ("6.3", "6.3 DVA(1)", None),  # None: the bare wing, ratio 1
    ("6.3.2", "Maxwell design 2", _TIP),
    ("6.3.2", _TIP, "Maxwell design 1"),
)
"""``(table, better, worse)``: the study's trends, each ``better > worse + RANK_MARGIN``."""


# -- parameter space ------------------------------------------------------------------------
def from_unit(unit) -> dict:
    """Parameters (dict by :data:`NAMES`) from a point of the unit cube (clipped into it)."""
    u = np.clip(np.asarray(unit, dtype=float), 0.0, 1.0)
    if u.shape != (len(BOUNDS),):
        raise ValueError(f"unit must have shape ({len(BOUNDS)},), got {u.shape}")
    out = {}
    for b, v in zip(BOUNDS, u):
        if b.log:
            out[b.name] = float(math.exp(math.log(b.low) + v * math.log(b.high / b.low)))
        else:
            out[b.name] = float(b.low + v * (b.high - b.low))
    return out


def to_unit(params: dict) -> np.ndarray:
    """Inverse of :func:`from_unit` (values outside the bounds map outside [0, 1])."""
    missing = [n for n in NAMES if n not in params]
    if missing:
        raise ValueError(f"params lack {missing}")
    out = []
    for b in BOUNDS:
        v = float(params[b.name])
        if b.log:
            out.append(math.log(v / b.low) / math.log(b.high / b.low))
        else:
            out.append((v - b.low) / (b.high - b.low))
    return np.array(out)


def _unscaled_wing(p: dict) -> WingParameters:
    """The wing of shape ``p`` with its pitch frequency at 10 Hz (before scaling to U_cr)."""
    c0 = FRONT_TIP + p["le_ext"]
    chord = c0 - REAR_TIP + p["te_ext"]
    ce = c0 - p["ea_frac"] * chord
    inertia = WING_MASS * (p["r_frac"] * chord) ** 2
    w_alpha = 2.0 * math.pi * 10.0
    return WingParameters(
        mass=WING_MASS,
        inertia=inertia,
        plunge_stiffness=WING_MASS * (p["freq_ratio"] * w_alpha) ** 2,
        pitch_stiffness=(inertia + WING_MASS * ce**2) * w_alpha**2,
        damping_factor=2.0 * p["zeta_pitch"] / w_alpha,
        chord=chord,
        gravity_centre=c0,
        elastic_axis=ce,
        aileron_position=c0 - chord,  # at the trailing edge (does not affect any ratio)
        lift_slope=p["lift_slope"],
        span=p["span"],
    )


def params_from_wing(wing: WingParameters) -> dict:
    """The shape parameters of an existing wing (inverse of :func:`build_wing`)."""
    chord, c0, ce = wing.chord, wing.gravity_centre, wing.elastic_axis
    i_ea = wing.inertia + wing.mass * ce**2
    w_alpha = math.sqrt(wing.pitch_stiffness / i_ea)
    return {
        "le_ext": c0 - FRONT_TIP,
        "te_ext": chord - c0 + REAR_TIP,
        "ea_frac": (c0 - ce) / chord,
        "r_frac": math.sqrt(wing.inertia / wing.mass) / chord,
        "freq_ratio": math.sqrt(wing.plunge_stiffness / wing.mass) / w_alpha,
        "zeta_pitch": wing.damping_factor * w_alpha / 2.0,
        "span": wing.span,
        "lift_slope": wing.lift_slope,
    }


def build_wing(params: dict, pitch_damping: str = "thin_airfoil", density: float = AIR_DENSITY,
               target_ucr: float = TARGET_UCR):
    """The wing of shape ``params``, its stiffness scaled so that it flutters at ``target_ucr``.

    Returns
    -------
    wing : WingParameters
    aero : QuasiSteadyAero
    flutter : FlutterResult
        Of the scaled bare wing (``critical_airspeed`` = ``target_ucr`` to rounding).

    Raises
    ------
    ValueError
        The shape does not flutter (static divergence first, or no instability at all).
    """
    aero = QuasiSteadyAero(pitch_damping=pitch_damping)
    wing = _unscaled_wing(params)
    res = bare_flutter(wing, density, aero)  # NoFlutterError: a ValueError
    if res.kind != "flutter":
        raise ValueError(f"the wing diverges statically at {res.critical_airspeed:.4g} m/s "
                         "before it flutters")
    s = target_ucr / res.critical_airspeed
    wing = wing.replace(plunge_stiffness=wing.plunge_stiffness * s * s,
                        pitch_stiffness=wing.pitch_stiffness * s * s,
                        damping_factor=wing.damping_factor / s)
    return wing, aero, bare_flutter(wing, density, aero)


# -- the study's ratios on one wing ----------------------------------------------------------
def _best_passive(model, density):
    """``u -> best minimum damping ratio`` over ``(k1, c1)``: a 12 x 12 log grid, then
    Nelder-Mead to 1e-3 in ``log k1, log c1`` (coarser than ``optimise_passive``, whose 24 x 24
    grid and 1e-9 tolerance on the damping ratio cost about three times as much)."""
    lk = np.log(dd.DEFAULT_STIFFNESS_BOUNDS)
    lc = np.log(dd.DEFAULT_DAMPING_BOUNDS)
    gk, gc = np.linspace(*lk, 12), np.linspace(*lc, 12)
    lo, hi = np.array([lk[0], lc[0]]), np.array([lk[1], lc[1]])
    step = np.array([gk[1] - gk[0], gc[1] - gc[0]])

    def best(u):
        f = dd._objective(model, u, density)
        z = f(np.exp(gk)[:, None], np.exp(gc)[None, :])
        i, j = np.unravel_index(np.argmax(z), z.shape)
        x0 = np.array([gk[i], gc[j]])
        res = minimize(lambda p: -float(f(*np.exp(np.clip(p, lo, hi)))), x0,
                       method="Nelder-Mead",
                       options={"initial_simplex": [x0, x0 + [step[0], 0], x0 + [0, step[1]]],
                                "xatol": 1e-3, "fatol": 1e-7, "maxiter": 300})
        return max(float(z[i, j]), -float(res.fun))
    return best


def _tuned(wing, absorber, aero, density, u_cr, fast, **kwargs) -> float:
    model = AeroelasticModel(wing, absorber, aero)
    if fast:  # every study ratio lies in 1.0-1.15: bracket there, coarser
        if isinstance(absorber, PassiveAbsorber):
            best = _best_passive(model, density)
        else:
            def best(u):
                return dd.optimise_maxwell(model, u, density, **kwargs).min_damping_ratio
        grid = u_cr * np.array([0.95, 1.1, 1.25, 1.45, 1.6])
        values = [best(grid[0])]
        if values[0] > 0:
            for a, b in zip(grid[:-1], grid[1:]):
                values.append(best(b))
                if values[-1] <= 0:
                    return brentq(best, a, b, xtol=1e-5 * u_cr) / u_cr
            return float("nan")
    try:  # the settings of ``dva wing design``
        tc = dd.tuned_critical_airspeed(model, density, (0.5 * u_cr, 2.0 * u_cr), **kwargs)
    except ValueError:  # includes NoFlutterError
        return float("nan")
    return tc.airspeed / u_cr


def study_ratios(wing: WingParameters, aero=None, density: float = AIR_DENSITY,
                fast: bool = True) -> dict:
    """The twelve ratios of :data:`STUDY_TARGETS` on ``wing`` (NaN where nothing flutters).

    ``fast=False`` uses the settings of ``dva wing design`` (bracketing grid of 16 over
    0.5-2 U_cr, ``xtol = 1e-7``, ``optimise_passive``); ``fast=True`` brackets on 5 points
    over 0.95-1.6 U_cr (every study ratio lies there) with a coarser passive optimiser
    (:func:`_best_passive`), about 4 times faster and within ~1e-4 of the exact ratios on the
    reference wing (``tests/unit/dva_offline/wing/test_calibration.py``).
    """
    aero = QuasiSteadyAero() if aero is None else aero
    u_cr = bare_critical_airspeed(wing, density, aero)
    m = wing.mass
    out = {}

    def passive(mass_ratio, position):
        return _tuned(wing, PassiveAbsorber(mass_ratio * m, 1e5, 1e3, position), aero, density,
                      u_cr, fast)

    for label in ("rear_tip", "rear_middle", "front_middle"):
        out[f"6.1 {label}"] = passive(0.04, dd.STUDY_POSITIONS[label])
    out[_TIP] = passive(0.04, FRONT_TIP)
    for r in (0.01, 0.02, 0.03):
        out[f"6.2 m1/m={r:g}"] = passive(r, FRONT_TIP)
    for i, (k1, c1, _) in enumerate(dd.STUDY_TABLE_6_3):
        model = AeroelasticModel(wing, PassiveAbsorber(0.04 * m, k1, c1, FRONT_TIP), aero)
        try:
            u = flutter_speed(model, density, (0.0, 4.0 * u_cr)).critical_airspeed
        except ValueError:
            u = float("nan")
        out[f"6.3 DVA({i + 1})"] = u / u_cr
    for i, (k1, k2, c_max, _) in enumerate(dd.STUDY_MAXWELL_DESIGNS):
        dva = MaxwellAbsorber(0.04 * m, k1, k2, c_max / 2, FRONT_TIP)
        out[f"Maxwell design {i + 1}"] = _tuned(wing, dva, aero, density, u_cr, fast,
                                                damping_bounds=(1e-3 * c_max, c_max))
    return out


# -- cost -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Cost:
    """Calibration cost of one set of ratios (all terms in units of ``0.01^2``).

    Attributes
    ----------
    total : float
    squared_error : float
        Sum over :data:`STUDY_TARGETS` of ``((ratio - seed) / 0.01)^2``; a missing ratio
        counts :data:`NAN_PENALTY`.
    ranking : float
        ``RANK_WEIGHT * ((RANK_MARGIN - (better - worse)) / 0.01)^2`` summed over the violated
        :data:`ORDERINGS`.
    frequency : float
        ``(distance of the flutter frequency outside 5-20 Hz / 1 Hz)^2``.
    max_error : float
        Largest ``|ratio - study|`` (inf if a ratio is missing).
    wrong_trends : tuple of str
        The violated orderings, e.g. ``"6.1: 6.1 front_middle > 6.1 rear_tip"``.
    """

    total: float
    squared_error: float
    ranking: float
    frequency: float
    max_error: float
    wrong_trends: tuple = field(default_factory=tuple)


def calibration_cost(ratios: dict, flutter_frequency: float = 10.0) -> Cost:
    """Cost of ``ratios`` (keys of :data:`STUDY_TARGETS`) against the study; lower is better."""
    missing = [k for k in STUDY_TARGETS if k not in ratios]
    if missing:
        raise ValueError(f"ratios lack {missing}")
    sq, worst = 0.0, 0.0
    for key, target in STUDY_TARGETS.items():
        r = float(ratios[key])
        if math.isnan(r):
            sq += NAN_PENALTY
            worst = math.inf
        else:
            sq += ((r - target) / UNIT) ** 2
            worst = max(worst, abs(r - target))
    rank, wrong = 0.0, []
    for table, better, worse in ORDERINGS:
        a = float(ratios[better])
        b = 1.0 if worse is None else float(ratios[worse])
        if math.isnan(a) or math.isnan(b):
            continue  # already paid for as missing
        gap = a - b
        if gap < RANK_MARGIN:
            rank += RANK_WEIGHT * ((RANK_MARGIN - gap) / UNIT) ** 2
            wrong.append(f"{table}: {better} > {worse or 'bare wing'}")
    lo, hi = FLUTTER_BAND
    f = float(flutter_frequency)
    freq = (max(lo - f, 0.0, f - hi)) ** 2
    return Cost(sq + rank + freq, sq, rank, freq, worst, tuple(wrong))


# -- one evaluation and the search ----------------------------------------------------------
@dataclass(frozen=True)
class Evaluation:
    """One calibration candidate and its result (``ratios`` empty when it was rejected)."""

    params: dict
    pitch_damping: str
    cost: float
    ratios: dict
    flutter_frequency: float
    max_error: float
    wrong_trends: tuple
    note: str = ""
    phase: str = ""
    seconds: float = 0.0

    def to_dict(self) -> dict:
        return {"params": self.params, "pitch_damping": self.pitch_damping, "cost": self.cost,
                "ratios": self.ratios, "flutter_frequency": self.flutter_frequency,
                "max_error": self.max_error, "wrong_trends": list(self.wrong_trends),
                "note": self.note, "phase": self.phase, "seconds": self.seconds}

    @classmethod
    def from_dict(cls, d: dict) -> Evaluation:
        return cls(dict(d["params"]), d["pitch_damping"], float(d["cost"]), dict(d["ratios"]),
                   float(d["flutter_frequency"]), float(d["max_error"]),
                   tuple(d["wrong_trends"]), d.get("note", ""), d.get("phase", ""),
                   float(d.get("seconds", 0.0)))


REJECTED_COST = 1.0e6
"""Cost of a shape that does not flutter (or diverges statically first)."""


def evaluate(params: dict, pitch_damping: str = "thin_airfoil", fast: bool = True,
             phase: str = "") -> Evaluation:
    """Build the wing of ``params``, compute its study ratios and their cost."""
    t0 = time.perf_counter()
    try:
        wing, aero, res = build_wing(params, pitch_damping)
    except ValueError as exc:
        return Evaluation(dict(params), pitch_damping, REJECTED_COST, {}, float("nan"),
                          math.inf, (), f"rejected: {exc}", phase, time.perf_counter() - t0)
    ratios = study_ratios(wing, aero, fast=fast)
    cost = calibration_cost(ratios, res.flutter_frequency)
    return Evaluation(dict(params), pitch_damping, cost.total, ratios, res.flutter_frequency,
                      cost.max_error, cost.wrong_trends, "", phase, time.perf_counter() - t0)


def _key(unit, variant) -> tuple:
    return (variant,) + tuple(round(float(v), 9) for v in np.clip(unit, 0.0, 1.0))


def search(*, seed: int = 0, n_random: int = 200, max_evaluations: int | None = None,
           max_seconds: float | None = None, history=(), starts=(), on_evaluation=None,
           variants=PITCH_DAMPING_VARIANTS, local_iterations: int = 150,
           restarts: int = 8, evaluate_fn=None) -> list:
    """Random search, then Nelder-Mead restarts from the best points; returns all evaluations.

    Parameters
    ----------
    seed : int
        Seed of the random phase (``numpy.random.default_rng``); the same the study gives the same
        candidates, so a resumed run (``history``) replays them from the memo.
    n_random : int
        Candidates of the random phase that flutter (uniform in the unit cube, variants
        alternating; shapes that diverge statically first are cheap and not counted).
    max_evaluations, max_seconds : optional
        Budget of new evaluations / wall time; the search stops between evaluations.
    history : iterable of Evaluation
        Earlier evaluations (a checkpoint): looked up instead of evaluated again.
    starts : iterable of (params, pitch_damping)
        Candidates evaluated first (e.g. the current reference wing).
    on_evaluation : callable(Evaluation, best Evaluation, is_new), optional
        Called after every candidate (progress output, checkpoint).
    variants : tuple of str
        Pitch-damping readings to search.
    local_iterations, restarts : int
        Nelder-Mead function evaluations per restart and number of restarts. Even restarts
        start from the best point not yet used as a start (often the end of the previous
        one), odd ones from the best point at least 0.25 (unit cube) from all earlier starts.
    evaluate_fn : callable, optional
        Replaces :func:`evaluate` (tests).
    """
    evaluate_fn = evaluate if evaluate_fn is None else evaluate_fn
    memo = {_key(to_unit(e.params), e.pitch_damping): e for e in history}
    done: list = []
    t_start = time.perf_counter()
    new = [0]

    class Budget(Exception):
        pass

    def run(unit, variant, phase):
        key = _key(unit, variant)
        hit = memo.get(key)
        fresh = hit is None
        if fresh:
            if max_evaluations is not None and new[0] >= max_evaluations:
                raise Budget
            if max_seconds is not None and time.perf_counter() - t_start > max_seconds:
                raise Budget
            hit = evaluate_fn(from_unit(key[1:]), variant, phase=phase)
            memo[key] = hit
            new[0] += 1
        done.append(hit)
        if on_evaluation is not None:
            on_evaluation(hit, min(done, key=lambda e: e.cost), fresh)
        return hit.cost

    rng = np.random.default_rng(seed)
    try:
        for params, variant in starts:
            run(to_unit(params), variant, "start")
        valid, i = 0, 0
        while valid < n_random:  # rejected shapes are cheap: count the valid ones only
            if run(rng.random(len(BOUNDS)), variants[i % len(variants)], "random") \
                    < REJECTED_COST:
                valid += 1
            i += 1
        tried: dict = {}
        for r in range(restarts):
            ranked = sorted((e for e in done if e.cost < REJECTED_COST), key=lambda e: e.cost)
            fresh = [e for e in ranked if _key(to_unit(e.params), e.pitch_damping) not in tried]
            if r % 2:  # every other restart explores: the best point away from earlier starts
                far = [e for e in fresh if all(np.linalg.norm(to_unit(e.params) - t) > 0.25
                                               for t in tried.values())]
                fresh = far or fresh
            if not fresh:
                break
            start = fresh[0]
            tried[_key(to_unit(start.params), start.pitch_damping)] = to_unit(start.params)
            x0 = np.clip(to_unit(start.params), 0.0, 1.0)
            simplex = [x0] + [np.clip(x0 + np.eye(len(x0))[i] * (0.08 if x0[i] < 0.92
                                                                   else -0.08), 0, 1)
                              for i in range(len(x0))]
            variant = start.pitch_damping

            def objective(u, variant=variant, r=r):
                outside = float(np.sum(np.clip(u - 1.0, 0, None) ** 2
                                       + np.clip(-u, 0, None) ** 2))
                return run(u, variant, f"local {r + 1}") + 1e4 * outside

            minimize(objective, x0, method="Nelder-Mead",
                     options={"initial_simplex": np.array(simplex),
                              "maxfev": local_iterations, "xatol": 1e-4, "fatol": 1e-3})
    except Budget:
        pass
    return done
