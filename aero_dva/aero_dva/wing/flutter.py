"""Critical airspeed (flutter or divergence) and flutter frequency.

Method: the *growth rate* ``g(U)`` = largest real part [1/s] of the system's eigenvalues
(ignoring exactly neutral ones, ``|lambda| < NEUTRAL``: the free integrator of a locked Maxwell
damper and the aerodynamic lag states at ``U = 0``) goes from negative to positive at the
critical airspeed. With quasi-steady or finite-state aerodynamics ``A(U) = A0 + U A1 + U^2 A2``
and the search marches up from the low end on the modes' tangents
(:mod:`aero_dva.wing.flutter_march`: one eigenvalue problem per sample, with every mode's
slope from the left and right eigenvectors), then solves the first sign change to a relative
tolerance far below 1e-6 by Newton's method on ``g`` with the eigenvalue derivative,
safeguarded by bisection. The previous fixed-grid searches are kept for comparison
(:func:`grid_flutter_speed`, :func:`reference_flutter_speed`). With Theodorsen aerodynamics
each structural mode is converged by the p-k method (C(k) frozen at the mode's own reduced
frequency), which is exact where the damping crosses zero, i.e. at the flutter point; the
sign change is bracketed on a grid and solved by Brent's method.

:class:`NoFlutterError` (a ValueError) is raised when the range holds no instability.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dgeev
from scipy.optimize import brentq, minimize_scalar

from aero_dva.wing.aerodynamics import TheodorsenAero
from aero_dva.wing.checks import non_negative, real_scalar
from aero_dva.wing.flutter_march import TangentGrowth, march_to_instability

__all__ = ["FlutterResult", "NoFlutterError", "bare_critical_airspeed", "bare_flutter",
           "flutter_speed", "flutter_vs_density", "grid_flutter_speed", "growth_rate",
           "reference_flutter_speed"]

NEUTRAL = 1e-7
"""[rad/s] Eigenvalues smaller than this are neutral integrators, not instabilities."""


class NoFlutterError(ValueError):
    """No flutter or divergence in the searched airspeed range."""


@dataclass(frozen=True)
class FlutterResult:
    """Onset of instability.

    Attributes
    ----------
    critical_airspeed : float
        [m/s]
    flutter_frequency : float
        [Hz] ``|Im lambda| / (2 pi)`` of the mode that goes unstable (0 for divergence).
    kind : str
        ``"flutter"`` (oscillatory) or ``"divergence"`` (real eigenvalue).
    density : float
        [kg/m^3]
    eigenvalue : complex
        [rad/s] The critical eigenvalue at ``critical_airspeed``.
    """

    critical_airspeed: float
    flutter_frequency: float
    kind: str
    density: float
    eigenvalue: complex


def _pick(eigs: np.ndarray):
    """Largest real part over non-neutral eigenvalues (last axis) and the eigenvalue."""
    masked = np.where(np.abs(eigs) < NEUTRAL, -np.inf, eigs.real)
    idx = np.argmax(masked, axis=-1)
    lam = np.take_along_axis(eigs, idx[..., None], axis=-1)[..., 0]
    return np.take_along_axis(masked, idx[..., None], axis=-1)[..., 0], lam


class _EigenGrowth:
    """Growth rate from the polynomial ``A(U)`` (quasi-steady and finite-state models)."""

    def __init__(self, model, density, damping, checked: bool = False):
        poly = model.polynomial_unchecked if checked else model.polynomial
        self.a0, self.a1, self.a2 = poly(density, damping)

    def matrices(self, u):
        u = np.asarray(u, dtype=float)[..., None, None]
        return self.a0 + u * self.a1 + u * u * self.a2

    def grid(self, u):
        return _pick(np.linalg.eigvals(self.matrices(u)))

    def __call__(self, u):
        g, lam = _pick(np.linalg.eigvals(self.matrices(u)))
        return float(g), complex(lam)

    def samples(self, u):
        """Growth rate (k,) and the largest ``|critical eigenvalue|`` at airspeeds ``u`` (k,),
        by one batched eigenvalue call (no index gathering: it costs more than the 7 x 7
        eigenvalue problems of a short grid)."""
        lam = np.linalg.eigvals(self.matrices(u))
        masked = np.where(np.abs(lam) < NEUTRAL, -np.inf, lam.real)
        j = masked.argmax(axis=-1)
        k = np.arange(lam.shape[0])
        return masked[k, j], float(np.max(np.abs(lam[k, j])))

    def at(self, u: float):
        """Growth rate, critical eigenvalue and its derivative ``dlambda/dU`` at one airspeed.

        One LAPACK ``dgeev`` call gives the right and left eigenvectors ``v``, ``w`` of the
        critical eigenvalue, and ``dlambda/dU = w^H A'(U) v / (w^H v)`` (NaN for a defective,
        coalescing pair); the slope of the growth rate is its real part.
        """
        a = self.a0 + u * self.a1 + (u * u) * self.a2
        wr, wi, vl, vr, info = dgeev(a)
        masked = np.where(wr * wr + wi * wi < NEUTRAL * NEUTRAL, -np.inf, wr)
        j = int(masked.argmax())
        g, lam = float(masked[j]), complex(wr[j], wi[j])
        if info != 0:
            return g, lam, complex(np.nan)
        # dgeev packs a complex pair's vectors as (real part, imaginary part) columns.
        if wi[j] > 0:
            v, w = vr[:, j] + 1j * vr[:, j + 1], vl[:, j] + 1j * vl[:, j + 1]
        elif wi[j] < 0:
            v, w = vr[:, j - 1] - 1j * vr[:, j], vl[:, j - 1] - 1j * vl[:, j]
        else:
            v, w = vr[:, j], vl[:, j]
        den = np.vdot(w, v)
        if den == 0:
            return g, lam, complex(np.nan)
        return g, lam, complex(np.vdot(w, (self.a1 + (2.0 * u) * self.a2) @ v) / den)


class _PkGrowth:
    """Growth rate by the p-k method with Theodorsen's function."""

    def __init__(self, model, density, damping, u_start):
        self.model, self.density, self.damping = model, density, damping
        self.b = model.wing.chord / 2.0
        # Wind-off modes (k -> inf at U = 0), then continued to the first airspeed.
        lam = np.linalg.eigvals(model.frequency_frozen(0.0, density, 1e9, damping))
        osc = lam[lam.imag > 1e-6]
        modes = osc[np.argsort(np.abs(osc))]
        for u in np.linspace(0.0, u_start, 9)[1:]:
            modes = self.modes_at(max(u, 1e-6), modes)
        self.modes = modes

    def _converge(self, u, guess, system=None):
        system = system or self.model.frequency_frozen_factory(u, self.density, self.damping)
        lam = guess
        for _ in range(100):
            k = max(lam.imag, 0.0) * self.b / max(u, 1e-9)
            eigs = np.linalg.eigvals(system(k))
            upper = eigs[eigs.imag > -1e-12]
            new = upper[np.argmin(np.abs(upper - lam))]
            if abs(new - lam) <= 1e-12 * max(abs(new), 1.0):
                return new
            lam = new
        return lam

    def modes_at(self, u, guesses):
        system = self.model.frequency_frozen_factory(u, self.density, self.damping)
        return np.array([self._converge(u, g, system) for g in guesses])

    def grid(self, u):
        growth, lams, stored = [], [], []
        guesses = self.modes
        for ui in np.asarray(u, dtype=float):
            guesses = self.modes_at(ui, guesses)
            stored.append(guesses)
            j = int(np.argmax(guesses.real))
            growth.append(guesses[j].real)
            lams.append(guesses[j])
        self._grid_u = np.asarray(u, dtype=float)
        self._grid_modes = stored
        return np.array(growth), np.array(lams)

    def __call__(self, u):
        # Continue from the modes converged at the nearest grid airspeed below u.
        i = max(int(np.searchsorted(self._grid_u, u, side="right")) - 1, 0)
        modes = self.modes_at(u, self._grid_modes[i])
        j = int(np.argmax(modes.real))
        return float(modes[j].real), complex(modes[j])


