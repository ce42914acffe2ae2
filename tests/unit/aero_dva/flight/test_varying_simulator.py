"""The wing along a log whose c2 changes every sample (a linear time-varying system): the
interpolated steps against a plain sample-by-sample matrix exponential, and the refusals."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from aero_dva.flight.discrete_model import DiscreteWing
from aero_dva.flight.per_sample.switching_law import maxwell_index
from aero_dva.flight.varying_simulator import VaryingSteps, simulate_varying, transitions
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

FS = 1000.0
OUTPUTS = ("plunge_acceleration", "pitch_acceleration")
WING = load_wing(None)
MODEL = AeroelasticModel(WING.wing, WING.maxwell_design, WING.aero)
K2 = WING.maxwell_design.series_stiffness
ROWS = DiscreteWing.output_index(OUTPUTS)


def build(rows):
    u, rho = rows[:, 0], rows[:, 1]
    a, b = MODEL.matrices(u, rho, np.full(u.size, np.inf))
    c, d = DiscreteWing(MODEL, FS).output_matrices(a, b)
    return a, b, c[:, ROWS], d[:, ROWS]


def reference(conditions, condition, c2, force):
    """Each sample stepped exactly at its own condition and c2 (scipy's expm), outputs from
    the model at that c2 (they must not depend on it)."""
    n = MODEL.n_states
    x = np.zeros(n)
    out = np.empty((len(OUTPUTS), force.size))
    for i, (k, c, f) in enumerate(zip(condition, c2, force)):
        u, rho = conditions[k]
        a, b = MODEL.matrices(u, rho, c)
        cm, dm = DiscreteWing(MODEL, FS).output_matrices(a[None], b[None])
        out[:, i] = cm[0, ROWS] @ x + dm[0, ROWS] * f
        m = np.zeros((n + 1, n + 1))
        m[:n, :n], m[:n, n] = a, b
        step = expm(m / FS)
        x = step[:n, :n] @ x + step[:n, n] * f
    return out


@pytest.mark.parametrize("n_speeds", [3, 40])  # held conditions as they are; a ramp's nodes
def test_steps_at_every_sample_match_a_plain_matrix_exponential(n_speeds):
    rng = np.random.default_rng(3)
    n = 1500
    speeds = np.linspace(70.0, 95.0, n_speeds)
    conditions = np.column_stack([speeds, np.full(n_speeds, 1.225)])
    condition = np.repeat(np.arange(n_speeds), -(-n // n_speeds))[:n]
    # a switching law's c2 (two values) through a lag: every value in between
    c2 = np.where(rng.random(n) < 0.5, 100.0, 2500.0)
    c2 = np.maximum(100.0, np.convolve(c2, np.ones(7) / 7, mode="same"))
    force = 1000.0 * rng.standard_normal(n)
    steps = VaryingSteps(build, conditions, (K2 / c2.max(), K2 / c2.min()), 1 / FS,
                         maxwell_index(MODEL))
    got = simulate_varying(steps, condition, K2 / c2, force)
    want = reference(conditions, condition, c2, force)
    scale = np.abs(want).max(axis=1, keepdims=True)
    assert np.max(np.abs(got - want) / scale) < 1e-9
    # a c2 held over the samples is not the same flight: the comparison can fail
    held = simulate_varying(steps, condition, np.full(n, K2 / 1000.0), force)
    assert np.max(np.abs(held - want) / scale) > 1e-2


def test_transitions_are_the_product_of_the_steps():
    conditions = np.array([[80.0, 1.225]])
    c2 = np.array([300.0, 2500.0, 100.0, 900.0])
    steps = VaryingSteps(build, conditions, (K2 / 2500.0, K2 / 100.0), 1 / FS,
                         maxwell_index(MODEL))
    phi = transitions(steps, np.zeros(4, dtype=int), K2 / c2, np.array([0, 1]), 3)
    want = []
    for start in (0, 1):
        p = np.eye(MODEL.n_states)
        for c in c2[start:start + 3]:
            a, _ = MODEL.matrices(80.0, 1.225, c)
            p = expm(a / FS) @ p
        want.append(p)
    np.testing.assert_allclose(phi, np.array(want), atol=1e-10)


def test_rates_outside_the_built_range_and_bad_shapes_are_refused():
    conditions = np.array([[80.0, 1.225]])
    steps = VaryingSteps(build, conditions, (K2 / 2500.0, K2 / 100.0), 1 / FS,
                         maxwell_index(MODEL))
    with pytest.raises(ValueError, match="leave the range"):
        simulate_varying(steps, np.zeros(3, dtype=int), np.full(3, K2 / 50.0), np.zeros(3))
    with pytest.raises(ValueError, match="condition indices"):
        simulate_varying(steps, np.ones(3, dtype=int), np.full(3, K2 / 500.0), np.zeros(3))
    with pytest.raises(ValueError, match="inputs"):
        simulate_varying(steps, np.zeros(3, dtype=int), np.full(3, K2 / 500.0), np.zeros(4))
    with pytest.raises(ValueError, match="rate_range"):
        VaryingSteps(build, conditions, (5.0, 1.0), 1 / FS, maxwell_index(MODEL))
