"""Optimal damper c2 versus airspeed for the exact RMS objective (Zhang (2006) section 7.1.1)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from aero_dva.control import optimal_damping as od
from aero_dva.control.optimal_damping import optimal_damping, simulated_rms
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.wing.flutter import flutter_speed
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

RHO = 1.2
GRID = np.linspace(0.0, 2500.0, 51)


@pytest.fixture(scope="module")
def cfg():
    return load_wing()


@pytest.fixture(scope="module")
def model(cfg):
    return AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)


@pytest.fixture(scope="module")
def u_cr(cfg):
    return flutter_speed(AeroelasticModel(cfg.wing, None, cfg.aero), RHO).critical_airspeed


@pytest.fixture(scope="module")
def result(model, u_cr):
    return optimal_damping(model, np.linspace(0.8, 1.3, 51) * u_cr, GRID, RHO)


def test_result_shapes_and_units(result):
    assert result.objective == "leading_edge"
    assert result.rms.shape == (3, 51, GRID.size)
    assert result.optimal_damping.shape == result.min_rms.shape == (51,)
    assert result.optimal_rms.shape == (3, 51)
    assert result.objective_rms.shape == (51, GRID.size)
    assert result.method == "discrete" and result.force_std == 1000.0
    ok = result.has_optimum
    np.testing.assert_array_equal(result.min_rms[ok], result.optimal_rms[2, ok])


@pytest.mark.parametrize("objective", ["leading_edge", "plunge", "rotation"])
def test_optimum_is_a_true_minimum_on_a_fine_grid(model, u_cr, objective):
    """No c2 of a 5001-point grid over the whole range beats the refined optimum."""
    speeds = np.array([0.85, 1.0, 1.08]) * u_cr
    res = optimal_damping(model, speeds, GRID, RHO, objective=objective)
    column = {"leading_edge": 2, "plunge": 0, "rotation": 1}[objective]
    fine = np.linspace(GRID[0], GRID[-1], 5001)
    for i, speed in enumerate(speeds):
        values = stationary_rms(model, speed, RHO, fine).displacement[:, column]
        assert res.min_rms[i] <= values.min() * (1 + 1e-9)
        # and the refinement found the basin the fine grid sees, to its spacing
        assert abs(res.optimal_damping[i] - fine[np.argmin(values)]) <= 2 * (fine[1] - fine[0])
        # the reported minimum is the RMS at the reported c2
        check = stationary_rms(model, speed, RHO, res.optimal_damping[i]).displacement
        assert res.min_rms[i] == pytest.approx(check[column], rel=1e-12)


def test_refinement_never_worse_than_the_grid(model, u_cr):
    speeds = np.linspace(0.8, 1.1, 13) * u_cr
    coarse = optimal_damping(model, speeds, GRID, RHO, refine=False)
    fine = optimal_damping(model, speeds, GRID, RHO)
    assert np.all(np.isin(coarse.optimal_damping, GRID))
    assert np.all(fine.min_rms <= coarse.min_rms)
    assert np.all(np.abs(fine.optimal_damping - coarse.optimal_damping) <= GRID[1] - GRID[0])


def test_refinement_equals_independent_minimize_scalar(model, u_cr):
    """The batched refinement is minimize_scalar's bounded method: same c2, bit for bit."""
    speeds = np.array([0.8, 0.95, 1.05]) * u_cr
    res = optimal_damping(model, speeds, GRID, RHO, xtol=1e-4)
    for i, speed in enumerate(speeds):
        j = int(np.argmin(res.objective_rms[i]))
        lo, hi = GRID[max(j - 1, 0)], GRID[min(j + 1, GRID.size - 1)]
        ref = minimize_scalar(
            lambda c, s=speed: stationary_rms(model, s, RHO, c).displacement[2],
            bounds=(lo, hi), method="bounded", options={"xatol": 1e-4 * (hi - lo)})
        assert res.optimal_damping[i] == ref.x


def test_bounded_minimize_batch_matches_scipy_step_for_step():
    rng = np.random.default_rng(4)
    centres = rng.uniform(-1.0, 3.0, 40)
    widths = rng.uniform(0.1, 2.0, 40)
    lower, upper = centres - widths, centres + rng.uniform(0.1, 2.0, 40)
    shift = rng.uniform(-2.0, 2.0, 40)  # some minima lie outside the bounds
    funcs = [
        lambda x, c, s: (x - c - s) ** 2 + 0.3 * np.abs(np.sin(3 * x)),
        lambda x, c, s: np.abs(x - c - s) ** 0.7 - np.cos(x),
    ]
    for f in funcs:
        def evaluate(k, x, f=f):
            return np.array([f(float(xi), c=centres[ki], s=shift[ki]) for ki, xi in zip(k, x)])

        for xatol in (1e-5, 1e-2):
            batch = od.bounded_minimize_batch(evaluate, lower, upper, xatol)
            for k in range(40):
                ref = minimize_scalar(lambda x, k=k, f=f: f(x, c=centres[k], s=shift[k]),
                                      bounds=(lower[k], upper[k]), method="bounded",
                                      options={"xatol": xatol})
                assert batch.x[k] == ref.x and batch.fun[k] == ref.fun
                assert batch.nfev[k] == ref.nfev and batch.success[k] == ref.success
    capped = od.bounded_minimize_batch(lambda k, x: (x - 0.3) ** 2, [0.0], [1.0], 1e-12,
                                       maxiter=4)
    assert not capped.success[0] and capped.nfev[0] == 4
    with pytest.raises(ValueError, match="bound"):
        od.bounded_minimize_batch(lambda k, x: x, [1.0], [0.0], 1e-3)


