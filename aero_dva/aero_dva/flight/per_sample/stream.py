"""The switching c2 law in the damper path of a flight streamed block by block: what the
simulator runs every sample while the law is armed (pure numerics, no ROS).

:class:`SwitchedStream` steps the wing, the damper's Kalman observer, the law and the damper's
first-order lag sample by sample with the same compiled loop as
:func:`~aero_dva.flight.per_sample.flight.fly_switched` (each sample an exact zero-order-hold step
at the c2 table level acting over it). It takes the plant state from the flight when the law
is armed and hands it back when it is disarmed; in between it keeps the observer's prediction,
the lag's c2 and the last decision, so a flight cut into blocks is flown as one.
Airspeed and density are held on the flight's grid of ``hold`` samples with the flight's
quantum, as the streaming simulator holds them.

Arming starts the observer from a zero prediction (the damper's controller does not know the
wing's state) and from the c2 the damper has; the first decision acts from the next sample.
"""
from __future__ import annotations

import math

import numpy as np

from aero_dva.flight.discrete_model import DEFAULT_HOLD, FLIGHT_QUANTUM, next_held
from aero_dva.flight.per_sample.flight import (
    _condition_maps,
    _Damper,
    _measurement,
    _steps,
    c2_levels,
)
from aero_dva.flight.per_sample.kernel import fly_maps
from aero_dva.flight.per_sample.switching_law import (
    MEASURED_OUTPUTS,
    SwitchingLaw,
    maxwell_index,
)
from aero_dva.flight.samples import FlightSamples
from aero_dva.wing.model import AeroelasticModel

__all__ = ["SwitchedStream"]


class SwitchedStream:
    """The law in the damper path of one flight (see the module docstring).

    Parameters
    ----------
    model : AeroelasticModel
        The flown wing with its Maxwell DVA (the observer's model too).
    law : SwitchingLaw
    sample_rate : float
        [Hz]
    time_constant : float
        [s] the damper's first-order lag (0: none).
    """

    def __init__(self, model: AeroelasticModel, law: SwitchingLaw, sample_rate: float,
                 time_constant: float, hold: int = DEFAULT_HOLD,
                 quantum: float = FLIGHT_QUANTUM):
        maxwell_index(model)
        if law.states != model.n_states:
            raise ValueError(f"the law's gain has {law.states} entries, the wing "
                             f"{model.n_states} states")
        self.model, self.law = model, law
        self.sample_rate = float(sample_rate)
        self.dt = 1.0 / self.sample_rate
        self.table = c2_levels(law.c_lo, law.c_hi, float(time_constant))
        self.hold, self.quantum = int(hold), float(quantum)
        self._lag = _Damper(float(time_constant), self.dt, law.c_lo, law.c_hi,
                            self.table.size, law.c_hi, math.inf,
                            model.absorber.series_stiffness, maxwell_index(model), 1)
        self._keys: dict[tuple, int] = {}
        self._maps: list[tuple] = []
        self._held = (math.nan, math.nan)
        m = 0 if law.observer is None else model.n_states
        self._z = np.zeros((1, model.n_states + m))
        self._c = np.full(1, law.c_hi)
        self._target = np.ones(1, dtype=bool)
        self._prev = np.zeros(1)
        self.armed = False
        self.switches = 0  # target changes in the last block flown (and at its start)

    @property
    def damping(self) -> float:
        """[N s/m] the lag's c2 at the end of the last block."""
        return float(self._c[0])

    def arm(self, state, damping: float) -> None:
        """Take over the flight with plant ``state`` and the damper at ``damping`` c2."""
        n = self.model.n_states
        self._z[:] = 0.0
        self._z[0, :n] = state
        c = min(max(float(damping), self.law.c_lo), self.law.c_hi)
        self._c[0] = c
        self._target[0] = c >= math.sqrt(self.law.c_lo * self.law.c_hi)
        self._prev[0] = 0.0
        self.armed = True

    def disarm(self) -> None:
        self.armed = False

    def _condition(self, key: tuple) -> int:
        j = self._keys.get(key)
        if j is None:
            cond = np.array([key])
            steps = _steps(self.model, self.model, cond, self.table, self.dt)[0]
            est, g_in, g_state = _condition_maps(self.model, self.model, self.law, cond)
            c, d = _measurement(self.model, cond)
            j = self._keys[key] = len(self._maps)
            self._maps.append((steps, est[0], g_in[0], g_state[0], c[0, 1:], d[0, 1:]))
        return j

    def advance(self, first_index: int, force, airspeed, density,
                noise=None) -> FlightSamples:
        """Fly samples ``first_index ..`` with the law (armed); ``force``, ``airspeed`` and
        ``density`` (n,) per sample; ``noise`` (n, 4) [SI] on the observer's measurements
        (None: exact). The samples' ``damping`` is the c2 level flown over each, ``target``
        True where the law asked for c_hi, ``damper_force`` the damper force k2 delta at each
        sample, ``state`` the plant state after the block; :attr:`switches` counts the
        target's changes within the block and at its start."""
        if not self.armed:
            raise RuntimeError("the switching law is not armed")
        force = np.asarray(force, dtype=float)
        n = force.size
        speeds = np.broadcast_to(np.asarray(airspeed, dtype=float), (n,))
        rhos = np.broadcast_to(np.asarray(density, dtype=float), (n,))
        held, conds = self._held, np.empty(n, dtype=np.int64)
        for i in range(n):
            if (first_index + i) % self.hold == 0 or math.isnan(held[0]):
                held = next_held((float(speeds[i]), float(rhos[i])), held,
                                 (self.quantum, self.quantum))
            conds[i] = self._condition(held)
        self._held = held
        used, sample_map = np.unique(conds, return_inverse=True)
        maps = [self._maps[j] for j in used]
        steps = np.stack([mp[0] for mp in maps])
        est, g_in, g_state = (np.stack([mp[k] for mp in maps]) for k in (1, 2, 3))
        index = np.arange(used.size, dtype=np.int64)[:, None]
        inputs = np.zeros((1, n, 1 + len(MEASURED_OUTPUTS)))
        inputs[0, :, 0] = force
        if noise is not None:
            inputs[0, :, 1:] = noise
        lag, before = self._lag, bool(self._target[0])
        states, level, target = fly_maps(
            steps, index, np.ones((used.size, 1)), est, g_in, g_state,
            sample_map.astype(np.int64).ravel(), inputs, self.model.n_states, lag.tau,
            lag.decay, lag.mean_factor, lag.c_lo, lag.c_hi, lag.per_level, math.inf, lag.k2,
            lag.deflection, 1, int(first_index), self._z, self._c, self._target, self._prev,
            0.0, np.zeros((1, 1)), self.table)
        x = states[0]  # (n, n_states) at each sample's start
        c_out = np.stack([mp[4] for mp in maps])[sample_map.ravel()]
        d_out = np.stack([mp[5] for mp in maps])[sample_map.ravel()]
        acc = (np.einsum("sij,sj->is", c_out, x) + d_out.T * force)
        disp = self.model.c_displacement @ x.T
        self.switches = int(np.count_nonzero(np.diff(np.concatenate([[before], target[0]]))))
        return FlightSamples(first_index=int(first_index), sample_rate=self.sample_rate,
                             airspeed=speeds, density=rhos, damping=self.table[level[0]],
                             force=force, displacements=disp, accelerations=acc,
                             state=self._z[0, :self.model.n_states].copy(),
                             target=target[0].copy(),
                             damper_force=x[:, lag.deflection] * lag.k2)
