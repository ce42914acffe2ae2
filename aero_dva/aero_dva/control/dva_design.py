"""DVA design: absorber settings that maximise the minimum damping ratio (seed 6.2.2-6.3.2).

The study's objective at a given airspeed is the *minimum damping ratio* over all modes
(:func:`~aero_dva.wing.modal.min_damping_ratio`); the best setting maximises it. A *tuned*
absorber takes its best setting at every airspeed, and its critical airspeed is where the best
minimum damping ratio crosses zero:

- passive DVA with tunable ``k1`` and ``c1`` (fig. 6.6-6.12, tables 6.1 and 6.2, the "tunable
  DVA" of table 6.3): :func:`optimise_passive`, :func:`tuned_critical_airspeed`;
- Maxwell DVA with tunable ``c2`` only (fig. 6.19-6.24): :func:`optimise_maxwell`,
  :func:`tuned_critical_airspeed`.

The search is a log-spaced grid followed by Nelder-Mead in log coordinates (the objective is a
minimum over modes, so it has kinks where the least damped mode changes; Nelder-Mead does not
need gradients). Critical airspeeds are bracketed on a grid and solved with Brent's method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize, minimize_scalar

from aero_dva.flight.damper import DAMPER_RANGE
from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.checks import positive
from aero_dva.wing.flutter import NoFlutterError, bare_critical_airspeed, flutter_speed
from aero_dva.wing.modal import min_damping_ratio
from aero_dva.wing.model import N_FEATURES, AeroelasticModel

__all__ = [
    "STUDY_MAXWELL_DESIGNS",
    "STUDY_POSITIONS",
    "STUDY_TABLE_6_1",
    "STUDY_TABLE_6_2",
    "STUDY_TABLE_6_3",
    "STUDY_TUNED_RATIO",
    "CriticalRatio",
    "DEFAULT_DAMPING_BOUNDS",
    "DEFAULT_STIFFNESS_BOUNDS",
    "FixedDampingChoice",
    "TunedSetting",
    "bare_critical_airspeed",
    "best_damping_curve",
    "best_fixed_damping",
    "constant_absorber_study",
    "critical_frequency",
    "flutter_airspeed_of",
    "maximise_on_grid",
    "mass_study",
    "maxwell_study",
    "min_damping_map",
    "optimise_maxwell",
    "optimise_passive",
    "position_study",
    "tuned_critical_airspeed",
]

DEFAULT_STIFFNESS_BOUNDS = (1.0e3, 1.0e6)
"""[N/m] Search range of ``k1`` (1 to 1000 N/mm)."""
DEFAULT_DAMPING_BOUNDS = (1.0, 1.0e5)
"""[N s/m] Search range of ``c1`` and ``c2`` (0.001 to 100 N-s/mm); c2 also tries 0."""


@dataclass(frozen=True)
class TunedSetting:
    """Best absorber setting at one airspeed.

    Attributes
    ----------
    airspeed : float
        [m/s]
    min_damping_ratio : float
        [1] The maximised minimum damping ratio.
    stiffness : float
        [N/m] ``k1`` (passive) or the fixed ``k1`` (Maxwell).
    damping : float
        [N s/m] ``c1`` (passive) or ``c2`` (Maxwell).
    """

    airspeed: float
    min_damping_ratio: float
    stiffness: float
    damping: float


def min_damping_map(model, airspeed: float, density: float, stiffness, damping) -> np.ndarray:
    """Minimum damping ratio on a grid of absorber settings (fig. 6.6-6.9, 6.19, 6.22).

    Parameters
    ----------
    model : AeroelasticModel
        With a passive or Maxwell absorber.
    airspeed, density : float
        [m/s], [kg/m^3]
    stiffness : array_like, shape (n_k,)
        ``k1`` values [N/m].
    damping : array_like, shape (n_c,)
        ``c1`` (passive) or ``c2`` (Maxwell) values [N s/m].

    Returns
    -------
    ndarray, shape (n_k, n_c)
    """
    if model.absorber is None:
        raise ValueError("model has no absorber")
    k = np.asarray(stiffness, dtype=float)[:, None]
    c = np.asarray(damping, dtype=float)[None, :]
    a, _ = model.matrices(airspeed, density, damping=c, stiffness=k)
    return min_damping_ratio(a)


def _objective(model, airspeed, density):
    """Minimum damping ratio as a function of (k1, c) at one condition.

    For a passive absorber ``A`` is affine in ``k1`` and ``c1`` (the mass matrix does not
    depend on them), so it is assembled once and only combined per evaluation.
    """
    if isinstance(model.absorber, PassiveAbsorber):
        a0, _ = model.matrices(airspeed, density, damping=0.0, stiffness=0.0)
        # The k1 and c1 directions exactly, from the unit feature vectors (no differencing).
        unit = np.zeros((2, N_FEATURES))
        unit[0, 4] = unit[1, 5] = 1.0
        (ak, ac), _ = model.matrices_from_features(unit, np.full(2, float(density)))

        def f(k, c):
            k = np.asarray(k, dtype=float)[..., None, None]
            c = np.asarray(c, dtype=float)[..., None, None]
            return min_damping_ratio(a0 + k * ak + c * ac)
        return f

    def g(k, c):
        a, _ = model.matrices(airspeed, density, damping=c, stiffness=k)
        return min_damping_ratio(a)
    return g


def optimise_passive(model, airspeed: float, density: float,
                     stiffness_bounds=DEFAULT_STIFFNESS_BOUNDS,
                     damping_bounds=DEFAULT_DAMPING_BOUNDS, n_grid: int = 24,
                     xatol: float = 1e-5) -> TunedSetting:
    """Best ``(k1, c1)`` of a passive absorber at one airspeed (fig. 6.12).

    Parameters
    ----------
    model : AeroelasticModel
        With a :class:`PassiveAbsorber` (its ``k1``, ``c1`` are ignored).
    airspeed, density : float
    stiffness_bounds, damping_bounds : (float, float)
        Search ranges [N/m], [N s/m], both > 0.
    n_grid : int
        Log-spaced grid points per axis before refinement.
    xatol : float
        Tolerance of the refinement on ``log k1`` and ``log c1``.
    """
    if not isinstance(model.absorber, PassiveAbsorber):
        raise ValueError("optimise_passive needs a model with a PassiveAbsorber")
    lk = np.log([positive(v, "stiffness_bounds") for v in stiffness_bounds])
    lc = np.log([positive(v, "damping_bounds") for v in damping_bounds])
    f = _objective(model, airspeed, density)
    gk = np.linspace(lk[0], lk[1], n_grid)
    gc = np.linspace(lc[0], lc[1], n_grid)
    z = f(np.exp(gk)[:, None], np.exp(gc)[None, :])
    i, j = np.unravel_index(np.argmax(z), z.shape)
    lo = np.array([lk[0], lc[0]])
    hi = np.array([lk[1], lc[1]])

    def neg(p):
        p = np.clip(p, lo, hi)
        return -float(f(np.exp(p[0]), np.exp(p[1])))

    step = np.array([gk[1] - gk[0], gc[1] - gc[0]])
    x0 = np.array([gk[i], gc[j]])
    simplex = np.array([x0, x0 + [step[0], 0], x0 + [0, step[1]]])
    res = minimize(neg, x0, method="Nelder-Mead",
                   options={"initial_simplex": simplex, "xatol": xatol, "fatol": 1e-9,
                            "maxiter": 400})
    p, best = np.clip(res.x, lo, hi), -res.fun
    if z[i, j] > best:
        p, best = x0, z[i, j]
    return TunedSetting(float(airspeed), float(best), float(np.exp(p[0])), float(np.exp(p[1])))


def optimise_maxwell(model, airspeed: float, density: float,
                     damping_bounds=DEFAULT_DAMPING_BOUNDS, n_grid: int = 48) -> TunedSetting:
    """Best ``c2`` of a Maxwell absorber at one airspeed (fig. 6.19, 6.20, 6.22, 6.23).

    ``c2 = 0`` is also tried. Returns the best setting (``stiffness`` is the fixed ``k1``).
    """
    if not isinstance(model.absorber, MaxwellAbsorber):
        raise ValueError("optimise_maxwell needs a model with a MaxwellAbsorber")
    lc = np.log([positive(v, "damping_bounds") for v in damping_bounds])
    f = _objective(model, airspeed, density)
    k1 = model.absorber.stiffness
    grid = np.concatenate([[0.0], np.exp(np.linspace(lc[0], lc[1], n_grid))])
    z = f(k1, grid)
    j = int(np.argmax(z))
    best_c, best = grid[j], float(z[j])
    lo = np.log(grid[max(j - 1, 1)]) if j > 0 else lc[0] - 1.0
    hi = np.log(grid[min(j + 1, len(grid) - 1)])
    res = minimize_scalar(lambda lg: -float(f(k1, np.exp(lg))), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-6})
    if -res.fun > best:
        best, best_c = float(-res.fun), float(np.exp(res.x))
    return TunedSetting(float(airspeed), best, k1, float(best_c))


def _optimiser(model, density, **kwargs):
    if isinstance(model.absorber, PassiveAbsorber):
        return lambda u: optimise_passive(model, u, density, **kwargs)
    if isinstance(model.absorber, MaxwellAbsorber):
        return lambda u: optimise_maxwell(model, u, density, **kwargs)
    raise ValueError("model has no absorber to tune")


def best_damping_curve(model, airspeeds, density: float, **kwargs) -> list[TunedSetting]:
    """The tuned setting at each airspeed (fig. 6.10-6.12, 6.20, 6.23)."""
    opt = _optimiser(model, density, **kwargs)
    return [opt(float(u)) for u in airspeeds]  # any iterable, e.g. wrapped in a progress bar


def critical_frequency(model, setting: TunedSetting, density: float) -> float:
    """[Hz] ``|Im lambda| / (2 pi)`` of the least stable eigenvalue at a tuned setting."""
    kwargs = {"damping": setting.damping}
    if isinstance(model.absorber, PassiveAbsorber):
        kwargs["stiffness"] = setting.stiffness
    a, _ = model.matrices(setting.airspeed, density, **kwargs)
    lam = np.linalg.eigvals(a)
    return float(abs(lam[np.argmax(lam.real)].imag) / (2 * np.pi))


def tuned_critical_airspeed(model, density: float, airspeed_range, n_grid: int = 16,
                            xtol: float = 1e-7, **kwargs) -> TunedSetting:
    """Critical airspeed of the tuned absorber: where the best minimum damping ratio is 0.

    Parameters
    ----------
    model : AeroelasticModel
        With a passive (tunes ``k1``, ``c1``) or Maxwell (tunes ``c2``) absorber.
    density : float
    airspeed_range : (float, float)
        [m/s] Must be stable (tuned) at the low end.
    n_grid : int
        Bracketing grid.
    xtol : float
        Relative tolerance of the airspeed.
    **kwargs
        Passed to the optimiser (bounds, grid size).

    Returns
    -------
    TunedSetting
        At the critical airspeed (``min_damping_ratio`` ~ 0).

    Raises
    ------
    NoFlutterError
        The tuned absorber keeps the wing stable over the whole range.
    """
    opt = _optimiser(model, density, **kwargs)
    low, high = (float(v) for v in airspeed_range)
    if not 0 <= low < high:
        raise ValueError(f"airspeed_range must satisfy 0 <= low < high, got {airspeed_range}")
    u = np.linspace(low, high, n_grid)
    prev = opt(u[0])
    if prev.min_damping_ratio <= 0:
        raise ValueError(f"the tuned absorber is already unstable at {low:g} m/s")
    for a, b in zip(u[:-1], u[1:]):
        cur = opt(b)
        if cur.min_damping_ratio <= 0:
            root = brentq(lambda x: opt(x).min_damping_ratio, a, b, xtol=xtol * b)
            return opt(root)
        prev = cur
    raise NoFlutterError(f"the tuned absorber is stable up to {high:g} m/s")


# -- the study's chapter-6 studies ---------------------------------------------------------------

STUDY_POSITIONS = {"rear_tip": -0.27, "rear_middle": -0.15, "front_middle": 0.80,
                   "front_tip": 1.53}
"""[m] DVA positions of table 6.1 / fig. 6.10 from the gravity centre, positive toward the
leading edge. The study's captions print 0.27, 0.15, -0.8, -1.53 for rear tip .. front tip, i.e.
with the opposite sign to its own eq. 6.11 (where ``w - l_a alpha`` makes positive ``l_a`` point
to the leading edge); the labels decide, so the signs are flipped here."""

STUDY_TABLE_6_1 = {"rear_tip": 1.07, "rear_middle": 1.06, "front_middle": 1.09, "front_tip": 1.14}
"""Critical airspeed ratio of the tuned passive DVA (m1/m = 0.04) by position."""

STUDY_TABLE_6_2 = {0.01: 1.08, 0.02: 1.10, 0.03: 1.12, 0.04: 1.14}
"""Critical airspeed ratio of the tuned passive DVA at the front tip by mass ratio."""

STUDY_TABLE_6_3 = (
    (29.38e3, 1.88e3, 1.02),
    (91.56e3, 0.86e3, 1.074),
    (123.16e3, 0.59e3, 1.04),
)
"""Constant DVAs: ``(k1 [N/m], c1 [N s/m], critical ratio)``; DVA(2) is 1.07 in the table and
1.074 in the text."""

STUDY_TUNED_RATIO = 1.141
"""Tuned passive DVA (k1 and c1 tuned), front tip, m1/m = 0.04 (section 6.2.2)."""

STUDY_MAXWELL_DESIGNS = (
    (25.0e3, 150.0e3, 2.5e3, 1.065),
    (90.0e3, 70.0e3, 1.2e3, 1.149),
)
"""Maxwell DVAs ``(k1 [N/m], k2 [N/m], largest c2 [N s/m], critical ratio)`` (section 6.3.2)."""


@dataclass(frozen=True)
class CriticalRatio:
    """A critical airspeed relative to the bare wing's.

    Attributes
    ----------
    label : str
    critical_airspeed : float
        [m/s] (NaN when stable over the searched range)
    ratio : float
        ``critical_airspeed / U_cr`` of the wing without DVA.
    setting : TunedSetting or None
        The tuned setting at the critical airspeed (tuned absorbers only).
    """

    label: str
    critical_airspeed: float
    ratio: float
    setting: TunedSetting | None = None


def _tuned_ratio(model, density, u_cr, label, **kwargs) -> CriticalRatio:
    try:
        tc = tuned_critical_airspeed(model, density, (0.5 * u_cr, 2.0 * u_cr), **kwargs)
    except NoFlutterError:
        return CriticalRatio(label, float("nan"), float("nan"))
    return CriticalRatio(label, tc.airspeed, tc.airspeed / u_cr, tc)


def position_study(wing, density: float, positions=None, mass_ratio: float = 0.04,
                   aero=None) -> list[CriticalRatio]:
    """Table 6.1: tuned passive DVA (``k1``, ``c1`` tuned) at several positions."""
    positions = STUDY_POSITIONS if positions is None else positions
    u_cr = bare_critical_airspeed(wing, density, aero)
    out = []
    for label, x in positions.items():
        ab = PassiveAbsorber(mass_ratio * wing.mass, 1e5, 1e3, x)
        out.append(_tuned_ratio(AeroelasticModel(wing, ab, aero), density, u_cr, label))
    return out


def mass_study(wing, density: float, position: float = STUDY_POSITIONS["front_tip"],
               mass_ratios=tuple(STUDY_TABLE_6_2), aero=None) -> list[CriticalRatio]:
    """Table 6.2: tuned passive DVA at ``position`` with several mass ratios ``m1/m``."""
    u_cr = bare_critical_airspeed(wing, density, aero)
    out = []
    for r in mass_ratios:
        ab = PassiveAbsorber(float(r) * wing.mass, 1e5, 1e3, position)
        out.append(_tuned_ratio(AeroelasticModel(wing, ab, aero), density, u_cr, f"{r:g}"))
    return out


def constant_absorber_study(wing, density: float, absorbers=STUDY_TABLE_6_3,
                            position: float = STUDY_POSITIONS["front_tip"],
                            mass_ratio: float = 0.04, aero=None) -> list[CriticalRatio]:
    """Table 6.3: constant passive DVAs ``(k1, c1, ...)`` and the tuned one."""
    u_cr = bare_critical_airspeed(wing, density, aero)
    m1 = mass_ratio * wing.mass
    out = []
    for i, row in enumerate(absorbers):
        k1, c1 = row[0], row[1]
        model = AeroelasticModel(wing, PassiveAbsorber(m1, k1, c1, position), aero)
        try:
            u = flutter_speed(model, density, (0.0, 4.0 * u_cr)).critical_airspeed
        except NoFlutterError:
            u = float("nan")
        out.append(CriticalRatio(f"constant DVA({i + 1})", u, u / u_cr))
    tuned = AeroelasticModel(wing, PassiveAbsorber(m1, 1e5, 1e3, position), aero)
    out.append(_tuned_ratio(tuned, density, u_cr, "tunable DVA"))
    return out


def maxwell_study(wing, density: float, designs=STUDY_MAXWELL_DESIGNS,
                  position: float = STUDY_POSITIONS["front_tip"], mass_ratio: float = 0.04,
                  aero=None) -> list[CriticalRatio]:
    """Section 6.3.2: Maxwell DVAs ``(k1, k2, c2_max, ...)`` with ``c2`` tuned in [0, c2_max]."""
    u_cr = bare_critical_airspeed(wing, density, aero)
    m1 = mass_ratio * wing.mass
    out = []
    for i, row in enumerate(designs):
        k1, k2, c2_max = row[0], row[1], row[2]
        ab = MaxwellAbsorber(m1, k1, k2, c2_max / 2, position)
        out.append(_tuned_ratio(AeroelasticModel(wing, ab, aero), density, u_cr,
                                f"Maxwell DVA({i + 1})",
                                damping_bounds=(1e-3 * c2_max, c2_max)))
    return out


# -- the best constant c2 ------------------------------------------------------------------------

@dataclass(frozen=True)
class FixedDampingChoice:
    """The constant c2 whose wing + Maxwell DVA has the highest flutter airspeed.

    Attributes
    ----------
    damping : float
        [N s/m] the best constant c2 (refined between grid points).
    critical_airspeed : float
        [m/s] flutter airspeed with that c2 held fixed (inf: none found up to 1e5 m/s).
    grid, grid_critical_airspeed : (n,) the c2 grid [N s/m] and its flutter airspeeds [m/s]
        (inf where no flutter was found).
    """

    damping: float
    critical_airspeed: float
    grid: np.ndarray
    grid_critical_airspeed: np.ndarray


def flutter_airspeed_of(model: AeroelasticModel, density: float):
    """c2 [N s/m] -> flutter airspeed [m/s] of ``model`` with that c2 held fixed, inf when no
    flutter or divergence is found (the search goes up to 1e5 m/s: a c2 that keeps the wing
    stable that far is the best a constant c2 can do, so it must rank above every finite
    airspeed; NaN would drop it from the comparison and a worse c2 would be taken for the
    best without a word)."""
    def critical(c2: float) -> float:
        try:
            return flutter_speed(model, density, damping=float(c2)).critical_airspeed
        except NoFlutterError:
            return math.inf

    return critical


def maximise_on_grid(critical_airspeed, grid) -> FixedDampingChoice:
    """The c2 of ``grid`` (increasing, at least 3) that maximises ``critical_airspeed(c2)``,
    refined by bounded Brent search between its two neighbours (the flutter airspeed is
    continuous but has kinks where the critical mode changes, so no derivative is used)."""
    c2 = np.asarray(grid, dtype=float)
    if c2.ndim != 1 or c2.size < 3 or np.any(np.diff(c2) <= 0) or c2[0] < 0 \
            or not np.all(np.isfinite(c2)):
        raise ValueError("grid must hold at least 3 increasing finite c2 values >= 0")
    speeds = np.array([float(critical_airspeed(float(c))) for c in c2])
    if np.any(np.isnan(speeds)):
        raise ValueError("a flutter airspeed of the grid is NaN: no c2 can be called best")
    i = int(np.argmax(speeds))
    if math.isinf(speeds[i]):  # stable to the end of the search: nothing to refine
        return FixedDampingChoice(float(c2[i]), math.inf, c2, speeds)
    low, high = c2[max(i - 1, 0)], c2[min(i + 1, c2.size - 1)]
    res = minimize_scalar(lambda c: -float(critical_airspeed(float(c))), bounds=(low, high),
                          method="bounded", options={"xatol": 1e-3 * (high - low)})
    best, u_best = (float(res.x), float(-res.fun)) if -res.fun >= speeds[i] \
        else (float(c2[i]), float(speeds[i]))
    return FixedDampingChoice(best, u_best, c2, speeds)


def best_fixed_damping(model: AeroelasticModel, density: float,
                       damping_range: tuple[float, float] = DAMPER_RANGE,
                       points: int = 51) -> FixedDampingChoice:
    """The best constant c2: in ``damping_range`` (``points`` evenly spaced, then refined),
    the c2 with the highest flutter airspeed of ``model`` (eigenvalues at ``density``). The
    evaluation's fixed controller and the switching law's safe c2 and reference are this c2."""
    return maximise_on_grid(flutter_airspeed_of(model, density),
                            np.linspace(*damping_range, int(points)))
