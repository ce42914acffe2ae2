"""The streaming and batch simulators of the sampled wing against scipy, each other and per-sample
references (exact ZOH, Zhang (2006) eq. 6.7-6.9)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import cont2discrete, dlsim

from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.model import AeroelasticModel, WingParameters

WING = WingParameters(mass=1000.0, inertia=650.0, plunge_stiffness=4.8e6, pitch_stiffness=2.0e6,
                      damping_factor=2e-4, chord=1.9, gravity_centre=1.53, elastic_axis=0.8,
                      aileron_position=-0.3, lift_slope=5.5, span=90.0)
DVA = MaxwellAbsorber(40.0, 9.0e4, 7.0e4, 500.0, 1.53)


def _dlsim_outputs(model, u, rho, force, dt=1e-3):
    ss = model.state_space(u, rho)
    c = np.vstack([ss.c_displacement, ss.c_acceleration])
    d = np.r_[np.zeros(4), ss.d_acceleration][:, None]
    _, y, _ = dlsim(cont2discrete((ss.a, ss.b[:, None], c, d), dt, "zoh"), force)
    return y.T


@pytest.mark.parametrize("aero", [None, WagnerAero()])
def test_constant_condition_equals_scipy_dlsim(aero):
    rng = np.random.default_rng(2)
    force = 1000.0 * rng.standard_normal(2003)
    ref = _dlsim_outputs(AeroelasticModel(WING, DVA, aero), 70.0, 1.2, force)
    out = StreamingSimulator(WING, DVA, aero=aero).advance(force, 70.0, 1.2)
    got = np.vstack([out.displacements, out.accelerations])
    scale = np.abs(ref).max(axis=1, keepdims=True)
    np.testing.assert_allclose(got / scale, ref / scale, atol=1e-11)
    batch = simulate_flights(WING, DVA, force=force, airspeed=70.0, density=1.2, aero=aero)
    np.testing.assert_allclose(batch.displacements[0], out.displacements, rtol=0,
                               atol=1e-12 * np.abs(out.displacements).max())


def _reference_loop(model, force, u, rho, c, hold, dt=1e-3):
    """Per-sample loop with scipy's expm: parameters sampled every ``hold`` samples."""
    n = model.n_states
    y = np.zeros(n)
    disp = []
    for i, f in enumerate(force):
        if i % hold == 0:
            a, b = model.matrices(u[i], rho[i], c[i])
            big = np.zeros((n + 1, n + 1))
            big[:n, :n], big[:n, n] = a * dt, b * dt
            e = expm(big)
            phi, gam = e[:n, :n], e[:n, n]
        disp.append(model.c_displacement @ y)
        y = phi @ y + gam * f
    return np.array(disp).T


def test_time_varying_flight_equals_a_per_sample_reference():
    rng = np.random.default_rng(3)
    n = 437
    force = 1000.0 * rng.standard_normal(n)
    u = np.linspace(60.0, 95.0, n)
    rho = 1.2 * (1 + 0.1 * np.sin(np.linspace(0, 6, n)))
    c = np.linspace(50.0, 2500.0, n)
    model = AeroelasticModel(WING, DVA)
    ref = _reference_loop(model, force, u, rho, c, hold=7)
    out = StreamingSimulator(WING, DVA, hold=7).advance(force, u, rho, c)
    np.testing.assert_allclose(out.displacements, ref, rtol=0, atol=1e-11 * np.abs(ref).max())


