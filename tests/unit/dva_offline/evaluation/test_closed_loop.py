"""Closed-loop flights in one process: the controllers' arithmetic, pairing, the oracle table."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.control.oracle import OptimalDampingTable
from aero_dva.control.rbf_network import InputScaling, RBFNetwork, spectrum_input_names
from aero_dva.flight.flight_runtime import load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, Scenario
from aero_dva.wing.model import AeroelasticModel
from dva_offline.evaluation.closed_loop import fly

from .controls import fixed_control, oracle_control, rbf_control, schedule_control

CONFIG = load_runtime_config({})
MODEL = AeroelasticModel(CONFIG.wing, CONFIG.absorber, CONFIG.aero)


def _config(duration=4.0, airspeed=("ramp", (85.0, 95.0)), density=1.2, mu=0.0, seed=3):
    scenario = Scenario("t", duration, block_size=50, airspeed=AirspeedProfile(*airspeed),
                        density=density, density_variation=mu, density_frequency=1.0,
                        seed=seed)
    return replace(CONFIG, scenario=scenario)


def test_fixed_command_acts_from_the_next_block_and_the_force_is_paired():
    config = _config()
    first = fly(config, fixed_control(300.0))
    second = fly(config, fixed_control(900.0))
    initial = CONFIG.damper.initial_damping
    assert np.all(first.damping[:50] == initial) and np.all(first.damping[50:] == 300.0)
    assert np.all(second.damping[50:] == 900.0)
    # the same seed: the same force, hence the same response up to the first command
    np.testing.assert_array_equal(first.leading_edge[:51], second.leading_edge[:51])
    assert not np.array_equal(first.leading_edge[-100:], second.leading_edge[-100:])
    assert first.samples == 4000 and not first.diverged


def test_schedule_commands_eq_7_1_of_the_blocks_airspeed():
    schedule = AirspeedSchedule(-1000.0, 15.0, (80.0, 120.0), (0.0, 2500.0))
    out = fly(_config(), schedule_control(schedule))
    # block k (samples 50 k ..) carries the command made from block k - 1's first airspeed
    for k in (1, 17, 79):
        expected = schedule.evaluate(out.airspeed[50 * (k - 1)])
        np.testing.assert_allclose(out.damping[50 * k:50 * (k + 1)], expected)


def test_oracle_table_holds_the_exact_optimum_and_interpolates():
    speeds, rho = np.array([80.0, 90.0, 100.0]), np.array([1.1, 1.3])
    table = OptimalDampingTable.build(MODEL, speeds, rho)
    exact = optimal_damping(MODEL, speeds, np.linspace(0, 2500, 126), 1.3).optimal_damping
    np.testing.assert_allclose(table.damping[:, 1], exact)
    assert table.stable.all()
    middle = table(85.0, 1.2)
    assert middle == pytest.approx(table.damping[:2].mean(), rel=1e-12)  # bilinear
    # an airspeed with no stable c2 gets the most stable one, not NaN
    unstable = OptimalDampingTable.build(MODEL, np.array([100.0, 130.0]), np.array([1.2]))
    assert not unstable.stable[1, 0] and np.isfinite(unstable.damping[1, 0])


def test_oracle_commands_the_optimum_of_the_true_next_condition():
    table = OptimalDampingTable.build(MODEL, np.arange(84.0, 97.0, 1.0),
                                      np.array([1.05, 1.2, 1.35]))
    out = fly(_config(mu=0.1), oracle_control(table))
    k = 40  # block 40 acts at samples 2000..2049; its command used the block's middle
    t = (50 * k + 25) / 1000.0
    u = 85.0 + 10.0 * t / 4.0
    rho = 1.2 * (1 + 0.1 * np.sin(2 * np.pi * t))
    np.testing.assert_allclose(out.damping[50 * k:50 * (k + 1)], table(u, rho), rtol=1e-9)


def _network(weight: float) -> RBFNetwork:
    """One neuron on the c2 input only: output = 500 + weight * a(c2)."""
    names, units = spectrum_input_names()
    scale = np.ones(33)
    scale[:32] = 1e9  # the spectra do not move the neuron
    centre = np.zeros((1, 33))
    centre[0, 32] = 500.0 / 400.0
    return RBFNetwork(centres=centre, output_weights=np.array([weight]), output_bias=500.0,
                      spread=1.0, scaling=InputScaling(np.zeros(33), np.r_[scale[:32], 400.0]),
                      input_names=names, input_units=units)


def test_spectrum_rbf_control_answers_every_window_with_the_network():
    network = _network(100.0)
    control = rbf_control(network)
    out = fly(_config(duration=3.0, airspeed=("constant", (90.0,))), control)
    initial = CONFIG.damper.initial_damping
    # no command before the first 2 s window is complete (after block 39), then one per
    # 0.1 s hop: windows end at 2.0, 2.1, .. 3.0 s
    assert np.all(out.damping[:2000] == initial)
    assert len(control.peak_activation) == 11
    # the first window: the network of its spectra and its mean c2 (all the initial c2)
    expected = network.predict(np.append(np.full(32, 1 / 16), initial))
    assert expected == pytest.approx(600.0)  # the neuron sits at c2 = 500
    np.testing.assert_allclose(out.damping[2000:2100], expected, rtol=1e-12)
    clamped = fly(_config(duration=2.2, airspeed=("constant", (90.0,))),
                  rbf_control(_network(1e5), damping_range=(0.0, 2500.0)))
    assert clamped.damping[-1] == 2500.0


def test_a_diverging_flight_stops():
    out = fly(_config(duration=30.0, airspeed=("constant", (130.0,))), fixed_control(600.0))
    assert out.diverged and out.samples < 30000
    assert np.abs(out.leading_edge[-50:]).max() > 0.5 * CONFIG.wing.chord
