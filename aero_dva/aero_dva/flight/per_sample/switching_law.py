"""The switching c2 law as the damper's own controller holds it, and what it measures (no ROS).

Every sample, from an estimate ``x`` of the state, the law sets the damper's target

    c2 = c_hi  when  F(x) h(x) > 0,  else c_lo,      F = k2 delta (the damper force),

with ``h = gain @ x`` linear in the state (:mod:`aero_dva.control.switching_design` designs
the gain and the observer). :mod:`.flight` flies it over a whole flight, :mod:`.stream` block
by block in the simulator's damper path, both with the compiled loop of :mod:`.kernel`.
Pure numerics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.wing.absorbers import MaxwellAbsorber
from aero_dva.wing.model import AeroelasticModel

__all__ = ["MEASURED_OUTPUTS", "SwitchingLaw", "maxwell_index", "measurement_matrices"]

#: Rows of the discrete model's outputs the damper's controller measures: the absorber stroke
#: [m] and the plunge [m/s^2], pitch [rad/s^2] and leading-edge [m/s^2] accelerations.
MEASURED_OUTPUTS = ("absorber_stroke", "plunge_acceleration", "pitch_acceleration",
                    "leading_edge_acceleration")


@dataclass(frozen=True)
class SwitchingLaw:
    """The per-sample law and its observer, as the damper's controller holds them.

    Attributes
    ----------
    gain : (n,)
        ``h = gain @ x`` on the observer model's state.
    c_lo, c_hi : float
        [N s/m] the two targets, ``0 < c_lo < c_hi``.
    observer : (n, 4) or None
        Filter gain on :data:`MEASURED_OUTPUTS` (``x = x_pred + observer (y - C x_pred)``);
        None: the law sees the plant's true state (the plant and observer models must then be
        the same).
    force_gain : (n,) or None
        ``F = force_gain @ x``; None: the damper force k2 delta. A design that leads the
        damper's lag evaluates F and h on the state predicted ahead (both rows times the
        model's transition matrix over the lead).
    """

    gain: np.ndarray
    c_lo: float
    c_hi: float
    observer: np.ndarray | None = None
    force_gain: np.ndarray | None = None

    def __post_init__(self):
        gain = np.asarray(self.gain, dtype=float)
        if gain.ndim != 1 or not np.all(np.isfinite(gain)):
            raise ValueError("gain must be a finite vector")
        lo, hi = float(self.c_lo), float(self.c_hi)
        if not (math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"need 0 < c_lo < c_hi (finite), got ({lo}, {hi}) N s/m")
        object.__setattr__(self, "gain", gain)
        object.__setattr__(self, "c_lo", lo)
        object.__setattr__(self, "c_hi", hi)
        if self.observer is not None:
            obs = np.asarray(self.observer, dtype=float)
            if obs.shape != (gain.size, len(MEASURED_OUTPUTS)) or not np.all(np.isfinite(obs)):
                raise ValueError(f"observer must be a finite ({gain.size}, "
                                 f"{len(MEASURED_OUTPUTS)}) matrix")
            object.__setattr__(self, "observer", obs)
        if self.force_gain is not None:
            fg = np.asarray(self.force_gain, dtype=float)
            if fg.shape != gain.shape or not np.all(np.isfinite(fg)):
                raise ValueError(f"force_gain must be a finite vector of {gain.size} entries")
            object.__setattr__(self, "force_gain", fg)


def maxwell_index(model: AeroelasticModel) -> int:
    """State index of the Maxwell spring deflection ``delta`` (F = k2 delta)."""
    if not isinstance(model.absorber, MaxwellAbsorber):
        raise ValueError("the switching law needs a Maxwell absorber")
    return model.state_names.index("maxwell_deflection")


def measurement_matrices(model: AeroelasticModel, airspeed, density, damping):
    """``C`` (..., 4, n) and ``D`` (..., 4) of :data:`MEASURED_OUTPUTS` (force input)."""
    a, b = model.matrices(airspeed, density, damping)
    c_acc, d_acc = model.acceleration_output(a, b)
    stroke = np.broadcast_to(model.c_displacement[3], a.shape[:-2] + (1, a.shape[-1]))
    c = np.concatenate([stroke, c_acc], axis=-2)
    d = np.concatenate([np.zeros(a.shape[:-2] + (1,)), d_acc], axis=-1)
    return c, d


