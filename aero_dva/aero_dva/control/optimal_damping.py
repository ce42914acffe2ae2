"""Optimal tunable damping ``c2`` versus airspeed for an RMS objective (Zhang (2006) sec. 7.1.1).

The study's chapter-7 objective is the RMS of the vibration response under the random aileron
force (1 kN standard deviation, 1 kHz): of the plunge (fig. 7.1), the rotation (fig. 7.2) or, its
choice, the leading edge (fig. 7.3), which weights both and is easy to measure. At each airspeed
the optimal ``c2`` minimises that RMS (fig. 7.4).

Exact route (:func:`optimal_damping`)
-------------------------------------
The stationary RMS of every (airspeed, c2) pair of a grid comes from
:func:`aero_dva.control.stationary_rms.stationary_rms` (exact for the sampled system as simulated,
or its continuous limit), all pairs in one vectorised batch. At each airspeed the grid minimum
is then refined by a bounded scalar minimisation on the interval between its two grid
neighbours: ``scipy.optimize.minimize_scalar(method="bounded")`` (Brent's golden-section
search with parabolic interpolation), run for all airspeeds at once by
:func:`bounded_minimize_batch`, which takes the same steps and returns the same values as the
separate calls but evaluates the RMS of all airspeeds of one step in one batch (the per-call
overhead of separate ``minimize_scalar`` calls would outweigh the whole grid; see
``bench/bench_optimal_damping.py`` and docs/performance.md). The refined value is kept only if it
improves on the grid value. In the continuous limit with a Maxwell absorber the grid comes from
:func:`aero_dva.control.damping_map.continuous_rms_map` (one Lyapunov solve per airspeed, ``c2``
entering through one entry). An airspeed at which no grid value of ``c2`` is stable has no
optimum (NaN, minimum RMS ``inf``).

Simulated route (:func:`simulated_rms`), as the study did
--------------------------------------------------------
Each pair is flown at constant airspeed and ``c2`` with :func:`~aero_dva.flight.batch_simulator.
simulate_flights` (white Gaussian force held over each sample); a settling time is discarded
and the RMS of the rest is taken. Its expected relative standard error follows from the exact
autocorrelation of the sampled response (:meth:`~aero_dva.control.stationary_rms.StationaryRMS.
relative_standard_error`): ``sqrt(sum_tau rho(tau)^2 / (2 N M))`` for ``M`` flights of ``N``
kept samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.control.damping_map import continuous_rms_map
from aero_dva.control.stationary_rms import METHODS, stationary_rms
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.wing.checks import non_negative, positive, real_array
from aero_dva.wing.model import DISPLACEMENT_NAMES, AeroelasticModel

__all__ = [
    "BoundedResult",
    "MAX_SETTLE",
    "OBJECTIVES",
    "RMS_OUTPUTS",
    "OptimalDamping",
    "SimulatedRMS",
    "bounded_minimize_batch",
    "optimal_damping",
    "simulated_rms",
]

OBJECTIVES = ("leading_edge", "plunge", "rotation")
"""Objectives: RMS of the leading edge (the study's choice), plunge or pitch (rotation)."""

RMS_OUTPUTS = ("plunge", "pitch", "leading_edge")
"""Displacement outputs kept in the RMS surfaces, in this order: [m], [rad], [m]."""

_OUTPUT_OF = {"leading_edge": "leading_edge", "plunge": "plunge", "rotation": "pitch"}
_COLUMNS = [DISPLACEMENT_NAMES.index(name) for name in RMS_OUTPUTS]
_BATCH = 8192  # (airspeed, c2) pairs per vectorised batch

MAX_SETTLE = 30.0
"""[s] Cap of the automatic settling time (a nearly locked Maxwell damper relaxes over hours,
but that mode is barely excited by the force)."""


def _objective(objective: str) -> int:
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    return RMS_OUTPUTS.index(_OUTPUT_OF[objective])


def _model(model) -> AeroelasticModel:
    if not isinstance(model, AeroelasticModel):
        raise TypeError(f"model must be an AeroelasticModel, got {type(model).__name__}")
    if model.absorber is None:
        raise ValueError("model has no absorber: there is no damper to tune")
    return model


def _airspeeds(airspeeds) -> np.ndarray:
    u = real_array(airspeeds, "airspeeds")
    if u.ndim != 1 or u.size < 1:
        raise ValueError(f"airspeeds must be a non-empty 1-D array, got shape {u.shape}")
    if np.any(u < 0):
        raise ValueError("airspeeds must be >= 0 m/s")
    return u


def _grid(damping_grid, minimum: int = 3) -> np.ndarray:
    c = real_array(damping_grid, "damping_grid")
    if c.ndim != 1 or c.size < minimum:
        raise ValueError(f"damping_grid must be 1-D with at least {minimum} values, "
                         f"got shape {c.shape}")
    if np.any(c < 0) or np.any(np.diff(c) <= 0):
        raise ValueError("damping_grid must be >= 0 N s/m and strictly increasing")
    return c


@dataclass(frozen=True)
class OptimalDamping:
    """Optimal ``c2`` versus airspeed (Zhang (2006) fig. 7.1-7.4).

    Attributes
    ----------
    objective : str
        One of :data:`OBJECTIVES`.
    airspeeds : ndarray, shape (n_u,)
        [m/s]
    damping_grid : ndarray, shape (n_c,)
        [N s/m] the ``c2`` grid.
    rms : ndarray, shape (3, n_u, n_c)
        Stationary RMS of plunge [m], pitch [rad] and leading edge [m] (:data:`RMS_OUTPUTS`)
        on the grid; ``inf`` where unstable.
    optimal_damping : ndarray, shape (n_u,)
        [N s/m] the refined optimal ``c2``; NaN where no grid value is stable.
    min_rms : ndarray, shape (n_u,)
        The objective's RMS at ``optimal_damping`` (its unit); ``inf`` where no optimum.
    optimal_rms : ndarray, shape (3, n_u)
        All three RMS outputs at ``optimal_damping``.
    at_bound : ndarray of bool, shape (n_u,)
        The optimum lies in the first or last grid interval: the true optimum may lie
        outside the grid.
    density : float
        [kg/m^3]
    force_std : float
        [N] force standard deviation per sample.
    sample_rate : float
        [Hz]
    method : str
        ``"discrete"`` (sampled, as simulated) or ``"continuous"``.
    """

    objective: str
    airspeeds: np.ndarray
    damping_grid: np.ndarray
    rms: np.ndarray
    optimal_damping: np.ndarray
    min_rms: np.ndarray
    optimal_rms: np.ndarray
    at_bound: np.ndarray
    density: float
    force_std: float
    sample_rate: float
    method: str

    @property
    def objective_rms(self) -> np.ndarray:
        """(n_u, n_c) RMS surface of the objective."""
        return self.rms[_objective(self.objective)]

    @property
    def has_optimum(self) -> np.ndarray:
        """(n_u,) bool: some grid value of ``c2`` is stable at this airspeed."""
        return np.isfinite(self.min_rms)

    def stable_airspeed_limit(self) -> float:
        """[m/s] Largest airspeed of the contiguous run from the first airspeed at which an
        optimum exists (NaN if none at the first airspeed)."""
        ok = self.has_optimum
        if not ok[0]:
            return math.nan
        stop = int(np.argmin(ok)) if not ok.all() else ok.size
        return float(self.airspeeds[stop - 1])


def _surface(model, airspeeds, grid, density, force_std, sample_rate, method, progress):
    """RMS surface (3, n_u, n_c), computed in batches of airspeeds."""
    n_u, n_c = airspeeds.size, grid.size
    out = np.empty((3, n_u, n_c))
    step = max(1, _BATCH // n_c)
    fast = method == "continuous" and model.has_maxwell  # one Lyapunov solve per airspeed
    for s in range(0, n_u, step):
        u = airspeeds[s:s + step, None]
        if fast:
            rms, _ = continuous_rms_map(model, u[:, 0], grid, density, force_std=force_std,
                                        sample_rate=sample_rate)
        else:
            rms = stationary_rms(model, u, density, grid[None, :], force_std=force_std,
                                 sample_rate=sample_rate, method=method).displacement
        out[:, s:s + step] = np.moveaxis(rms[..., _COLUMNS], -1, 0)
        if progress is not None:
            progress(min(s + step, n_u))
    return out


_SQRT_EPS = math.sqrt(2.2e-16)
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))