def test_streaming_does_not_depend_on_how_the_flight_is_cut():
    rng = np.random.default_rng(4)
    n = 3000
    force = 1000.0 * rng.standard_normal(n)
    u = np.linspace(60.0, 95.0, n)
    c = np.linspace(100.0, 2000.0, n)
    sim = StreamingSimulator(WING, DVA, quantum=2e-3)
    whole = sim.advance(force, u, 1.2, c)
    sim.reset()
    parts, i = [], 0
    while i < n:
        step = int(rng.integers(1, 37))
        blk = sim.advance(force[i:i + step], u[i:i + step], 1.2, c[i:i + step])
        np.testing.assert_allclose(blk.time, np.arange(i, min(i + step, n)) / 1000.0)
        parts.append(np.vstack([blk.displacements, blk.accelerations]))
        i += step
    np.testing.assert_allclose(np.hstack(parts), np.vstack([whole.displacements,
                                                            whole.accelerations]),
                               rtol=0, atol=1e-12 * np.abs(whole.accelerations).max())
    assert sim.sample_index == n
    np.testing.assert_allclose(sim.state, sim.state)  # a copy, usable
    batch = simulate_flights(WING, DVA, force=np.vstack([force, force]), airspeed=u,
                             density=1.2, damping=c)
    np.testing.assert_allclose(batch.accelerations[1], whole.accelerations, rtol=0,
                               atol=1e-12 * np.abs(whole.accelerations).max())


def test_batch_flights_with_different_schedules_equal_single_flights():
    rng = np.random.default_rng(5)
    n = 1200
    force = 1000.0 * rng.standard_normal((3, n))
    u = np.vstack([np.linspace(60, 90, n), np.linspace(70, 80, n), np.full(n, 50.0)])
    batch = simulate_flights(WING, PassiveAbsorber(40, 9e4, 800, 1.0), force=force,
                             airspeed=u, density=1.2, quantum=0.0)
    for i in range(3):
        one = simulate_flights(WING, PassiveAbsorber(40, 9e4, 800, 1.0), force=force[i],
                               airspeed=u[i], density=1.2, quantum=0.0)
        np.testing.assert_allclose(batch.displacements[i], one.displacements[0], rtol=0,
                                   atol=1e-12 * np.abs(one.displacements).max())
    np.testing.assert_array_equal(batch.airspeed[2], 50.0)


def test_many_flights_on_one_schedule_equal_single_flights():
    # Eight or more flights sharing a schedule take the whole-period products (period maps in
    # sample-major order, written in place); one flight steps its periods instead.
    rng = np.random.default_rng(8)
    n = 2400
    force = 1000.0 * rng.standard_normal((9, n))
    u = np.linspace(60.0, 95.0, n)
    c = np.interp(u, [60.0, 95.0], [1500.0, 200.0])
    batch = simulate_flights(WING, DVA, force=force, airspeed=u, density=1.2, damping=c)
    assert batch.displacements.shape == (9, 4, n) and batch.accelerations.shape == (9, 3, n)
    for i in (0, 4, 8):
        one = simulate_flights(WING, DVA, force=force[i], airspeed=u, density=1.2, damping=c)
        for got, ref in ((batch.displacements[i], one.displacements[0]),
                         (batch.accelerations[i], one.accelerations[0])):
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(batch.state[i], one.state[0], rtol=0,
                                   atol=1e-12 * np.abs(one.state).max())
    np.testing.assert_array_equal(batch.damping[3], one.damping[0])  # same held schedule


def test_reset_and_initial_state():
    sim = StreamingSimulator(WING, DVA)
    x0 = np.zeros(sim.n_states)
    x0[1] = 0.01  # 10 mrad pitch, free decay
    sim.reset(x0)
    out = sim.advance(np.zeros(200), 50.0, 1.2)
    assert out.displacements[1, 0] == pytest.approx(0.01)
    assert abs(out.displacements[1, -1]) < 0.01
    sim.reset()
    assert np.all(sim.state == 0) and sim.sample_index == 0
    with pytest.raises(ValueError, match="x0"):
        sim.reset(np.zeros(3))


def test_divergence_flag_beyond_the_limit():
    sim = StreamingSimulator(WING, None, divergence_limit=1e-3)
    assert not sim.advance(np.zeros(10), 50.0, 1.2).diverged
    out = sim.advance(np.full(2000, 5e5), 50.0, 1.2)
    assert out.diverged and sim.diverged
    assert sim.advance(np.zeros(10), 50.0, 1.2).diverged  # sticky until reset
    sim.reset()
    assert not sim.diverged


