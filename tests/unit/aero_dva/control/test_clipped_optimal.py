"""The clipped-optimal law's design: the LQR of the ideal force, its schedule with the airspeed,
and the rows read between the schedule's airspeeds."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control.clipped_optimal import schedule_airspeeds, scheduled_law
from aero_dva.control.switching_design import desired_force_gain
from aero_dva.flight.per_sample.switching_law import SwitchingLaw, maxwell_index
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

U_CR = 100.0


@pytest.fixture(scope="module")
def model():
    cfg = load_wing(None)
    return AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)


@pytest.mark.parametrize("ratio", [0.8, 1.15, 1.3, 1.5])
def test_the_desired_force_stabilises_the_wing_even_beyond_its_flutter(model, ratio):
    """With the ideal force f_c = -K x in place of the Maxwell element the wing with its
    absorber mass is stable at every airspeed of the schedule, also far beyond the best
    constant c2's flutter (1.15 U_cr), where without the force it is not."""
    idx = maxwell_index(model)
    a, _ = model.matrices(ratio * U_CR, 1.2, 1000.0)
    keep = [i for i in range(a.shape[0]) if i != idx]
    a_s = a[np.ix_(keep, keep)]
    b_s = a[keep, idx][:, None] / model.absorber.series_stiffness
    k = desired_force_gain(model, ratio * U_CR, 1.2, effort=30.0)
    assert k[idx] == 0.0
    closed = np.linalg.eigvals(a_s - b_s @ k[keep][None, :])
    assert np.max(closed.real) < 0
    if ratio >= 1.3:  # the open wing with only the absorber's parallel spring flutters there
        assert np.max(np.linalg.eigvals(a_s).real) > 0


def test_more_effort_asks_for_less_force(model):
    small = desired_force_gain(model, 110.0, 1.2, effort=10.0)
    large = desired_force_gain(model, 110.0, 1.2, effort=1000.0)
    assert np.linalg.norm(large) < 0.5 * np.linalg.norm(small)


def test_rows_read_between_the_airspeeds_are_linear_and_held_beyond(model):
    law = scheduled_law(model, [90.0, 110.0, 130.0], 1.2, 100.0, 2500.0, effort=30.0,
                        lead=0.01)
    gain, force = law.rows_at([80.0, 90.0, 100.0, 125.0, 140.0])
    np.testing.assert_array_equal(gain[0], law.gain[0])  # held below the first airspeed
    np.testing.assert_array_equal(gain[1], law.gain[0])
    np.testing.assert_allclose(gain[2], 0.5 * (law.gain[0] + law.gain[1]), rtol=1e-15)
    np.testing.assert_allclose(gain[3], 0.25 * law.gain[1] + 0.75 * law.gain[2], rtol=1e-15)
    np.testing.assert_array_equal(gain[4], law.gain[2])  # held beyond the last
    np.testing.assert_allclose(force[2], 0.5 * (law.force_gain[0] + law.force_gain[1]))
    one = SwitchingLaw(law.gain[1], 100.0, 2500.0)
    rows, none = one.rows_at([80.0, 140.0])
    assert none is None and np.array_equal(rows, [law.gain[1], law.gain[1]])


def test_the_schedule_between_its_airspeeds_is_within_two_percent_of_the_exact_design(model):
    grid = schedule_airspeeds(U_CR)
    assert grid[0] <= 0.6 * U_CR and grid[-1] >= 1.6 * U_CR
    law = scheduled_law(model, grid, 1.2, 100.0, 2500.0, effort=30.0, lead=0.01)
    middle = 0.5 * (grid[1:] + grid[:-1])
    exact = scheduled_law(model, middle, 1.2, 100.0, 2500.0, effort=30.0, lead=0.01)
    gain, force = law.rows_at(middle)
    for read, true in ((gain, exact.gain), (force, exact.force_gain)):
        error = np.max(np.abs(read - true), axis=1) / np.max(np.abs(true), axis=1)
        assert error.max() < 0.02


def test_without_lead_the_damper_force_is_k2_delta_and_h_is_fc_minus_f(model):
    law = scheduled_law(model, [100.0, 120.0], 1.2, 100.0, 2500.0, effort=30.0)
    assert law.force_gain is None
    k2 = model.absorber.series_stiffness
    expected = -desired_force_gain(model, 100.0, 1.2, 30.0)
    expected[maxwell_index(model)] -= k2
    np.testing.assert_allclose(law.gain[0], expected / k2, rtol=1e-15)


@pytest.mark.parametrize("kwargs, message", [
    ({"airspeeds": [100.0]}, "at least 2"),
    ({"airspeeds": [100.0, 100.0]}, "increasing"),
    ({"airspeeds": None}, "a matrix needs airspeeds"),
    ({"airspeeds": [100.0, 110.0, 120.0]}, "one row per airspeed"),
])
def test_a_bad_schedule_is_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SwitchingLaw(np.ones((2, 7)), 100.0, 2500.0, **kwargs)
