"""Exact stationary RMS of the wing under white-noise aileron force (Zhang (2006) sec. 7.1.1)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl

from aero_dva.control import stationary_rms as srm
from aero_dva.control.stationary_rms import (
    solve_continuous_lyapunov_batch,
    solve_discrete_lyapunov_batch,
    stationary_covariance,
    stationary_rms,
)
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.flight.discretize import zoh
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.flutter import flutter_speed
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

RHO = 1.2
SIGMA = 1000.0  # [N] per sample, the study's excitation
DT = 1e-3


@pytest.fixture(scope="module")
def cfg():
    return load_wing()


@pytest.fixture(scope="module")
def model(cfg):
    return AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)


@pytest.fixture(scope="module")
def u_cr(cfg):
    return flutter_speed(AeroelasticModel(cfg.wing, None, cfg.aero), RHO).critical_airspeed


def _scipy_rms(model, speed, c2, method):
    a, b = model.matrices(speed, RHO, c2)
    if method == "discrete":
        phi, gam = zoh(a, b, DT)
        p = sl.solve_discrete_lyapunov(phi, SIGMA**2 * np.outer(gam, gam))
    else:
        p = sl.solve_continuous_lyapunov(a, -SIGMA**2 * DT * np.outer(b, b))
    c = model.c_displacement
    return np.sqrt(np.diag(c @ p @ c.T))


@pytest.mark.parametrize("method", ["discrete", "continuous"])
def test_matches_scipy_lyapunov(model, u_cr, method):
    """Modal solution = scipy's Lyapunov solvers, c2 from 0 (plain damper) to stiff."""
    speeds = np.array([0.5, 0.9, 1.02]) * u_cr
    c2 = np.array([0.0, 1e-3, 40.0, 300.0, 2500.0, 1e5])
    res = stationary_rms(model, speeds[:, None], RHO, c2[None, :], force_std=SIGMA,
                         sample_rate=1 / DT, method=method)
    assert res.displacement.shape == (3, 6, 4)
    for i, u in enumerate(speeds):
        for j, c in enumerate(c2):
            if not res.stable[i, j]:
                continue
            ref = _scipy_rms(model, u, c, method)
            np.testing.assert_allclose(res.displacement[i, j, :3], ref[:3], rtol=1e-6)


def test_wagner_aerodynamics_with_lag_states(cfg):
    model = AeroelasticModel(cfg.wing, cfg.absorber, WagnerAero())
    assert model.n_states == 9
    res = stationary_rms(model, 90.0, RHO, 300.0)
    np.testing.assert_allclose(res.displacement, _scipy_rms(model, 90.0, 300.0, "discrete"),
                               rtol=1e-6)


def test_kronecker_fallback_agrees_with_modal(model, monkeypatch):
    speeds = np.linspace(60.0, 108.0, 7)[:, None]
    c2 = np.array([0.0, 50.0, 400.0, 2000.0])[None, :]
    modal = stationary_rms(model, speeds, RHO, c2, correlation=True)
    modal_c = stationary_rms(model, speeds, RHO, c2, method="continuous")
    monkeypatch.setattr(srm, "CONDITION_LIMIT", 0.0)  # every system takes the Kronecker path
    kron = stationary_rms(model, speeds, RHO, c2, correlation=True)
    kron_c = stationary_rms(model, speeds, RHO, c2, method="continuous")
    ok = modal.stable
    assert ok.sum() >= 20
    np.testing.assert_allclose(kron.displacement[ok], modal.displacement[ok], rtol=1e-6)
    np.testing.assert_allclose(kron.acceleration[ok], modal.acceleration[ok], rtol=1e-6)
    np.testing.assert_allclose(kron.correlation_samples[ok], modal.correlation_samples[ok],
                               rtol=1e-5)
    np.testing.assert_allclose(kron_c.displacement[ok], modal_c.displacement[ok], rtol=1e-6)