@pytest.mark.parametrize("kwargs,match", [
    (dict(force=np.zeros((2, 3))), "force"),
    (dict(force=[0.0, float("nan")]), "force"),
    (dict(airspeed=-5.0), "airspeed"),
    (dict(airspeed=np.ones(4)), "airspeed"),
    (dict(density=float("inf")), "density"),
    (dict(damping=-1.0), "damping"),
])
def test_bad_advance_inputs_are_named(kwargs, match):
    args = dict(force=np.zeros(3), airspeed=50.0, density=1.2, damping=None)
    with pytest.raises((ValueError, TypeError), match=match):
        StreamingSimulator(WING, DVA).advance(**{**args, **kwargs})


@pytest.mark.parametrize("block", [50, 37])
def test_streaming_blocks_equal_the_batch_path_on_a_ramp_with_varying_c2(block):
    # The simulator node's use: one flight in short blocks, hold 10, quantum 1e-3, a new c2
    # every 50 samples (as commanded), density varying; 37-sample blocks cut hold periods.
    rng = np.random.default_rng(7)
    n = 4000
    force = 1000.0 * rng.standard_normal(n)
    u = np.linspace(60.0, 95.0, n)
    rho = 1.2 * (1 + 0.05 * np.sin(np.linspace(0.0, 8.0, n)))
    c = np.repeat(np.linspace(100.0, 2000.0, n // 50), 50)
    batch = simulate_flights(WING, DVA, force=force, airspeed=u, density=rho, damping=c,
                             quantum=1e-3)
    sim = StreamingSimulator(WING, DVA, quantum=1e-3)
    parts = [sim.advance(force[i:i + block], u[i:i + block], rho[i:i + block], c[i:i + block])
             for i in range(0, n, block)]
    assert sim.discrete.cached  # the short calls took the streaming path
    got = np.hstack([np.vstack([p.displacements, p.accelerations]) for p in parts])
    ref = np.vstack([batch.displacements[0], batch.accelerations[0]])
    scale = np.abs(ref).max(axis=1, keepdims=True)
    np.testing.assert_allclose(got / scale, ref / scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sim.state, batch.state[0], rtol=0,
                               atol=1e-12 * np.abs(batch.state).max())


@pytest.mark.parametrize("block", [50, 37])
def test_the_compiled_route_flies_the_numpy_route_to_rounding_however_it_is_cut(block):
    """The simulator node's compiled route: the same flight as the NumPy route within
    rounding, and bit for bit the same whether flown in blocks of 50, 37 or one call of short
    calls (each sample takes its period's condition, whatever the cut)."""
    rng = np.random.default_rng(8)
    n = 3000
    force = 1000.0 * rng.standard_normal(n)
    u = np.linspace(60.0, 95.0, n)
    rho = 1.2 * (1 + 0.05 * np.sin(np.linspace(0.0, 8.0, n)))
    c = np.repeat(np.linspace(100.0, 2000.0, n // 50), 50)

    def fly(compiled, step):
        sim = StreamingSimulator(WING, DVA, quantum=1e-3, compiled=compiled)
        sim.prepare(u[0], rho[0], c[0])
        parts = [sim.advance(force[i:i + step], u[i:i + step], rho[i:i + step], c[i:i + step])
                 for i in range(0, n, step)]
        return np.hstack([np.vstack([p.displacements, p.accelerations]) for p in parts]), sim

    ref, numpy_sim = fly(False, block)
    got, sim = fly(True, block)
    assert sim.compiled and not numpy_sim.compiled
    scale = np.abs(ref).max(axis=1, keepdims=True)
    np.testing.assert_allclose(got / scale, ref / scale, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(fly(True, 50)[0], got)
    np.testing.assert_allclose(sim.state, numpy_sim.state, rtol=0,
                               atol=1e-11 * np.abs(numpy_sim.state).max())


def test_models_the_compiled_loop_does_not_take_step_in_numpy():
    sim = StreamingSimulator(WING, DVA, aero=WagnerAero(), compiled=True)
    assert not sim.compiled  # the Wagner lag's states do not fit the stacked maps
    sim.prepare(70.0, 1.2)  # nothing to load
    out = sim.advance(np.ones(20), 70.0, 1.2)
    assert out.displacements.shape == (4, 20)