def growth_rate(model, airspeed, density: float, damping=None) -> np.ndarray:
    """Largest real part [1/s] of the (non-neutral) eigenvalues at each airspeed.

    Quasi-steady or finite-state aerodynamics; ``airspeed`` any shape [m/s].
    """
    g, _ = _EigenGrowth(model, density, damping).grid(airspeed)
    return g


def bare_flutter(wing, density: float, aero=None) -> FlutterResult:
    """The onset of instability of the wing without DVA (quasi-steady by default)."""
    from aero_dva.wing.model import AeroelasticModel  # the model module imports none of this

    return flutter_speed(AeroelasticModel(wing, None, aero), density)


def bare_critical_airspeed(wing, density: float, aero=None) -> float:
    """Critical airspeed [m/s] of the wing without DVA (quasi-steady by default): the
    reference of every U/U_cr."""
    return bare_flutter(wing, density, aero).critical_airspeed


def flutter_speed(model, density: float = 1.2, airspeed_range=None, damping=None,
                  n_grid: int | None = None, xtol: float = 1e-10) -> FlutterResult:
    """Lowest airspeed at which the model becomes unstable, and the flutter frequency.

    Parameters
    ----------
    model : AeroelasticModel
    density : float
        Air density [kg/m^3], > 0.
    airspeed_range : (float, float), optional
        Searched airspeeds [m/s], ``0 <= low < high``; the model must be stable at ``low``.
        Default: from 0 on up to 1e5 m/s (steps of at most 25 m/s or half the airspeed).
    damping : float, optional
        Tunable damper [N s/m] (``c2`` or ``c1``), held fixed; default the absorber's.
    n_grid : int, optional
        The longest step is the range over ``n_grid - 1`` (default 5, i.e. 25 m/s for the
        default search); for Theodorsen p-k models, grid points per range (default 32).
    xtol : float
        Relative tolerance on the critical airspeed.

    Returns
    -------
    FlutterResult

    Raises
    ------
    NoFlutterError
        No instability in ``airspeed_range``.
    ValueError
        Bad arguments, or the model is already unstable at the low end of the range.

    Notes
    -----
    With quasi-steady or finite-state aerodynamics the search marches up from the low end,
    each sample one eigenvalue problem with the slopes of every mode from the left and right
    eigenvectors; steps end where a rising mode's tangent reaches zero, and a stable step is
    split where the tangents at its ends leave room for a crossing
    (:mod:`aero_dva.wing.flutter_march`). The first sign change is solved by Newton's method on
    the growth rate with the eigenvalue derivative, safeguarded by bisection inside the
    bracket. Theodorsen models use :func:`reference_flutter_speed` (p-k method).
    :func:`grid_flutter_speed` keeps the previous fixed-grid search.
    """
    if isinstance(getattr(model, "aero", None), TheodorsenAero):
        return reference_flutter_speed(model, density, airspeed_range, damping,
                                       64 if n_grid is None else 2 * int(n_grid), xtol)
    rho, n, damping = _checked(model, density, damping, 5 if n_grid is None else n_grid)
    growth = TangentGrowth(*model.polynomial_unchecked(rho, damping))
    if airspeed_range is None:
        low, high = 0.0, 1e5
        shortest = 100.0 / (n - 1)

        def max_step(u):
            return max(shortest, 0.5 * u)
    else:
        low, high = _checked_range(airspeed_range)
        shortest = (high - low) / (n - 1)

        def max_step(u):
            return shortest
    bracket = march_to_instability(growth, low, high, max_step, True, 1e-9 * high)
    if bracket is None:
        where = (f"below {high:g} m/s" if airspeed_range is None
                 else f"between {low:g} and {high:g} m/s")
        raise NoFlutterError(f"no flutter or divergence {where} at density {rho:g} kg/m^3")
    a, b = bracket
    # Start from the root of the critical mode's tangent at the unstable end.
    slope = b.derivative.real
    x0 = b.airspeed - b.growth / slope if np.isfinite(slope) and slope > 0 else None
    u_cr, lam_cr = _safeguarded_newton(growth, a.airspeed, b.airspeed, a.growth, b.growth,
                                       xtol, x0=x0)
    return _result(u_cr, lam_cr, rho)