def test_no_optimum_where_every_c2_is_unstable(model, u_cr, result):
    """Above the tuned critical airspeed: NaN optimum, inf RMS; the limit is where it ends."""
    limit = result.stable_airspeed_limit()
    assert 1.0 * u_cr < limit < 1.3 * u_cr
    above = result.airspeeds > limit
    assert above.any()
    assert np.all(np.isnan(result.optimal_damping[above]))
    assert np.all(np.isinf(result.min_rms[above]))
    assert np.all(np.isinf(result.rms[:, above]))
    below = ~above
    assert np.all(np.isfinite(result.min_rms[below]))
    # at the first unstable airspeed no grid value is stable, checked directly
    first = result.airspeeds[above][0]
    assert not stationary_rms(model, first, RHO, GRID).stable.any()


def test_optimal_rms_grows_with_airspeed_and_is_flat_at_low_speed(model, u_cr, result):
    """Seed 7.1.1: small and insensitive to c2 at 0.5 U_cr; the minimum grows with U."""
    ok = result.has_optimum
    assert np.all(np.diff(result.min_rms[ok]) > 0)
    low = optimal_damping(model, [0.5 * u_cr], GRID, RHO)
    surface = low.objective_rms[0]
    assert surface.max() / surface.min() < 1.05
    # smaller than anywhere on the 0.8-1.2 U_cr grid (default wing: 0.79 x the RMS at 0.8 U_cr)
    assert low.min_rms[0] < 0.8 * result.min_rms[0]


def test_objectives_have_different_optima(model, u_cr):
    """Seed: the translational and rotational optima differ (fig. 7.1 vs 7.2). For the
    reference wing the two curves cross near 0.9 U_cr, so compare away from the crossing."""
    speeds = np.array([0.8, 1.0]) * u_cr
    plunge = optimal_damping(model, speeds, GRID, RHO, objective="plunge")
    pitch = optimal_damping(model, speeds, GRID, RHO, objective="rotation")
    edge = optimal_damping(model, speeds, GRID, RHO)
    assert np.all(np.abs(plunge.optimal_damping - pitch.optimal_damping) > 10.0)
    # the leading edge weights both: its RMS at its own optimum beats the others' optima
    for other in (plunge, pitch):
        assert np.all(edge.min_rms <= other.optimal_rms[2])


def test_continuous_limit_gives_nearly_the_same_optimum(model, u_cr):
    speeds = np.array([0.85, 1.0, 1.08]) * u_cr
    d = optimal_damping(model, speeds, GRID, RHO)
    c = optimal_damping(model, speeds, GRID, RHO, method="continuous")
    np.testing.assert_allclose(c.optimal_damping, d.optimal_damping, rtol=2e-3)
    np.testing.assert_allclose(c.min_rms, d.min_rms, rtol=1e-3)


def test_progress_and_bad_inputs(model, cfg):
    seen = []
    optimal_damping(model, np.linspace(80, 100, 300), GRID, RHO, refine=False,
                    progress=seen.append)
    assert seen[-1] == 300 and seen == sorted(seen)
    with pytest.raises(ValueError, match="objective"):
        optimal_damping(model, [90.0], GRID, RHO, objective="yaw")
    with pytest.raises(ValueError, match="damping_grid"):
        optimal_damping(model, [90.0], [0.0, 500.0, 400.0], RHO)
    with pytest.raises(ValueError, match="damping_grid"):
        optimal_damping(model, [90.0], [0.0, 500.0], RHO)
    with pytest.raises(ValueError, match="airspeeds"):
        optimal_damping(model, [-1.0], GRID, RHO)
    with pytest.raises(ValueError, match="method"):
        optimal_damping(model, [90.0], GRID, RHO, method="euler")
    with pytest.raises(ValueError, match="absorber"):
        optimal_damping(AeroelasticModel(cfg.wing, None, cfg.aero), [90.0], GRID, RHO)
    with pytest.raises(TypeError, match="rng"):
        simulated_rms(model, [90.0], [300.0], RHO, rng=0)


def test_simulated_route_agrees_within_sampling_error(model, u_cr):
    """The study's route (settle, then RMS of a simulation) agrees with the exact RMS to
    within 3 of its expected standard errors, sqrt(sum rho^2 / (2 N M))."""
    sim = simulated_rms(model, np.array([0.85, 1.0]) * u_cr, [200.0, 600.0], RHO,
                        rng=np.random.default_rng(0), duration=20.0, flights=3)
    assert sim.rms.shape == sim.exact.shape == (3, 2, 2)
    assert np.all(sim.relative_standard_error < 0.05)
    assert np.all(np.abs(sim.z_score) < 3.0), sim.z_score
    assert np.all(sim.settle_time >= 0.5)
    assert sim.n_samples == 20000 and sim.flights == 3
    assert sim.optimal_damping.shape == (2,)
