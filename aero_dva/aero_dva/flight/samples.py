"""Samples of a flight: the one record every simulator of the flight layer returns (no ROS).

A :class:`FlightSamples` holds what a flight did sample by sample: a block of it (the streaming
simulator's, the flight runtime's, a per-sample law's stream) or the whole of it (the batch
simulator's, a per-sample law's flight), for one flight or for a batch of flights flown
together, which then carry a leading axis of flights. Time is on the last axis; sample ``i`` is
the state at ``time[i]`` and the outputs there with ``force[i]`` acting. What a route does not
compute is None (the accelerations of a flight kept for its leading edge only, the force a
batch drew itself); what only a per-sample law has (its targets, the damper's force and power)
is None elsewhere.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aero_dva.wing.model import LEADING_EDGE

__all__ = ["FlightSamples"]

STROKE = 3  # row of the absorber stroke in ``displacements``


@dataclass(frozen=True)
class FlightSamples:
    """Samples of a flight, a block of one, or of a batch of flights (module docstring).

    Attributes
    ----------
    first_index : int
        Index of the first sample since the start of the flight.
    sample_rate : float
        [Hz]
    airspeed, density : (n,) or (F, n)
        [m/s], [kg/m^3] as flown (per sample).
    damping : (n,) or (F, n)
        [N s/m] the c2 acting over each sample.
    force : (n,) or (F, n), or None
        [N] aileron force.
    displacements : (4, n) or (F, 4, n)
        plunge [m], pitch [rad], leading edge [m], absorber stroke [m].
    accelerations : (3, n) or (F, 3, n), or None
        plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2].
    diverged : bool or (F,) bool
        The flight diverged (in this block or before: sticky).
    flights : (F,) int or None
        A batch's block: the indices (into the batch's seeds) of the flights in it.
    samples : (F,) int or None
        A batch's whole flights: the samples each flew (past them: not flown, undefined).
    state : (n_states,) or (F, n_states), or None
        The state after the last sample.
    states : (n, n_states) or (F, n, n_states), or None
        The state at each sample's start, where a route keeps it on request.
    target : like ``damping`` (bool), or None
        A per-sample law's: True where it asked for its high c2.
    damper_force : like ``damping``, or None
        A per-sample law's: [N] the damper force k2 delta at each sample.
    damper_power : like ``damping``, or None
        A per-sample law's: [W] the power the damper dissipates over each sample.
    """

    first_index: int
    sample_rate: float
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    force: np.ndarray | None
    displacements: np.ndarray
    accelerations: np.ndarray | None = None
    diverged: bool | np.ndarray = False
    flights: np.ndarray | None = None
    samples: np.ndarray | None = None
    state: np.ndarray | None = None
    states: np.ndarray | None = None
    target: np.ndarray | None = None
    damper_force: np.ndarray | None = None
    damper_power: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Samples per flight."""
        return self.displacements.shape[-1]

    @property
    def time(self) -> np.ndarray:
        """(n,) [s] the samples' times."""
        return (self.first_index + np.arange(self.n)) / self.sample_rate

    @property
    def t0(self) -> float:
        """[s] time of the first sample."""
        return self.first_index / self.sample_rate

    @property
    def t_end(self) -> float:
        """[s] time of the sample after the last one (the next block's ``t0``)."""
        return (self.first_index + self.n) / self.sample_rate

    @property
    def leading_edge(self) -> np.ndarray:
        """[m] leading-edge displacement."""
        return self.displacements[..., LEADING_EDGE, :]

    @property
    def stroke(self) -> np.ndarray:
        """[m] absorber stroke."""
        return self.displacements[..., STROKE, :]

    @property
    def switches_per_second(self) -> float | np.ndarray:
        """A per-sample law's target changes per second of flight (per flight of a batch)."""
        target = self.target
        changes = np.count_nonzero(target[..., 1:] != target[..., :-1], axis=-1)
        out = changes * self.sample_rate / max(1, target.shape[-1] - 1)
        return float(out) if np.ndim(out) == 0 else out

    def dissipated(self, stop: int | None = None) -> float:
        """A per-sample law's [J] energy the damper dissipated over the first ``stop`` samples
        (all: None)."""
        return float(np.sum(self.damper_power[..., :stop]) / self.sample_rate)