def _checked(model, density, damping, n_grid):
    rho = non_negative(density, "density")
    if rho <= 0:
        raise ValueError("density must be > 0")
    n = int(n_grid)
    if n < 4:
        raise ValueError("n_grid must be >= 4")
    if damping is not None:
        damping = non_negative(damping, "damping", allow_inf=getattr(model, "has_maxwell", False))
    return rho, n, damping


def _checked_range(airspeed_range):
    try:
        low, high = (real_scalar(v, "airspeed_range") for v in airspeed_range)
    except (TypeError, ValueError) as exc:
        raise ValueError("airspeed_range must be two airspeeds (low, high) in m/s") from exc
    if not (0.0 <= low < high and np.isfinite(high)):
        raise ValueError(f"airspeed_range must satisfy 0 <= low < high, got {(low, high)}")
    return low, high


def _result(u_cr, lam_cr, rho) -> FlutterResult:
    kind = "flutter" if abs(lam_cr.imag) > NEUTRAL else "divergence"
    return FlutterResult(
        critical_airspeed=float(u_cr),
        flutter_frequency=abs(lam_cr.imag) / (2 * np.pi) if kind == "flutter" else 0.0,
        kind=kind,
        density=rho,
        eigenvalue=lam_cr,
    )


def grid_flutter_speed(model, density: float = 1.2, airspeed_range=None, damping=None,
                       n_grid: int = 16, xtol: float = 1e-10) -> FlutterResult:
    """:func:`flutter_speed` by the previous search: fixed grids of ``n_grid`` airspeeds per
    range, ``(0, 100)`` then on to 400, 1600, ... up to 1e5 m/s (each range starting at the
    previous range's last stable sample), local maxima of the samples refined, then the same
    safeguarded Newton iteration. Quasi-steady and finite-state models only; kept as the
    reference the marching search is compared with (tests, ``bench_wing_flutter``).
    """
    if isinstance(getattr(model, "aero", None), TheodorsenAero):
        raise ValueError("grid_flutter_speed needs quasi-steady or finite-state aerodynamics; "
                         "use flutter_speed for a Theodorsen (p-k) model")
    rho, n, damping = _checked(model, density, damping, n_grid)
    growth = _EigenGrowth(model, rho, damping, checked=True)
    if airspeed_range is None:
        low, high = 0.0, 100.0
        while True:
            try:
                return _newton_flutter(growth, rho, low, high, n, xtol, first=low == 0.0)
            except NoFlutterError as exc:
                if high >= 1e5:
                    raise NoFlutterError(
                        f"no flutter or divergence below {high:g} m/s at density {rho:g} kg/m^3"
                    ) from None
                # Continue from the last strictly stable sample: the range's end may already
                # be neutral to round-off (a wing tuned to flutter exactly there).
                low, high = exc.resume, 4.0 * high
    low, high = _checked_range(airspeed_range)
    return _newton_flutter(growth, rho, low, high, n, xtol, first=True)


