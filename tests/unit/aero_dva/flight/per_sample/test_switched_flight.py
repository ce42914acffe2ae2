"""The per-sample switched flight against a plain reference loop, the physics it claims, and
its observer and lag."""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from scipy import linalg

from aero_dva.control.switching_design import kalman_filter_gain, law_gain, measured_rms
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.flight.kept import KeptByKey
from aero_dva.flight.peak_limit import peak_limit_airspeed
from aero_dva.flight.per_sample.flight import c2_levels, fly_switched
from aero_dva.flight.per_sample.switching_law import (
    SwitchingLaw,
    maxwell_index,
    measurement_matrices,
)
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

U_CR = 100.0  # [m/s] the chapter-6 wing's bare critical airspeed
C_LO, C_HI = 100.0, 2500.0


@pytest.fixture(scope="module")
def wing():
    cfg = load_wing(None)
    return cfg, AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)


def reference_flight(model, law, speed, rho, force, noise, tau, dt=1e-3, observer_model=None,
                     yield_force=0.0):
    """The law written out sample by sample with scipy's expm: continuous lag, c2 rounded to
    the table in log c2, filtered estimate from the measurements, decision acting one sample
    later. ``speed`` per sample (an array) is held every 10 samples at the period's first
    (a ramp steep enough to pass the hold's quantum every period), and a scheduled law's rows
    are read there."""
    speeds = np.broadcast_to(np.asarray(speed, dtype=float), (len(force),))
    n = model.n_states
    obs_model = model if observer_model is None else observer_model
    table = c2_levels(law.c_lo, law.c_hi, tau)
    idx = maxwell_index(model)
    k2 = model.absorber.series_stiffness
    x, pred = np.zeros(n), np.zeros(n)
    c, target_hi, decision = law.c_hi, True, True
    les, damping = [], []
    for i, f in enumerate(force):
        speed = speeds[i - i % 10]
        gain, force_gain = law.rows_at(speed)
        target_hi = decision if i else True
        target = law.c_hi if target_hi else law.c_lo
        if tau > 0:
            decay = math.exp(-dt / tau)
            mean = target + (c - target) * tau / dt * (1 - decay)
            c = target + (c - target) * decay
            level = table[np.argmin(np.abs(np.log(table) - math.log(mean)))]
        else:
            level = target
        a, b = model.matrices(speed, rho, level)
        cm, dm = measurement_matrices(model, speed, rho, level)
        y = cm @ x + dm * f + noise[i]
        cm_obs = measurement_matrices(obs_model, speed, rho, level)[0]
        est = x if law.observer is None else pred + law.observer @ (y - cm_obs @ pred)
        damper_force = k2 * est[idx] if force_gain is None else force_gain[0] @ est
        decision = damper_force * (gain[0] @ est) > 0
        # A Bingham damper: locked (c2 = inf) at most at the yield force, else the linear
        # damper plus the yield force's offset on the deflection rate
        spring = k2 * x[idx]
        offset = 0.0
        if yield_force and abs(spring) <= yield_force:
            a, b = model.matrices(speed, rho, math.inf)
        elif yield_force:
            offset = yield_force / level * math.copysign(1.0, spring)
        aug = np.zeros((n + 2, n + 2))
        aug[:n, :n], aug[:n, n], aug[idx, n + 1] = a * dt, b * dt, dt
        e = linalg.expm(aug)
        les.append(model.c_displacement[2] @ x)
        damping.append(level)
        x = e[:n, :n] @ x + e[:n, n] * f + e[:n, n + 1] * offset
        aug[:n, :n] = obs_model.matrices(speed, rho, level)[0] * dt
        pred = linalg.expm(aug)[:n, :n] @ est
    return np.array(les), np.array(damping)


@pytest.mark.parametrize("tau, with_observer, mismatch, yield_force",
                         [(0.0, False, False, 0.0), (0.01, True, False, 0.0),
                          (0.01, True, True, 0.0), (0.01, True, False, 30.0)])