@dataclass(frozen=True)
class BoundedResult:
    """Outcome of :func:`bounded_minimize_batch`, one entry per problem.

    Attributes
    ----------
    x : ndarray, shape (K,)
        Minimiser found (``OptimizeResult.x`` of ``minimize_scalar``).
    fun : ndarray, shape (K,)
        Objective value at ``x``.
    nfev : ndarray of int, shape (K,)
        Objective evaluations used.
    success : ndarray of bool, shape (K,)
        Converged within ``maxiter`` evaluations without NaN.
    """

    x: np.ndarray
    fun: np.ndarray
    nfev: np.ndarray
    success: np.ndarray


def bounded_minimize_batch(evaluate, lower, upper, xatol, maxiter: int = 500) -> BoundedResult:
    """``scipy.optimize.minimize_scalar(f_k, bounds=(lower[k], upper[k]), method="bounded")``
    for many problems ``k`` at once.

    This is scipy's bounded method (Brent's golden-section search with parabolic
    interpolation, ``_minimize_scalar_bounded``) step for step, with the problems' states in
    arrays: each iteration evaluates the objectives of all unfinished problems in one call.
    Every problem takes exactly the steps it would take alone, so the results equal those of
    separate ``minimize_scalar`` calls (checked by
    ``tests/unit/aero_dva/control/test_optimal_damping.py``).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(k, x) -> f`` for index array ``k`` (m,) and points ``x`` (m,), returning
        the objective values (m,) of problems ``k`` at ``x``.
    lower, upper : array_like, shape (K,)
        Bounds, finite, ``lower <= upper``.
    xatol : float or array_like, shape (K,)
        Absolute tolerance of each solution.
    maxiter : int
        Most objective evaluations per problem.

    Returns
    -------
    BoundedResult
    """
    a = np.array(lower, dtype=float, ndmin=1)
    b = np.array(upper, dtype=float, ndmin=1)
    if a.shape != b.shape or a.ndim != 1 or not (np.all(np.isfinite(a))
                                                 and np.all(np.isfinite(b))):
        raise ValueError("lower and upper must be finite 1-D arrays of one shape")
    if np.any(a > b):
        raise ValueError("a lower bound exceeds its upper bound")
    xatol = np.broadcast_to(np.asarray(xatol, dtype=float), a.shape)
    everyone = np.arange(a.size)
    fulc = a + _GOLDEN * (b - a)
    nfc, xf = fulc.copy(), fulc.copy()
    rat = np.zeros_like(a)
    e = np.zeros_like(a)
    fx = np.asarray(evaluate(everyone, xf), dtype=float).copy()
    num = np.ones(a.size, dtype=int)
    fu = np.full_like(a, np.inf)
    ffulc, fnfc = fx.copy(), fx.copy()
    xm = 0.5 * (a + b)
    tol1 = _SQRT_EPS * np.abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    running = np.abs(xf - xm) > (tol2 - 0.5 * (b - a))
    hit_max = np.zeros(a.size, dtype=bool)
    while running.any():
        k = np.flatnonzero(running)
        ak, bk, xfk, fxk = a[k], b[k], xf[k], fx[k]
        nfck, fnfck, fulck, ffulck = nfc[k], fnfc[k], fulc[k], ffulc[k]
        t1, t2, xmk = tol1[k], tol2[k], xm[k]
        ek, ratk = e[k].copy(), rat[k].copy()
        # parabolic fit where the last step was not tiny
        para = np.abs(ek) > t1
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            r = (xfk - nfck) * (fxk - ffulck)
            q = (xfk - fulck) * (fxk - fnfck)
            p = (xfk - fulck) * q - (xfk - nfck) * r
            q = 2.0 * (q - r)
            p = np.where(q > 0.0, -p, p)
            q = np.abs(q)
            r = ek.copy()
            ek = np.where(para, ratk, ek)
            accept = para & (np.abs(p) < np.abs(0.5 * q * r)) & (p > q * (ak - xfk)) & (
                p < q * (bk - xfk))
            prat = np.where(accept, p / np.where(accept, q, 1.0), 0.0)
        xp = xfk + prat
        near = accept & (((xp - ak) < t2) | ((bk - xp) < t2))
        si = np.sign(xmk - xfk) + ((xmk - xfk) == 0)
        ratk = np.where(accept, np.where(near, t1 * si, prat), ratk)
        golden = ~accept
        eg = np.where(xfk >= xmk, ak - xfk, bk - xfk)
        ek = np.where(golden, eg, ek)
        ratk = np.where(golden, _GOLDEN * eg, ratk)
        si = np.sign(ratk) + (ratk == 0)
        x = xfk + si * np.maximum(np.abs(ratk), t1)
        fuk = np.asarray(evaluate(k, x), dtype=float)
        num[k] += 1
        better = fuk <= fxk
        right = x >= xfk
        # better: move the bracket end behind the old best, shift the history
        a_new = np.where(better, np.where(right, xfk, ak), np.where(~(x < xfk), ak, x))
        b_new = np.where(better, np.where(right, bk, xfk), np.where(x < xfk, bk, x))
        worse = ~better
        c1 = worse & ((fuk <= fnfck) | (nfck == xfk))
        c2 = worse & ~c1 & ((fuk <= ffulck) | (fulck == xfk) | (fulck == nfck))
        fulc[k] = np.where(better | c1, nfck, np.where(c2, x, fulck))
        ffulc[k] = np.where(better | c1, fnfck, np.where(c2, fuk, ffulck))
        nfc[k] = np.where(better, xfk, np.where(c1, x, nfck))
        fnfc[k] = np.where(better, fxk, np.where(c1, fuk, fnfck))
        xf[k] = np.where(better, x, xfk)
        fx[k] = np.where(better, fuk, fxk)
        a[k], b[k], e[k], rat[k], fu[k] = a_new, b_new, ek, ratk, fuk
        xm[k] = 0.5 * (a[k] + b[k])
        tol1[k] = _SQRT_EPS * np.abs(xf[k]) + xatol[k] / 3.0
        tol2[k] = 2.0 * tol1[k]
        going = np.abs(xf[k] - xm[k]) > (tol2[k] - 0.5 * (b[k] - a[k]))
        capped = num[k] >= maxiter
        hit_max[k] = capped
        running[k] = going & ~capped
    bad = np.isnan(xf) | np.isnan(fx) | np.isnan(fu)
    return BoundedResult(x=xf, fun=fx, nfev=num, success=~hit_max & ~bad)