def _newton_flutter(growth, rho, low, high, n_grid, xtol, first):
    u = low + (high - low) * np.arange(n_grid) / (n_grid - 1)
    g, lam_max = growth.samples(u)
    # Zero structural damping leaves the wind-off modes exactly neutral: allow round-off.
    tol = 1e-9 * max(lam_max, 1.0)
    if first and g[0] > tol:
        raise ValueError(
            f"the model is already unstable at the low end of airspeed_range ({low:g} m/s)"
        )
    bracket = _first_bracket(growth, u, g, high, tol)
    if bracket is None:
        exc = NoFlutterError(
            f"no flutter or divergence between {low:g} and {high:g} m/s at density {rho:g} "
            "kg/m^3"
        )
        negative = np.flatnonzero(g < 0)
        exc.resume = float(u[negative[-1]]) if negative.size else high
        raise exc
    a, b = bracket
    i = int(np.searchsorted(u, a))
    gb = g[i + 1] if b == u[i + 1] else growth.at(b)[0]
    u_cr, lam_cr = _safeguarded_newton(growth, a, b, g[i], gb, xtol)
    return _result(u_cr, lam_cr, rho)


def _safeguarded_newton(growth, a, b, ga, gb, xtol, maxiter: int = 100, x0=None):
    """Root of the growth rate in ``(a, b)`` (``g(a) < 0 < g(b)``) and its critical eigenvalue.

    Newton steps with the eigenvalue derivative from the secant point on, bisection whenever a
    step would leave the bracket or not halve the step before it (Press et al., Numerical
    Recipes, ``rtsafe``). Two Newton steps in a row measure the convergence: with
    ``K = |dx| / dx_prev^2`` the point after ``dx`` is within about ``K dx^2`` of the root; once
    that is below ``xtol / 10`` relative it is returned without another eigenvalue problem, its
    eigenvalue carried along by the derivative. Otherwise the search ends when a step is below
    ``xtol`` relative. ``x0``: a first point inside the bracket (default the secant point).
    """
    if x0 is not None and a < x0 < b:
        x = x0
    else:
        x = a - ga * (b - a) / (gb - ga) if gb > ga else 0.5 * (a + b)
    dx_old = dx = b - a
    newton_dx = None  # the previous step, if it was a Newton step
    for _ in range(maxiter):
        g, lam, dlam = growth.at(x)
        if g == 0.0:
            return x, lam
        if g < 0:
            a = x
        else:
            b = x
        slope = dlam.real
        newton_ok = (np.isfinite(slope) and slope != 0.0
                     and a < x - g / slope < b and abs(2.0 * g) <= abs(dx_old * slope))
        dx_old = dx
        dx = g / slope if newton_ok else x - 0.5 * (a + b)
        if newton_ok and newton_dx and abs(dx) * dx * dx <= 0.1 * xtol * x * newton_dx**2:
            return x - dx, lam - dlam * dx
        if abs(dx) <= xtol * x or b - a <= xtol * b:
            return x, lam
        newton_dx = dx if newton_ok else None
        x = x - dx
    return x, lam