def test_matches_a_plain_sample_by_sample_loop(wing, tau, with_observer, mismatch, yield_force):
    cfg, model = wing
    observer_model = model
    if mismatch:  # the flown plant 5 % stiffer in plunge than the observer's model
        observer_model = model
        model = AeroelasticModel(dataclasses.replace(
            cfg.wing, plunge_stiffness=1.05 * cfg.wing.plunge_stiffness), cfg.absorber, cfg.aero)
    speed, rho = 1.15 * U_CR, cfg.air_density
    gain = law_gain(observer_model, speed, rho, C_LO, C_HI)
    scale = measured_rms(observer_model, U_CR, rho, 624.7, 1000.0, 1000.0)
    observer = kalman_filter_gain(observer_model, speed, rho, 500.0, 1000.0, 1000.0,
                                  0.05 * scale) \
        if with_observer else None
    law = SwitchingLaw(gain, C_LO, C_HI, observer)
    rng = np.random.default_rng(3)
    force = rng.normal(0, 1000.0, 400)
    noise = rng.normal(0, 1.0, (400, 4)) * 0.05 * scale
    flight = fly_switched(model, law, speed, rho, force, time_constant=tau,
                          noise=noise if with_observer else None,
                          observer_model=observer_model if mismatch else None,
                          yield_force=yield_force)
    le, damping = reference_flight(model, law, speed, rho, force,
                                   noise if with_observer else np.zeros((400, 4)), tau,
                                   observer_model=observer_model, yield_force=yield_force)
    np.testing.assert_allclose(flight.damping, damping, rtol=1e-12)
    np.testing.assert_allclose(flight.leading_edge, le, rtol=1e-7,
                               atol=1e-9 * np.max(np.abs(le)))
    assert 0 < np.count_nonzero(np.diff(flight.target)) < 399  # it did switch


def test_a_law_scheduled_with_the_airspeed_reads_its_rows_at_the_held_airspeed(wing):
    """The clipped-optimal law's rows, read between its airspeeds at each held airspeed of a
    ramp, with its lead (a force row of its own), observer and lag: as the plain loop."""
    from aero_dva.control.clipped_optimal import scheduled_law

    cfg, model = wing
    rho = cfg.air_density
    scale = measured_rms(model, U_CR, rho, 624.7, 1000.0, 1000.0)
    observer = kalman_filter_gain(model, 115.0, rho, 500.0, 1000.0, 1000.0, 0.05 * scale)
    law = scheduled_law(model, [90.0, 110.0, 130.0, 150.0], rho, C_LO, C_HI, effort=30.0,
                        lead=0.01, observer=observer)
    rng = np.random.default_rng(4)
    force = rng.normal(0, 1000.0, 400)
    noise = rng.normal(0, 1.0, (400, 4)) * 0.05 * scale
    speed = np.linspace(100.0, 140.0, 400, endpoint=False)  # 1 m/s per hold period
    flight = fly_switched(model, law, speed, rho, force, time_constant=0.01, noise=noise)
    le, damping = reference_flight(model, law, speed, rho, force, noise, 0.01)
    np.testing.assert_allclose(flight.damping, damping, rtol=1e-12)
    np.testing.assert_allclose(flight.leading_edge, le, rtol=1e-7,
                               atol=1e-9 * np.max(np.abs(le)))
    assert 0 < np.count_nonzero(np.diff(flight.target)) < 399
    # the rows do change along the ramp: read at one airspeed, the law decides otherwise
    gain, force_gain = law.rows_at(105.0)
    fixed_rows = SwitchingLaw(gain[0], C_LO, C_HI, observer, force_gain[0])
    other = fly_switched(model, fixed_rows, speed, rho, force, time_constant=0.01, noise=noise)
    assert np.any(other.target != flight.target)


def test_a_law_that_never_switches_is_the_held_c2_flight(wing):
    cfg, model = wing
    force = np.random.default_rng(0).normal(0, 1000.0, 3000)
    law = SwitchingLaw(np.zeros(model.n_states), 624.7, 624.7 * (1 + 1e-9))
    flight = fly_switched(model, law, 105.0, cfg.air_density, force, time_constant=0.0,
                          initial_damping=624.7)
    held = simulate_flights(cfg.wing, cfg.absorber, force=force, airspeed=105.0,
                            density=cfg.air_density, damping=624.7)
    le = held.displacements[0, 2]
    assert np.all(flight.damping == 624.7)
    np.testing.assert_allclose(flight.leading_edge, le, rtol=1e-6, atol=1e-9 * np.abs(le).max())