def optimal_damping(model: AeroelasticModel, airspeeds, damping_grid, density: float, *,
                    objective: str = "leading_edge", force_std: float = 1000.0,
                    sample_rate: float = 1000.0, method: str = "discrete",
                    refine: bool = True, xtol: float = 1e-4,
                    progress=None) -> OptimalDamping:
    """Optimal ``c2`` at each airspeed for an exact stationary RMS objective.

    Parameters
    ----------
    model : AeroelasticModel
        With the tunable absorber (Maxwell: ``c2``; passive: ``c1``).
    airspeeds : array_like, shape (n_u,)
        [m/s]
    damping_grid : array_like, shape (n_c,)
        [N s/m] ``c2`` values, >= 0, strictly increasing, at least 3.
    density : float
        [kg/m^3]
    objective : {"leading_edge", "plunge", "rotation"}
        Which RMS to minimise (Zhang (2006) fig. 7.3, 7.1, 7.2).
    force_std : float
        [N] aileron force standard deviation per sample (the seed: 1000 N).
    sample_rate : float
        [Hz] (the seed: 1000 Hz).
    method : {"discrete", "continuous"}
        Sampled system as simulated, or its continuous limit.
    refine : bool
        Refine each grid minimum with ``minimize_scalar`` (bounded Brent).
    xtol : float
        Refinement tolerance relative to the bracketing interval (two grid steps).
    progress : callable, optional
        Called with the number of airspeeds done after each batch (for progress bars).

    Returns
    -------
    OptimalDamping
    """
    model = _model(model)
    u = _airspeeds(airspeeds)
    grid = _grid(damping_grid)
    rho = positive(density, "density")
    k = _objective(objective)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    sigma = non_negative(force_std, "force_std")
    rate = positive(sample_rate, "sample_rate")
    tol = positive(xtol, "xtol")
    rms = _surface(model, u, grid, rho, sigma, rate, method, progress)
    obj = rms[k]
    has = np.isfinite(obj).any(axis=1)
    j = np.argmin(np.where(np.isfinite(obj), obj, np.inf), axis=1)
    best_c = np.where(has, grid[j], np.nan)
    best_rms = np.where(has, obj[np.arange(u.size), j], np.inf)
    best_all = np.where(has, rms[:, np.arange(u.size), j], np.inf)
    at_bound = has & ((j == 0) | (j == grid.size - 1))

    def evaluate(speed, c):
        res = stationary_rms(model, speed, rho, c, force_std=sigma, sample_rate=rate,
                             method=method)
        return np.moveaxis(res.displacement[..., _COLUMNS], -1, 0)

    todo = np.flatnonzero(has)
    if refine and todo.size:
        penalty = 1e3 * best_rms[todo]

        def objective_values(idx, c):
            values = evaluate(u[todo[idx]], c)[k]
            return np.where(np.isfinite(values), values, penalty[idx])

        lo = grid[np.maximum(j[todo] - 1, 0)]
        hi = grid[np.minimum(j[todo] + 1, grid.size - 1)]
        found = bounded_minimize_batch(objective_values, lo, hi, tol * (hi - lo))
        keep = found.success & (found.fun < best_rms[todo])
        if keep.any():
            idx = todo[keep]
            best_c[idx] = found.x[keep]
            best_all[:, idx] = evaluate(u[idx], found.x[keep])
            best_rms[idx] = best_all[k, idx]
        at_bound = has & ((best_c < grid[1]) | (best_c > grid[-2]))
    return OptimalDamping(
        objective=objective, airspeeds=u, damping_grid=grid, rms=rms,
        optimal_damping=best_c, min_rms=best_rms, optimal_rms=best_all, at_bound=at_bound,
        density=rho, force_std=sigma, sample_rate=rate, method=method,
    )