def reference_flutter_speed(model, density: float = 1.2, airspeed_range=None, damping=None,
                            n_grid: int = 64, xtol: float = 1e-10) -> FlutterResult:
    """:func:`flutter_speed` by the previous route: a 64-point grid per range, Brent's method.

    Kept as the reference the faster route is compared with (tests, ``bench_wing_flutter``),
    and as the route of Theodorsen (p-k) models. Same parameters and result.

    Parameters
    ----------
    model : AeroelasticModel
    density : float
        Air density [kg/m^3], > 0.
    airspeed_range : (float, float), optional
        Searched airspeeds [m/s], ``0 <= low < high``; the model must be stable at ``low``.
        Default: ``(0, 100)``, then ``(0, 400)``, ``(0, 1600)``, ... up to 1e5 m/s, so that
        the grid is always fine compared with the critical airspeed.
    damping : float, optional
        Tunable damper [N s/m] (``c2`` or ``c1``), held fixed; default the absorber's.
    n_grid : int
        Grid points for bracketing (local maxima between them are refined).
    xtol : float
        Relative tolerance on the critical airspeed.

    Returns
    -------
    FlutterResult

    Raises
    ------
    NoFlutterError
        No instability in ``airspeed_range``.
    ValueError
        Bad arguments, or the model is already unstable at the low end of the range.
    """
    rho = non_negative(density, "density")
    if rho <= 0:
        raise ValueError("density must be > 0")
    if airspeed_range is None:
        high = 100.0
        while True:
            try:
                return reference_flutter_speed(model, rho, (0.0, high), damping, n_grid,
                                               xtol)
            except NoFlutterError:
                if high >= 1e5:
                    raise NoFlutterError(
                        f"no flutter or divergence below {high:g} m/s at density {rho:g} kg/m^3"
                    ) from None
                high *= 4.0
    try:
        low, high = (real_scalar(v, "airspeed_range") for v in airspeed_range)
    except (TypeError, ValueError) as exc:
        raise ValueError("airspeed_range must be two airspeeds (low, high) in m/s") from exc
    if not (0.0 <= low < high and np.isfinite(high)):
        raise ValueError(f"airspeed_range must satisfy 0 <= low < high, got {(low, high)}")
    if int(n_grid) < 4:
        raise ValueError("n_grid must be >= 4")
    if isinstance(model.aero, TheodorsenAero):
        low = max(low, 1e-3 * high)
        growth = _PkGrowth(model, rho, damping, low)
        n_grid = max(4, int(n_grid) // 2)  # each p-k point is costly; maxima are refined
    else:
        growth = _EigenGrowth(model, rho, damping)
    u = np.linspace(low, high, int(n_grid))
    g, lam = growth.grid(u)
    # Zero structural damping leaves the wind-off modes exactly neutral: allow round-off.
    tol = 1e-9 * max(float(np.max(np.abs(lam))), 1.0)
    if g[0] > tol:
        raise ValueError(
            f"the model is already unstable at the low end of airspeed_range ({low:g} m/s)"
        )
    bracket = _first_bracket(growth, u, g, high, tol)
    if bracket is None:
        raise NoFlutterError(
            f"no flutter or divergence between {low:g} and {high:g} m/s at density {rho:g} "
            "kg/m^3"
        )
    a, b = bracket
    u_cr = brentq(lambda x: growth(x)[0], a, b, xtol=xtol * b, rtol=4 * np.finfo(float).eps,
                  maxiter=200)
    _, lam_cr = growth(u_cr)
    return _result(u_cr, lam_cr, rho)


def _first_bracket(growth, u, g, high, tol):
    """The first interval ``(a, b)`` with ``g(a) < 0 < g(b)``, refining local maxima."""
    for i in range(1, len(u)):
        if g[i] > tol:
            if g[i - 1] >= 0:
                raise ValueError("the model goes unstable right above the low end of "
                                 "airspeed_range; start the range higher")
            return u[i - 1], u[i]
        # A local maximum of the samples may hide a short excursion above zero.
        if i + 1 < len(u) and g[i] >= g[i - 1] and g[i] >= g[i + 1]:
            res = minimize_scalar(lambda x: -growth(x)[0], bounds=(u[i - 1], u[i + 1]),
                                  method="bounded", options={"xatol": 1e-9 * high})
            if -res.fun > tol:
                return u[i - 1], float(res.x)
    return None


def flutter_vs_density(model, densities, airspeed_range=None, damping=None):
    """Critical airspeed [m/s] and flutter frequency [Hz] at each density (NaN if none).

    Returns
    -------
    critical_airspeed, flutter_frequency : ndarray, shape (n_rho,)
    """
    rhos = np.atleast_1d(np.asarray(densities, dtype=float))
    u = np.full(rhos.shape, np.nan)
    f = np.full(rhos.shape, np.nan)
    for i, rho in enumerate(rhos):
        try:
            r = flutter_speed(model, rho, airspeed_range, damping)
        except NoFlutterError:
            continue
        u[i], f[i] = r.critical_airspeed, r.flutter_frequency
    return u, f
