"""The continuous-limit c2 map by one Lyapunov solve per airspeed equals the pairwise route."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control.damping_map import continuous_rms_map, hurwitz_stable
from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing


@pytest.fixture(scope="module")
def cfg():
    return load_wing()


def _pairwise(model, speeds, grid, rho, **kw):
    res = stationary_rms(model, speeds[:, None], rho, grid[None, :], method="continuous", **kw)
    return res.displacement, res.stable


@pytest.mark.parametrize("aero", [None, WagnerAero()], ids=["quasi-steady", "wagner"])
def test_map_equals_the_pairwise_modal_solution(cfg, aero):
    """Across the flutter boundary (stable and unstable pairs), c2 = 0 and c2 = inf included,
    and with two aerodynamic lag states after the Maxwell node (d is not the last state)."""
    model = AeroelasticModel(cfg.wing, cfg.absorber, aero)
    speeds = np.linspace(60.0, 125.0, 27)
    grid = np.r_[0.0, 1e-5, np.geomspace(5.0, 5e4, 40), np.inf]
    rms, stable = continuous_rms_map(model, speeds, grid, cfg.air_density, force_std=700.0,
                                     sample_rate=500.0)
    ref, ref_stable = _pairwise(model, speeds, grid, cfg.air_density, force_std=700.0,
                                sample_rate=500.0)
    assert stable.any() and not stable.all()
    np.testing.assert_array_equal(stable, ref_stable)
    np.testing.assert_array_equal(np.isinf(rms), np.isinf(ref))
    fin = np.isfinite(ref)
    np.testing.assert_allclose(rms[fin], ref[fin], rtol=1e-9, atol=0.0)


def test_optimal_damping_continuous_uses_the_map_with_the_same_result(cfg):
    model = AeroelasticModel(cfg.wing, cfg.absorber)
    speeds = np.linspace(80.0, 115.0, 8)
    grid = np.linspace(0.0, 2500.0, 26)
    res = optimal_damping(model, speeds, grid, cfg.air_density, method="continuous",
                          refine=False)
    ref, _ = _pairwise(model, speeds, grid, cfg.air_density)
    fin = np.isfinite(ref[..., 2])
    np.testing.assert_allclose(res.objective_rms[fin], ref[..., 2][fin], rtol=1e-9)
    assert np.all(np.isinf(res.objective_rms[~fin]))


def test_hurwitz_test_agrees_with_the_roots():
    rng = np.random.default_rng(3)
    roots = rng.normal(size=(400, 6)) + 1j * rng.normal(size=(400, 6))
    roots = np.concatenate([roots[:, :3], roots[:, :3].conj()], axis=1)  # real polynomials
    roots.real -= 0.4  # about half of the polynomials stable
    coef = np.array([np.poly(r).real for r in roots])
    expected = np.all(roots.real < 0, axis=1)
    assert 50 < expected.sum() < 350
    np.testing.assert_array_equal(hurwitz_stable(coef), expected)
    odd = np.array([np.poly([-1.0, -2.0, -3.0]), np.poly([-1.0, 2.0, -3.0]),
                    np.poly([-1.0, 1j, -1j])]).real  # the last has roots on the axis
    np.testing.assert_array_equal(hurwitz_stable(odd), [True, False, False])


def test_bad_inputs_are_named(cfg):
    with pytest.raises(TypeError, match="Maxwell"):
        continuous_rms_map(AeroelasticModel(cfg.wing), [90.0], [500.0], 1.2)
    model = AeroelasticModel(cfg.wing, cfg.absorber)
    with pytest.raises(ValueError, match="damping_grid"):
        continuous_rms_map(model, [90.0], [-1.0], 1.2)
    with pytest.raises(ValueError, match="density"):
        continuous_rms_map(model, [90.0], [500.0], 0.0)
