"""A flight flown again with the c2 it recorded, sample by sample (no ROS).

A per-sample law decides c2 in the damper's own controller, in closed loop with the wing; a
bag records its decisions (``dva/damper_block``: the c2 acting over each sample of every block
the law flew) and, for the other blocks, the c2 the damper held (``dva/damper_state``).
:func:`fly_again` flies the wing once more with those c2 values and the recorded aileron force,
the way the flight runtime flew it: held blocks by the streaming simulator, law blocks sample by
sample with each sample's exact zero-order-hold step at its c2 (the maps
:func:`~aero_dva.flight.per_sample.flight._steps` forms for the law's stream) and the same
hold of airspeed and density, the plant's state carried across. No law and no observer runs:
what the law decided is taken as recorded. Each sample's state is summed in the compiled
loop's order: above flutter the wing under a recorded c2 sequence amplifies a rounding
difference 60 to 150 times per second (1.17-1.2 U_cr), so only the same sums give the
recorded accelerations over a whole flight.
"""
from __future__ import annotations

import math

import numpy as np

from aero_dva.flight.discrete_model import DEFAULT_HOLD, FLIGHT_QUANTUM, next_held
from aero_dva.flight.per_sample.flight import _measurement, _steps
from aero_dva.flight.samples import FlightSamples
from aero_dva.flight.streaming_simulator import StreamingSimulator

__all__ = ["fly_again"]


class _RecordedPath:
    """The law's path with its decisions given: the plant stepped at each sample's c2."""

    def __init__(self, model, sample_rate: float, hold: int, quantum: float):
        self.model, self.dt = model, 1.0 / float(sample_rate)
        self.hold, self.quantum = int(hold), float(quantum)
        self._held = (math.nan, math.nan)  # kept from block to block, as the law's stream
        self._steps: dict[tuple, np.ndarray] = {}
        self._outputs: dict[tuple, tuple] = {}

    def _step(self, held: tuple, c2: float) -> np.ndarray:
        key = (held, c2)
        step = self._steps.get(key)
        if step is None:
            n = self.model.n_states
            flat = _steps(self.model, self.model, np.array([held]), np.array([c2]), self.dt)
            step = self._steps[key] = flat[0, 0, :n * (n + 1)].reshape(n, n + 1)
        return step

    def _output(self, held: tuple) -> tuple:
        out = self._outputs.get(held)
        if out is None:
            c, d = _measurement(self.model, np.array([held]))
            out = self._outputs[held] = (c[0, 1:], d[0, 1:])
        return out

    def advance(self, first_index: int, state, force, airspeed, density, damping):
        """Samples ``first_index ..`` from ``state``: displacements (4, n), accelerations
        (3, n) at each sample and the state after the last."""
        n = force.size
        x = np.array(state, dtype=float)
        states = np.empty((n, x.size))
        c_out, d_out = [], []
        held = self._held
        for i in range(n):
            if (first_index + i) % self.hold == 0 or math.isnan(held[0]):
                held = next_held((float(airspeed[i]), float(density[i])), held,
                                 (self.quantum, self.quantum))
            states[i] = x
            step = self._step(held, float(damping[i]))
            # the compiled loop's sum, term by term in its order (input first, then each
            # state), so that the state comes out as flown to the bit, not only to rounding:
            # rounding grows as the wing's own motion does, above flutter by e^(4 t)
            xn = step[:, -1] * force[i]
            for j in range(x.size):
                xn = xn + step[:, j] * x[j]
            x = xn
            c, d = self._output(held)
            c_out.append(c)
            d_out.append(d)
        self._held = held
        acc = np.einsum("sij,sj->is", np.stack(c_out), states) + np.stack(d_out).T * force
        return self.model.c_displacement @ states.T, acc, x


def fly_again(config, force, damping, law_flew, critical_airspeed: float | None = None,
              samples: int | None = None) -> FlightSamples:
    """Fly ``config`` (a :class:`~aero_dva.flight.flight_runtime.RuntimeConfig`: its scenario,
    wing and absorber) again with the recorded ``force`` (N,) [N] and c2 ``damping`` (N,)
    [N s/m], where ``law_flew`` (N,) bool marks the samples a per-sample law set c2 for (its
    blocks); the others held the block's c2. ``samples``: how many were flown (default N).
    Returns the samples of the flight flown again (airspeed and density from the scenario)."""
    from aero_dva.flight.flight_runtime import resolved_scenario
    from aero_dva.flight.scenario import airspeed_at, density_at, sample_times

    u_cr, scenario = resolved_scenario(config, critical_airspeed)
    force = np.asarray(force, dtype=float)
    damping = np.asarray(damping, dtype=float)
    law_flew = np.asarray(law_flew, dtype=bool)
    total = force.size if samples is None else int(samples)
    if not (force.size == damping.size == law_flew.size >= total):
        raise ValueError("force, damping and law_flew must have one value per sample")
    if not (np.all(np.isfinite(force[:total])) and np.all(np.isfinite(damping[:total]))):
        raise ValueError("force and damping must be finite at every sample flown")
    if config.absorber is None:
        raise ValueError("the flight has no absorber: no c2 to fly again")
    t = sample_times(scenario, 0, total)
    airspeed, density = airspeed_at(scenario, t), density_at(scenario, t)
    rate, size = scenario.sample_rate, scenario.block_size
    sim = StreamingSimulator(config.wing, config.absorber, sample_rate=rate, aero=config.aero,
                             quantum=FLIGHT_QUANTUM)
    law = _RecordedPath(sim.model, rate, DEFAULT_HOLD, FLIGHT_QUANTUM)
    disp = np.empty((4, total))
    acc = np.empty((3, total))
    for a in range(0, total, size):
        b = min(a + size, total)
        block = slice(a, b)
        if law_flew[block].any() != law_flew[block].all():
            raise ValueError(f"samples {a}..{b - 1}: a per-sample law flew part of a block")
        if law_flew[a]:
            disp[:, block], acc[:, block], state = law.advance(
                a, sim.state, force[block], airspeed[block], density[block], damping[block])
            diverged = not np.all(np.isfinite(state)) or \
                np.max(np.abs(disp[2, block])) > sim.divergence_limit
            sim.continue_from(state, b - a, diverged)
        else:
            out = sim.advance(force[block], airspeed[block], density[block], damping[block])
            disp[:, block], acc[:, block] = out.displacements, out.accelerations
    return FlightSamples(first_index=0, sample_rate=rate, airspeed=airspeed, density=density,
                         damping=damping[:total], force=force[:total], displacements=disp,
                         accelerations=acc, diverged=sim.diverged, state=sim.state)