def test_a_batch_flies_each_flight_as_alone(wing):
    cfg, model = wing
    law = SwitchingLaw(law_gain(model, 115.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    force = np.random.default_rng(1).normal(0, 1000.0, (3, 2000))
    speed = np.linspace(110.0, 120.0, 2000)
    batch = fly_switched(model, law, speed, 1.2, force)
    for j in range(3):
        one = fly_switched(model, law, speed, 1.2, force[j])
        np.testing.assert_allclose(batch.leading_edge[j], one.leading_edge, rtol=1e-9,
                                   atol=1e-12)
        assert np.array_equal(batch.target[j], one.target)


def test_lagged_c2_stays_within_the_table_spacing_of_the_true_lag(wing):
    cfg, model = wing
    law = SwitchingLaw(law_gain(model, 115.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    force = np.random.default_rng(2).normal(0, 1000.0, 3000)
    flight = fly_switched(model, law, 115.0, 1.2, force, time_constant=0.01)
    c, decay, means = C_HI, math.exp(-0.1), []
    for hi in flight.target:
        t = C_HI if hi else C_LO
        means.append(t + (c - t) * 10 * (1 - decay))
        c = t + (c - t) * decay
    ratio = flight.damping / np.array(means)
    half_step = math.exp(math.log(C_HI / C_LO) / (len(c2_levels(C_LO, C_HI, 0.01)) - 1) / 2)
    assert np.all(ratio <= half_step * (1 + 1e-12))
    assert np.all(ratio >= 1 / half_step * (1 - 1e-12))
    assert len(np.unique(flight.damping)) > 10  # c2 really moved through the table


def test_switching_keeps_bounded_where_the_best_constant_c2_flutters(wing):
    # 1.18 U_cr is above the best constant c2's flutter airspeed (1.1505 U_cr, docs).
    cfg, model = wing
    speed = 1.18 * U_CR
    force = np.random.default_rng(4).normal(0, 1000.0, 12000)
    fixed = fly_switched(model, SwitchingLaw(np.zeros(7), 624.7, 624.71), speed, 1.2, force,
                         time_constant=0.0, initial_damping=624.7)
    law = SwitchingLaw(law_gain(model, 1.15 * U_CR, 1.2, C_LO, C_HI), C_LO, C_HI)
    switched = fly_switched(model, law, speed, 1.2, force, time_constant=0.0)

    def rms(x, a, b):
        return np.sqrt(np.mean(x[a:b] ** 2))

    assert rms(fixed.leading_edge, 10000, 12000) > 10 * rms(fixed.leading_edge, 1000, 3000)
    assert rms(switched.leading_edge, 10000, 12000) < 2 * rms(switched.leading_edge, 1000, 3000)
    assert switched.switches_per_second > 10
    assert switched.dissipated() > 0


def test_bad_inputs_are_refused(wing):
    _, model = wing
    with pytest.raises(ValueError, match="c_lo < c_hi"):
        SwitchingLaw(np.zeros(7), 500.0, 100.0)
    with pytest.raises(ValueError, match="observer"):
        SwitchingLaw(np.zeros(7), 100.0, 500.0, np.zeros((7, 3)))
    law = SwitchingLaw(np.zeros(6), 100.0, 500.0)
    with pytest.raises(ValueError, match="gain has 6 entries"):
        fly_switched(model, law, 100.0, 1.2, np.zeros(10))
    law = SwitchingLaw(np.zeros(7), 100.0, 500.0)
    with pytest.raises(ValueError, match="airspeed"):
        fly_switched(model, law, np.nan, 1.2, np.zeros(10))
    with pytest.raises(ValueError, match="time_constant"):
        fly_switched(model, law, 100.0, 1.2, np.zeros(10), time_constant=-1.0)
    with pytest.raises(ValueError, match="force must be finite"):
        fly_switched(model, law, 100.0, 1.2, np.zeros(0))


def test_peak_limit_airspeed():
    speed = np.linspace(80.0, 120.0, 5)
    response = np.array([[0.1, -0.2, 3.0, 0.1, 0.1], [0.1, 0.1, 0.1, 0.1, 0.1]])
    out = peak_limit_airspeed(speed, response, 1.0)
    assert out[0] == 100.0 and np.isnan(out[1])
    assert peak_limit_airspeed(speed, [0, 0, np.inf, 0, 0], 1.0) == 100.0


def test_relief_valve_drops_c2_while_the_force_is_above_its_limit(wing):
    cfg, model = wing
    law = SwitchingLaw(law_gain(model, 115.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    force = np.random.default_rng(6).normal(0, 1000.0, 4000)
    free = fly_switched(model, law, 110.0, 1.2, force, time_constant=0.01)
    free_force = np.sqrt(free.damper_power * free.damping)
    limit = np.quantile(free_force, 0.9)
    assert np.any((free_force > limit) & (free.damping > C_LO * 1.01))  # the valve has work
    valve = fly_switched(model, law, 110.0, 1.2, force, time_constant=0.01, force_limit=limit)
    valve_force = np.sqrt(valve.damper_power * valve.damping)
    over = valve_force > limit
    assert np.any(over)
    np.testing.assert_allclose(valve.damping[over], C_LO)
    with pytest.raises(ValueError, match="force_limit"):
        fly_switched(model, law, 110.0, 1.2, force, force_limit=0.0)


def test_a_slower_loop_changes_its_target_only_at_block_starts(wing):
    _, model = wing
    law = SwitchingLaw(law_gain(model, 115.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    force = np.random.default_rng(7).normal(0, 1000.0, (2, 3000))
    flight = fly_switched(model, law, 110.0, 1.2, force, update_every=20)
    for targets in flight.target:
        changes = np.flatnonzero(np.diff(targets)) + 1
        assert changes.size > 5 and np.all(changes % 20 == 0)
    with pytest.raises(ValueError, match="update_every"):
        fly_switched(model, law, 110.0, 1.2, force, update_every=0)


def test_interpolated_steps_match_the_exact_steps_of_every_condition_and_level(wing):
    # A ramp's held airspeeds and the 65-level table, interpolated from Chebyshev nodes in
    # airspeed and in k2 / c2, against the exact ZOH steps at a sample of conditions.
    from aero_dva.flight.per_sample.flight import _steps
    from aero_dva.flight.per_sample.smooth_tables import SPEED_NODES, interpolated_maps

    cfg, model = wing
    stiffer = dataclasses.replace(cfg.wing, plunge_stiffness=1.05 * cfg.wing.plunge_stiffness)
    other = AeroelasticModel(stiffer, cfg.absorber, cfg.aero)
    table = c2_levels(C_LO, C_HI, 0.01)
    speeds = np.linspace(80.0, 140.0, 301)
    keys = np.column_stack([speeds, np.full(speeds.size, 1.2)])
    for observer_model in (model, other):
        def build(cond, lev, observer_model=observer_model):
            return _steps(model, observer_model, cond, lev, 1e-3)
        base, index, weight = interpolated_maps(build, keys, table,
                                                model.absorber.series_stiffness)
        assert base.shape[0] == SPEED_NODES  # built at the nodes, not at 301 airspeeds
        check = np.arange(0, 301, 37)
        exact = build(keys[check], table)
        formed = np.einsum("qj,qjls->qls", weight[check], base[index[check]])
        assert np.abs(formed - exact).max() <= 1e-12 * np.abs(exact).max()


def test_a_yield_force_above_every_force_locks_the_damper(wing):
    # A Bingham damper that never yields is a locked damper: the wing flies as with c2 = inf.
    from aero_dva.flight.streaming_simulator import StreamingSimulator

    cfg, model = wing
    force = np.random.default_rng(8).normal(0, 1000.0, 2000)
    law = SwitchingLaw(law_gain(model, 100.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    flight = fly_switched(model, law, 100.0, 1.2, force, yield_force=1e9)
    sim = StreamingSimulator(cfg.wing, cfg.absorber, quantum=2e-3)
    locked = sim.advance(force, 100.0, 1.2, math.inf).displacements[2]
    np.testing.assert_allclose(flight.leading_edge, locked, rtol=1e-6,
                               atol=1e-9 * np.abs(locked).max())
    assert np.all(flight.damper_power == 0.0)  # a locked damper dissipates nothing


@pytest.mark.parametrize("case", ["observer", "other observer model", "true state",
                                  "yield and valve", "slow loop, no lag"])
def test_the_fixed_size_loop_equals_the_general_loop_to_the_bit(wing, monkeypatch, case):
    # The wing with its Maxwell DVA flies per_sample.kernel._fly_fixed; with FIXED_STATES
    # unmatched the same flight takes _fly_general. Same sums in the same order: equal.
    from aero_dva.flight.per_sample import flight as switched_flight
    from aero_dva.flight.per_sample import kernel as switched_kernel

    cfg, model = wing
    stiffer = dataclasses.replace(cfg.wing, plunge_stiffness=1.05 * cfg.wing.plunge_stiffness)
    other = AeroelasticModel(stiffer, cfg.absorber, cfg.aero)
    rng = np.random.default_rng(11)
    speed = np.linspace(90.0, 120.0, 3000)
    force = rng.normal(0, 1000.0, (2, speed.size))
    scale = measured_rms(model, U_CR, 1.2, 624.7, 1000.0, 1000.0)
    noise = rng.normal(0, 1.0, (speed.size, 4)) * 0.05 * scale
    observer = kalman_filter_gain(model, 110.0, 1.2, 500.0, 1000.0, 1000.0, 0.05 * scale)
    gain = law_gain(model, 115.0, 1.2, C_LO, C_HI)
    kw = dict(time_constant=0.01)
    if case == "true state":
        law = SwitchingLaw(gain, C_LO, C_HI)
    else:
        law = SwitchingLaw(gain, C_LO, C_HI, observer)
        kw["noise"] = noise
    if case == "other observer model":
        kw["observer_model"] = other
    if case == "yield and valve":
        kw.update(yield_force=300.0, force_limit=3000.0)
    if case == "slow loop, no lag":
        kw.update(time_constant=0.0, update_every=7)
    fixed = fly_switched(model, law, speed, 1.2, force, **kw)
    kept = switched_flight._kept.latest()
    assert kept[-1] is not None and kept[-1].whole.shape[0] > 0  # every level formed
    monkeypatch.setattr(switched_kernel, "FIXED_STATES", -1)
    monkeypatch.setattr(switched_flight, "_kept", KeptByKey(2))  # maps built afresh
    general = fly_switched(model, law, speed, 1.2, force, **kw)
    assert switched_flight._kept.latest()[-1] is None  # the general loop
    # and the fixed loop forming each level as it is flown (as the streaming flight does)
    monkeypatch.setattr(switched_kernel, "FIXED_STATES", 7)
    monkeypatch.setattr(switched_flight, "_kept", KeptByKey(2))
    monkeypatch.setattr(switched_kernel, "fixed_maps",
                        functools.partial(switched_kernel.fixed_maps, whole=False))
    as_flown = fly_switched(model, law, speed, 1.2, force, **kw)
    assert switched_flight._kept.latest()[-1].whole.shape[0] == 0
    for name in ("leading_edge", "stroke", "damping", "target", "damper_power"):
        np.testing.assert_array_equal(getattr(fixed, name), getattr(general, name), name)
        np.testing.assert_array_equal(getattr(fixed, name), getattr(as_flown, name), name)
    assert np.count_nonzero(np.diff(fixed.target, axis=1)) > 50  # the law did switch
    if case == "yield and valve":
        assert np.any(fixed.damper_power == 0.0) and np.any(fixed.damping == C_LO)


def test_a_repeated_flight_reuses_its_maps_and_another_law_or_wing_does_not(wing):
    from aero_dva.flight.per_sample import flight as switched_flight

    cfg, model = wing
    force = np.random.default_rng(12).normal(0, 1000.0, 3000)
    speed = np.linspace(95.0, 110.0, 3000)
    law = SwitchingLaw(law_gain(model, 115.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    first = fly_switched(model, law, speed, 1.2, force)
    kept = switched_flight._kept.latest()
    again = fly_switched(model, law, speed, 1.2, force)
    assert switched_flight._kept.latest()[0] is kept[0]  # reused
    np.testing.assert_array_equal(again.leading_edge, first.leading_edge)
    # another gain (not a multiple: F h > 0 does not see a positive factor) and a stiffer
    # wing each get maps of their own, equal to a fresh build
    other_law = SwitchingLaw(law_gain(model, 100.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    stiffer = AeroelasticModel(dataclasses.replace(
        cfg.wing, plunge_stiffness=1.05 * cfg.wing.plunge_stiffness), cfg.absorber, cfg.aero)
    for m, lw in ((model, other_law), (stiffer, law)):
        got = fly_switched(m, lw, speed, 1.2, force)
        assert switched_flight._kept.latest()[0] is not kept[0]
        switched_flight._kept.clear()
        fresh = fly_switched(m, lw, speed, 1.2, force)
        np.testing.assert_array_equal(got.leading_edge, fresh.leading_edge)
        assert not np.array_equal(got.leading_edge, first.leading_edge)