def test_batch_solvers_match_scipy():
    rng = np.random.default_rng(3)
    n = 5
    a = rng.standard_normal((6, n, n)) - 3.0 * np.eye(n)
    q = rng.standard_normal((6, n, n))
    q = q @ q.transpose(0, 2, 1)
    phi = 0.3 * rng.standard_normal((6, n, n))
    pc = solve_continuous_lyapunov_batch(a, q)
    pd = solve_discrete_lyapunov_batch(phi, q)
    for k in range(6):
        np.testing.assert_allclose(pc[k], sl.solve_continuous_lyapunov(a[k], -q[k]),
                                   rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(pd[k], sl.solve_discrete_lyapunov(phi[k], q[k]),
                                   rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="phi"):
        solve_discrete_lyapunov_batch(np.zeros((3, 2)), np.eye(3))
    with pytest.raises(ValueError, match="q"):
        solve_continuous_lyapunov_batch(np.eye(3), np.eye(2))


def test_covariance_matches_scipy_and_is_inf_when_unstable(model, u_cr):
    a, b = model.matrices(np.array([0.9, 1.3]) * u_cr, RHO, 300.0)
    p = stationary_covariance(a, b, force_std=SIGMA, sample_rate=1 / DT)
    phi, gam = zoh(a[0], b[0], DT)
    ref = sl.solve_discrete_lyapunov(phi, SIGMA**2 * np.outer(gam, gam))
    c = model.c_displacement
    np.testing.assert_allclose(c @ p[0] @ c.T, c @ ref @ c.T, rtol=1e-6, atol=1e-18)
    assert np.all(np.isinf(p[1]))


def test_discrete_and_continuous_agree_to_order_dt(model, u_cr):
    """The sampled system tends to the continuous limit as dt -> 0, at least as O(dt).

    For this wing the difference is in fact O(dt^2) (it falls 4x per halving): the ZOH
    force's spectrum differs from white only by sinc^2(f dt), 1 - O((f dt)^2) in the wing's
    band.
    """
    c2 = np.array([0.0, 300.0, 1000.0, 2500.0])
    speed = 0.9 * u_cr
    diffs = []
    for rate in (250.0, 500.0, 1000.0, 2000.0):
        d = stationary_rms(model, speed, RHO, c2, sample_rate=rate).displacement[:, :3]
        c = stationary_rms(model, speed, RHO, c2, sample_rate=rate,
                           method="continuous").displacement[:, :3]
        diffs.append(np.max(np.abs(d - c) / d))
    diffs = np.array(diffs)
    assert np.all(diffs[1:] < 0.55 * diffs[:-1])  # at least first order in dt
    assert diffs[2] < 1e-3  # at 1 kHz: far below any sampling error of a simulation
    order = np.log2(diffs[:-1] / diffs[1:])
    assert np.all(order > 1.8)  # observed second order


def test_inf_when_unstable(model, u_cr):
    """Above the critical airspeed of a fixed c2 the RMS is inf; just below it is finite."""
    c2 = 300.0
    u_f = flutter_speed(model, RHO, (0.5 * u_cr, 2.0 * u_cr), damping=c2).critical_airspeed
    for method in ("discrete", "continuous"):
        res = stationary_rms(model, [0.999 * u_f, 1.001 * u_f, 1.3 * u_cr], RHO, c2,
                             method=method)
        assert res.stable.tolist() == [True, False, False]
        assert np.all(np.isfinite(res.displacement[0]))
        assert np.all(np.isinf(res.displacement[1:]))
        assert res.growth_rate[0] < 0 < res.growth_rate[1]
        if method == "discrete":
            assert np.all(np.isinf(res.acceleration[1:]))
    # every c2 of a wide grid is unstable far above the tuned critical airspeed
    res = stationary_rms(model, 1.3 * u_cr, RHO, np.linspace(0.0, 5000.0, 51))
    assert not res.stable.any()
    assert np.all(np.isinf(res.displacement))


def test_locked_damper_is_the_limit_of_large_c2(model):
    """c2 = inf adds a neutral, unexcited integrator: ignored, finite RMS = large-c2 limit."""
    res = stationary_rms(model, 90.0, RHO, [1e10, np.inf])
    assert res.stable.all()
    np.testing.assert_allclose(res.displacement[1], res.displacement[0], rtol=1e-6)


def test_simple_scaling_and_shapes(model):
    one = stationary_rms(model, 90.0, RHO, 300.0, force_std=1.0)
    two = stationary_rms(model, 90.0, RHO, 300.0, force_std=2.0)
    np.testing.assert_allclose(two.displacement, 2.0 * one.displacement, rtol=1e-12)
    zero = stationary_rms(model, 90.0, RHO, 300.0, force_std=0.0)
    assert np.all(zero.displacement == 0.0)
    grid = stationary_rms(model, np.linspace(60, 100, 5)[:, None], RHO,
                          np.linspace(0, 2500, 3)[None, :])
    assert grid.displacement.shape == (5, 3, 4)
    assert grid.acceleration.shape == (5, 3, 3)
    assert grid.output("leading_edge").shape == (5, 3)
    assert stationary_rms(model, 90.0, RHO, 300.0, method="continuous").acceleration is None


def test_bad_inputs(model, cfg):
    with pytest.raises(ValueError, match="method"):
        stationary_rms(model, 90.0, RHO, 300.0, method="euler")
    with pytest.raises(ValueError, match="force_std"):
        stationary_rms(model, 90.0, RHO, 300.0, force_std=-1.0)
    with pytest.raises(ValueError, match="sample_rate"):
        stationary_rms(model, 90.0, RHO, 300.0, sample_rate=0.0)
    with pytest.raises(ValueError, match="correlation"):
        stationary_rms(model, 90.0, RHO, 300.0, method="continuous", correlation=True)
    with pytest.raises(TypeError, match="model"):
        stationary_rms(cfg.wing, 90.0, RHO, 300.0)
    with pytest.raises(ValueError, match="damping"):
        stationary_rms(model, 90.0, RHO, -1.0)
    res = stationary_rms(model, 90.0, RHO, 300.0)
    with pytest.raises(ValueError, match="correlation"):
        res.relative_standard_error(1000)
    with pytest.raises(ValueError, match="name"):
        res.output("yaw")


def test_correlation_sum_matches_direct_autocorrelation(model):
    """sum_tau rho(tau)^2 of displacements and accelerations = the sum of the lagged
    covariances, R(0) = c P c^T + sigma^2 d^2 and R(tau) = c Phi^(tau-1) (Phi P c^T +
    sigma^2 Gamma d) for tau >= 1."""
    res = stationary_rms(model, 90.0, RHO, 300.0, correlation=True)
    assert res.correlation_samples.shape == (7,)
    a, b = model.matrices(90.0, RHO, 300.0)
    c_acc, d_acc = model.acceleration_output(a, b)
    phi, gam = zoh(a, b, DT)
    p = sl.solve_discrete_lyapunov(phi, SIGMA**2 * np.outer(gam, gam))
    rows = [(model.c_displacement[k], 0.0, k) for k in range(3)]
    rows += [(c_acc[k], d_acc[k], 4 + k) for k in range(3)]
    for c, d, col in rows:
        r0 = c @ p @ c + SIGMA**2 * d**2
        x = phi @ p @ c + SIGMA**2 * gam * d
        tail = 0.0
        for _ in range(40000):  # 40 s: the slowest mode has decayed by far more than 1e-10
            tail += (c @ x) ** 2
            x = phi @ x
        direct = (r0**2 + 2.0 * tail) / r0**2
        assert res.correlation_samples[col] == pytest.approx(direct, rel=1e-8)


def _simulate(model, speed, c2, flights, seconds, settle, seed):
    n_keep, n_skip = int(seconds / DT), int(settle / DT)
    force = SIGMA * np.random.default_rng(seed).standard_normal((flights, n_skip + n_keep))
    traces = simulate_flights(model.wing, model.absorber, force=force, airspeed=speed,
                              density=RHO, damping=c2, aero=model.aero, quantum=0.0)
    return traces.displacements[:, :, n_skip:], traces.accelerations[:, :, n_skip:]


def test_exact_rms_matches_long_simulation_within_sampling_error(model):
    """8 flights x 30 s at 90 m/s, c2 = 300 N s/m: every RMS within 3 standard errors."""
    speed, c2, flights, seconds = 90.0, 300.0, 8, 30.0
    exact = stationary_rms(model, speed, RHO, c2, correlation=True)
    settle = 5.0 / -exact.growth_rate  # the variance deficit from rest is below exp(-10)
    disp, acc = _simulate(model, speed, c2, flights, seconds, settle, seed=0)
    sim = np.sqrt(np.mean(disp**2, axis=(0, 2)))
    rse = exact.relative_standard_error(disp.shape[-1], flights)
    assert np.all(rse < 0.02)  # the test is sharp: a 2 % bias would show
    z = (sim[:3] - exact.displacement[:3]) / (exact.displacement[:3] * rse[:3])
    assert np.all(np.abs(z) < 3.0), z
    sim_acc = np.sqrt(np.mean(acc**2, axis=(0, 2)))
    rse_acc = exact.relative_standard_error(acc.shape[-1], flights, kind="acceleration")
    z_acc = (sim_acc - exact.acceleration) / (exact.acceleration * rse_acc)
    assert np.all(np.abs(z_acc) < 3.0), z_acc


def test_standard_error_formula_is_calibrated(model):
    """The stated relative standard error matches the spread of many independent RMS values."""
    speed, c2, flights, seconds = 85.0, 400.0, 300, 3.0
    exact = stationary_rms(model, speed, RHO, c2, correlation=True)
    disp, acc = _simulate(model, speed, c2, flights, seconds, 5.0 / -exact.growth_rate,
                          seed=5)
    for kind, data in (("displacement", disp[:, :3]), ("acceleration", acc)):
        rms = np.sqrt(np.mean(data**2, axis=2))  # (flights, 3)
        spread = rms.std(axis=0, ddof=1) / rms.mean(axis=0)
        predicted = exact.relative_standard_error(data.shape[-1], kind=kind)[:3]
        # the spread of 300 values is itself uncertain by ~ 1/sqrt(2 * 300) = 4 %
        np.testing.assert_allclose(spread, predicted, rtol=0.15)