@dataclass(frozen=True)
class SimulatedRMS:
    """RMS from constant-condition simulations next to the exact stationary values.

    Attributes
    ----------
    objective : str
    airspeeds : ndarray, shape (n_u,)
        [m/s]
    damping_grid : ndarray, shape (n_c,)
        [N s/m]
    rms : ndarray, shape (3, n_u, n_c)
        Simulated RMS of plunge [m], pitch [rad], leading edge [m] over the kept samples of
        all flights (root of the pooled mean square).
    exact : ndarray, shape (3, n_u, n_c)
        Exact stationary RMS of the sampled system (``inf`` where unstable).
    relative_standard_error : ndarray, shape (3, n_u, n_c)
        Expected relative standard error of ``rms`` (``inf`` where unstable).
    settle_time : ndarray, shape (n_u, n_c)
        [s] discarded at the start of each flight.
    duration : float
        [s] kept after settling, per flight.
    flights : int
        Independent flights per pair.
    n_samples : int
        Kept samples per flight.
    force_std, sample_rate, density : float
    """

    objective: str
    airspeeds: np.ndarray
    damping_grid: np.ndarray
    rms: np.ndarray
    exact: np.ndarray
    relative_standard_error: np.ndarray
    settle_time: np.ndarray
    duration: float
    flights: int
    n_samples: int
    force_std: float
    sample_rate: float
    density: float

    @property
    def z_score(self) -> np.ndarray:
        """(3, n_u, n_c) ``(rms - exact) / (exact * relative_standard_error)`` (NaN where
        unstable)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            z = (self.rms - self.exact) / (self.exact * self.relative_standard_error)
        return np.where(np.isfinite(self.exact), z, np.nan)

    @property
    def optimal_damping(self) -> np.ndarray:
        """(n_u,) [N s/m] grid value of ``c2`` with the smallest simulated objective RMS."""
        obj = self.rms[_objective(self.objective)]
        return self.damping_grid[np.argmin(obj, axis=1)]


def simulated_rms(model: AeroelasticModel, airspeeds, damping_grid, density: float, *,
                  rng: np.random.Generator, duration: float = 20.0, settle_time=None,
                  flights: int = 1, objective: str = "leading_edge",
                  force_std: float = 1000.0, sample_rate: float = 1000.0,
                  progress=None) -> SimulatedRMS:
    """RMS of constant-condition flights (the study's route) with the exact values beside.

    Parameters
    ----------
    model : AeroelasticModel
    airspeeds : array_like, shape (n_u,)
        [m/s]
    damping_grid : array_like, shape (n_c,)
        [N s/m] (at least one value).
    density : float
        [kg/m^3]
    rng : numpy.random.Generator
        Source of the force samples (``numpy.random.default_rng(seed)``).
    duration : float
        [s] kept per flight after settling.
    settle_time : float, optional
        [s] discarded at the start of each flight, which starts at rest. Default: five time
        constants of the slowest mode, ``5 / |growth rate|`` (so the start-up deficit of the
        variance is below ``exp(-10)``), between 0.5 s and :data:`MAX_SETTLE`; 1 s where
        unstable.
    flights : int
        Independent flights per pair (their mean squares are pooled).
    objective : str
        Objective used by :attr:`SimulatedRMS.optimal_damping`.
    force_std : float
        [N] per sample.
    sample_rate : float
        [Hz]
    progress : callable, optional
        Called with the number of pairs done.

    Returns
    -------
    SimulatedRMS
    """
    model = _model(model)
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng)")
    u = _airspeeds(airspeeds)
    grid = _grid(damping_grid, minimum=1)
    rho = positive(density, "density")
    _objective(objective)
    sigma = non_negative(force_std, "force_std")
    rate = positive(sample_rate, "sample_rate")
    keep = int(round(positive(duration, "duration") * rate))
    if isinstance(flights, bool) or int(flights) != flights or flights < 1:
        raise ValueError(f"flights must be an integer >= 1, got {flights}")
    flights = int(flights)
    if keep < 2:
        raise ValueError("duration must span at least two samples")
    exact = stationary_rms(model, u[:, None], rho, grid[None, :], force_std=sigma,
                           sample_rate=rate, correlation=True)
    if settle_time is None:
        with np.errstate(divide="ignore"):
            settle = np.where(exact.stable, np.clip(5.0 / -exact.growth_rate, 0.5, MAX_SETTLE),
                              1.0)
    else:
        settle = np.full(exact.stable.shape, non_negative(settle_time, "settle_time"))
    rse = exact.relative_standard_error(keep, flights)
    sim = np.empty((3, u.size, grid.size))
    done = 0
    for i, speed in enumerate(u):
        for j, c in enumerate(grid):
            skip = int(round(settle[i, j] * rate))
            force = sigma * rng.standard_normal((flights, skip + keep))
            traces = simulate_flights(model.wing, model.absorber, force=force,
                                      airspeed=float(speed), density=rho, damping=float(c),
                                      sample_rate=rate, aero=model.aero, quantum=0.0)
            kept = traces.displacements[:, _COLUMNS, skip:]
            sim[:, i, j] = np.sqrt(np.mean(kept**2, axis=(0, 2)))
            done += 1
            if progress is not None:
                progress(done)
    return SimulatedRMS(
        objective=objective, airspeeds=u, damping_grid=grid, rms=sim,
        exact=np.moveaxis(exact.displacement[..., _COLUMNS], -1, 0),
        relative_standard_error=np.moveaxis(rse[..., _COLUMNS], -1, 0),
        settle_time=settle, duration=keep / rate, flights=flights, n_samples=keep,
        force_std=sigma, sample_rate=rate, density=rho,
    )
