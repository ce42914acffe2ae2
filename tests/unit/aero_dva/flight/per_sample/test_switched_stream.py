"""The switching law in a streamed flight's damper path: cut into blocks it flies as the
in-process switched flight, and a law that never switches flies as the streaming simulator."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control.switching_design import law_gain
from aero_dva.flight.discrete_model import FLIGHT_QUANTUM
from aero_dva.flight.per_sample.flight import fly_switched
from aero_dva.flight.per_sample.stream import SwitchedStream
from aero_dva.flight.per_sample.switching_law import SwitchingLaw
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

C_LO, C_HI = 100.0, 2500.0


@pytest.fixture(scope="module")
def wing():
    cfg = load_wing(None)
    return cfg, AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)


@pytest.mark.parametrize("scheduled", [False, True])
def test_blocks_fly_as_the_whole_switched_flight(wing, scheduled):
    """The switching law, and the clipped-optimal law whose rows follow the airspeed."""
    cfg, model = wing
    law = SwitchingLaw(law_gain(model, 115.0, 1.2, C_LO, C_HI), C_LO, C_HI)
    if scheduled:
        from aero_dva.control.clipped_optimal import scheduled_law

        law = scheduled_law(model, [100.0, 112.0, 124.0], 1.2, C_LO, C_HI, effort=30.0,
                            lead=0.01)
    force = np.random.default_rng(5).normal(0, 1000.0, 2000)
    speed = np.linspace(110.0, 118.0, 2000)
    whole = fly_switched(model, law, speed, 1.2, force, time_constant=0.01,
                         quantum=FLIGHT_QUANTUM)
    stream = SwitchedStream(model, law, 1000.0, 0.01)
    stream.arm(np.zeros(model.n_states), C_HI)
    blocks, switches = [], 0
    for i in range(0, 2000, 50):
        blocks.append(stream.advance(i, force[i:i + 50], speed[i:i + 50], 1.2))
        switches += stream.switches
    le = np.concatenate([b.displacements[2] for b in blocks])
    np.testing.assert_allclose(le, whole.leading_edge, rtol=1e-9,
                               atol=1e-11 * np.abs(le).max())
    assert np.array_equal(np.concatenate([b.target for b in blocks]), whole.target)
    assert np.array_equal(np.concatenate([b.damping for b in blocks]), whole.damping)
    # the damper force k2 delta, as the whole flight has it
    np.testing.assert_allclose(np.concatenate([b.damper_force for b in blocks]),
                               whole.damper_force, rtol=1e-9,
                               atol=1e-11 * np.abs(whole.damper_force).max())
    assert switches == np.count_nonzero(np.diff(whole.target)) > 20


def test_a_law_that_never_switches_flies_as_the_streaming_simulator(wing):
    cfg, model = wing
    c2 = 624.7
    law = SwitchingLaw(np.zeros(model.n_states), c2, c2 * (1 + 1e-9))
    force = np.random.default_rng(6).normal(0, 1000.0, 500)
    sim = StreamingSimulator(cfg.wing, cfg.absorber, quantum=FLIGHT_QUANTUM)
    ref = [sim.advance(force[i:i + 50], 105.0, 1.2, c2) for i in range(0, 500, 50)]
    stream = SwitchedStream(model, law, 1000.0, 0.0)
    stream.arm(np.zeros(model.n_states), c2)
    got = [stream.advance(i, force[i:i + 50], 105.0, 1.2) for i in range(0, 500, 50)]
    for r, g in zip(ref, got):
        for row in range(3):
            np.testing.assert_allclose(g.accelerations[row], r.accelerations[row], rtol=1e-6,
                                       atol=1e-9 * np.abs(r.accelerations[row]).max())
        np.testing.assert_allclose(g.displacements, r.displacements, rtol=1e-6,
                                   atol=1e-9 * np.abs(r.displacements).max())
    np.testing.assert_allclose(got[-1].state, sim.state, rtol=1e-6,
                               atol=1e-9 * np.abs(sim.state).max())


def test_advancing_a_disarmed_stream_is_refused(wing):
    _, model = wing
    stream = SwitchedStream(model, SwitchingLaw(np.zeros(model.n_states), C_LO, C_HI),
                            1000.0, 0.01)
    with pytest.raises(RuntimeError, match="not armed"):
        stream.advance(0, np.zeros(10), 100.0, 1.2)
