"""The discrete wing: sampled matrices, named outputs, the cached conditions and the hold rule."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import cont2discrete

from aero_dva.flight import discrete_model as dm
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.flight.hidden_plant import PlantOptions, PlantSimulator
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.model import AeroelasticModel
from tests.unit.aero_dva.flight.test_simulators import DVA, WING

MODEL = AeroelasticModel(WING, DVA)


def test_matrices_are_scipy_zoh_with_the_models_outputs():
    wing = dm.DiscreteWing(MODEL, 1000.0)
    params = np.array([[70.0, 1.2, 300.0], [85.0, 1.0, 1500.0]])
    got = wing.discretise(params)
    assert got.c.shape == (2, dm.N_OUTPUTS, MODEL.n_states) and got.d.shape == (2, dm.N_OUTPUTS)
    for k, (u, rho, c2) in enumerate(params):
        ss = MODEL.state_space(u, rho, c2)
        c = np.vstack([ss.c_displacement, ss.c_acceleration])
        d = np.r_[np.zeros(4), ss.d_acceleration]
        ad, bd, *_ = cont2discrete((ss.a, ss.b[:, None], c, d[:, None]), 1e-3, "zoh")
        np.testing.assert_allclose(got.ad[k], ad, rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(got.bd[k], bd[:, 0], rtol=1e-9, atol=1e-15)
        np.testing.assert_array_equal(got.c[k], c)
        np.testing.assert_array_equal(got.d[k], d)
    assert wing.output_index(["leading_edge", "pitch_acceleration"]) == [2, 5]
    with pytest.raises(ValueError, match="unknown outputs"):
        wing.output_index(["lift"])


def test_output_names_come_from_the_model_rows():
    assert dm.OUTPUT_NAMES[:dm.N_DISPLACEMENTS] == ("plunge", "pitch", "leading_edge",
                                                    "absorber_stroke")
    assert dm.ACCELERATION_OUTPUTS == ("plunge_acceleration", "pitch_acceleration",
                                       "leading_edge_acceleration")
    sim = StreamingSimulator(WING, DVA)
    out = sim.advance(np.ones(30), 70.0, 1.2)
    assert out.displacements.shape[0] == dm.N_DISPLACEMENTS
    assert out.accelerations.shape[0] == dm.N_OUTPUTS - dm.N_DISPLACEMENTS


def test_a_condition_is_built_once_and_rebuilt_when_it_changes():
    wing = dm.DiscreteWing(MODEL, 1000.0, hold=7, max_conditions=4)
    first = wing.at(70.0, 1.2, 300.0)
    assert wing.at(70.0, 1.2, 300.0) is first  # cached by its exact condition
    assert wing.cached == 1
    for other in (wing.at(70.0 + 1e-9, 1.2, 300.0), wing.at(70.0, 1.1, 300.0),
                  wing.at(70.0, 1.2, 301.0)):
        assert other is not first and not np.array_equal(other.ad, first.ad)
    assert wing.cached == 4
    wing.at(60.0, 1.2, 300.0)  # over max_conditions: the cache starts afresh
    assert wing.cached == 1
    # a call that mixes cached and new conditions past the limit gets all of them
    keys = [(60.0, 1.2, 300.0), *[(61.0 + i, 1.2, 300.0) for i in range(4)]]
    assert [c.ad.shape for c in wing.conditions(keys)] == [first.ad.shape] * 5
    assert wing.cached == 5  # one call's conditions are all kept, even past the limit
    # the maps: one step is [[Ad, Bd], [C, D]]; a hold period is h such steps
    m = wing.discretise([[70.0, 1.2, 300.0]])
    np.testing.assert_array_equal(first.ad, m.ad[0])
    np.testing.assert_array_equal(first.bd[:, 0], m.bd[0])
    np.testing.assert_array_equal(first.c, m.c[0])
    np.testing.assert_array_equal(first.d[:, 0], m.d[0])
    rng = np.random.default_rng(1)
    x0, f = rng.standard_normal(MODEL.n_states), 1000.0 * rng.standard_normal(7)
    x, ys = x0, []
    for fj in f:
        r = first.step @ np.r_[x, fj]
        x, y = r[:MODEL.n_states], r[MODEL.n_states:]
        ys.append(y)
    r = first.period @ np.r_[x0, f]
    np.testing.assert_allclose(r[:MODEL.n_states], x, rtol=1e-12, atol=1e-12 * np.abs(x).max())
    np.testing.assert_allclose(r[MODEL.n_states:].reshape(dm.N_OUTPUTS, 7), np.array(ys).T,
                               rtol=1e-12, atol=1e-12 * np.abs(ys).max())


def test_a_full_cache_keeps_the_conditions_asked_for_together():
    """A call mixing cached and new conditions that overflows the cache still returns all
    of them (a flight whose density and c2 change every block fills the cache this way)."""
    wing = dm.DiscreteWing(MODEL, 1000.0, max_conditions=4)
    cached = [(70.0, 1.2, c) for c in (300.0, 400.0, 500.0)]
    wing.conditions(cached)
    asked = [cached[0], (70.0, 1.2, 600.0), (70.0, 1.2, 700.0)]
    got = wing.conditions(asked)
    for key, condition in zip(asked, got):
        np.testing.assert_array_equal(condition.ad, wing.discretise([key]).ad[0])
    assert wing.cached == 3


def test_the_pitch_moment_input_is_a_couple_of_forces():
    wing = dm.DiscreteWing(MODEL, 1000.0, inputs=("force", "pitch_moment"))
    m = wing.discretise([[70.0, 1.2, 300.0]])
    assert m.bd.shape == (1, MODEL.n_states, 2) and m.d.shape == (1, dm.N_OUTPUTS, 2)
    # a unit moment = forces +1/dx at the aileron and -1/dx a distance dx ahead of it
    ahead = AeroelasticModel(WING.replace(aileron_position=WING.aileron_position + 0.5), DVA)
    _, b1 = MODEL.matrices(70.0, 1.2, 300.0)
    _, b2 = ahead.matrices(70.0, 1.2, 300.0)
    np.testing.assert_allclose(wing.continuous(np.array([[70.0, 1.2, 300.0]]))[1][0, :, 1],
                               (b1 - b2) / 0.5, rtol=1e-12, atol=1e-15)
    force_only = dm.DiscreteWing(MODEL, 1000.0).discretise([[70.0, 1.2, 300.0]])
    np.testing.assert_allclose(m.bd[..., 0], force_only.bd, rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(m.d[:, :dm.N_DISPLACEMENTS], 0.0)  # no feedthrough to them


@pytest.mark.parametrize("kwargs, match", [
    ({"hold": 0}, "hold"), ({"hold": 2.5}, "hold"), ({"quantum": 0.2}, "quantum"),
    ({"inputs": ("pitch_moment",)}, "inputs"), ({"inputs": ("force", "lift")}, "inputs"),
])
def test_bad_settings_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        dm.DiscreteWing(MODEL, 1000.0, **kwargs)
    with pytest.raises(ValueError, match="sample_rate"):
        dm.DiscreteWing(MODEL, 0.0)


def test_the_hold_rule_keeps_values_within_the_quantum():
    nan = float("nan")
    assert dm.next_held((70.0, 1.2, 300.0), (nan, nan, nan), (1e-3,) * 3) == (70.0, 1.2, 300.0)
    assert dm.next_held((70.05, 1.2, 300.0), (70.0, 1.2, 300.0), (1e-3,) * 3) == (70.0, 1.2,
                                                                                 300.0)
    assert dm.next_held((70.1, 1.2, 301.0), (70.0, 1.2, 300.0), (1e-3,) * 3) == (70.1, 1.2,
                                                                                301.0)
    # the vectorised rule over hold periods equals the scalar one step by step
    rng = np.random.default_rng(3)
    raw = 70.0 * (1.0 + np.cumsum(rng.uniform(0, 8e-4, (2, 50, 3)), axis=1))
    raw[1, :, 1] = 1.2  # a constant input
    got = dm.held_values(raw, np.full((2, 3), np.nan), 2e-3)
    for f in range(2):
        held = (nan, nan, nan)
        for p in range(50):
            held = dm.next_held(tuple(raw[f, p]), held, (2e-3,) * 3)
            assert tuple(got[f, p]) == held
    assert len(np.unique(got[0, :, 0])) < 50  # values were kept
    wing = dm.DiscreteWing(MODEL, 1000.0, quantum=2e-3)
    assert wing.held_sequence(map(tuple, raw[0]), (nan, nan, nan)) == [tuple(r) for r in got[0]]


def test_every_simulator_flies_a_discrete_wing():
    sim = StreamingSimulator(WING, DVA, quantum=1e-3)
    assert isinstance(sim.discrete, dm.DiscreteWing) and sim.discrete.hold == dm.DEFAULT_HOLD
    sim.advance(np.zeros(100), 70.0, 1.2, 300.0)
    assert sim.discrete.cached == 1
    plant = PlantSimulator(WING, DVA, 1000.0, WagnerAero(), PlantOptions(cubic_stiffness=10.0))
    plant.advance(np.zeros(25), 70.0, 1.2, 300.0)
    (plant_wing,) = plant._wings.values()
    assert plant_wing.inputs == ("force", "pitch_moment") and plant_wing.cached == 1
    traces = simulate_flights(WING, DVA, force=np.zeros((2, 40)), airspeed=70.0, density=1.2)
    assert traces.displacements.shape == (2, dm.N_DISPLACEMENTS, 40)
