"""The switching c2 law as the damper's own controller holds it, and what it measures (no ROS).

Every sample, from an estimate ``x`` of the state, the law sets the damper's target

    c2 = c_hi  when  F(x) h(x) > 0,  else c_lo,      F = k2 delta (the damper force),

with ``h = gain @ x`` linear in the state (:mod:`aero_dva.control.switching_design` designs
the gain and the observer). A law may schedule its rows with the airspeed (the clipped-optimal
law of :mod:`aero_dva.control.clipped_optimal`): rows given at a grid of airspeeds, linear
between them and held beyond its ends, read at the airspeed each sample is flown at.
:mod:`.flight` flies it over a whole flight, :mod:`.stream` block by block in the simulator's
damper path, both with the compiled loop of :mod:`.kernel`.
Pure numerics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.wing.absorbers import MaxwellAbsorber
from aero_dva.wing.model import AeroelasticModel

__all__ = ["DESIGNS", "MEASURED_OUTPUTS", "SCHEDULED_DESIGN", "SwitchingLaw", "maxwell_index",
           "measured_rms", "measurement_matrices"]

#: The designs of a gains file: the two of :func:`aero_dva.control.switching_design.law_gain` at
#: one airspeed, and the clipped-optimal law scheduled with the airspeed
#: (:mod:`aero_dva.control.clipped_optimal`). Here, not in the design module: reading a gains
#: file needs the names, not scipy.
SCHEDULED_DESIGN = "clipped_optimal"
DESIGNS = ("lyapunov", "clipped", SCHEDULED_DESIGN)

#: Rows of the discrete model's outputs the damper's controller measures: the absorber stroke
#: [m] and the plunge [m/s^2], pitch [rad/s^2] and leading-edge [m/s^2] accelerations.
MEASURED_OUTPUTS = ("absorber_stroke", "plunge_acceleration", "pitch_acceleration",
                    "leading_edge_acceleration")


@dataclass(frozen=True)
class SwitchingLaw:
    """The per-sample law and its observer, as the damper's controller holds them.

    Attributes
    ----------
    gain : (n,) or (G, n)
        ``h = gain @ x`` on the observer model's state; (G, n): one row per airspeed of
        ``airspeeds``.
    c_lo, c_hi : float
        [N s/m] the two targets, ``0 < c_lo < c_hi``.
    observer : (n, 4) or None
        Filter gain on :data:`MEASURED_OUTPUTS` (``x = x_pred + observer (y - C x_pred)``);
        None: the law sees the plant's true state (the plant and observer models must then be
        the same).
    force_gain : (n,) or (G, n) or None
        ``F = force_gain @ x``; None: the damper force k2 delta. A design that leads the
        damper's lag evaluates F and h on the state predicted ahead (both rows times the
        model's transition matrix over the lead).
    airspeeds : (G,) or None
        [m/s] increasing airspeeds of a scheduled law's rows (G >= 2); None: one row for
        every airspeed.
    """

    gain: np.ndarray
    c_lo: float
    c_hi: float
    observer: np.ndarray | None = None
    force_gain: np.ndarray | None = None
    airspeeds: np.ndarray | None = None

    def __post_init__(self):
        gain = np.asarray(self.gain, dtype=float)
        if self.airspeeds is not None:
            speeds = np.asarray(self.airspeeds, dtype=float)
            if speeds.ndim != 1 or speeds.size < 2 or not np.all(np.isfinite(speeds)) or \
                    not np.all(np.diff(speeds) > 0):
                raise ValueError("airspeeds must be at least 2 increasing finite values")
            if gain.shape[:1] != speeds.shape or gain.ndim != 2:
                raise ValueError(f"a scheduled gain must have one row per airspeed "
                                 f"({speeds.size}), got shape {gain.shape}")
            object.__setattr__(self, "airspeeds", speeds)
        elif gain.ndim != 1:
            raise ValueError("gain must be a vector (a matrix needs airspeeds)")
        if not np.all(np.isfinite(gain)):
            raise ValueError("gain must be finite")
        lo, hi = float(self.c_lo), float(self.c_hi)
        if not (math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"need 0 < c_lo < c_hi (finite), got ({lo}, {hi}) N s/m")
        object.__setattr__(self, "gain", gain)
        object.__setattr__(self, "c_lo", lo)
        object.__setattr__(self, "c_hi", hi)
        if self.observer is not None:
            obs = np.asarray(self.observer, dtype=float)
            if obs.shape != (self.states, len(MEASURED_OUTPUTS)) or not np.all(np.isfinite(obs)):
                raise ValueError(f"observer must be a finite ({self.states}, "
                                 f"{len(MEASURED_OUTPUTS)}) matrix")
            object.__setattr__(self, "observer", obs)
        if self.force_gain is not None:
            fg = np.asarray(self.force_gain, dtype=float)
            if fg.shape != gain.shape or not np.all(np.isfinite(fg)):
                raise ValueError(f"force_gain must be finite with the gain's shape {gain.shape}")
            object.__setattr__(self, "force_gain", fg)

    @property
    def states(self) -> int:
        """States of the observer model the rows act on."""
        return int(self.gain.shape[-1])

    @property
    def scheduled(self) -> bool:
        return self.airspeeds is not None

    def rows_at(self, airspeed) -> tuple[np.ndarray, np.ndarray | None]:
        """``(gain, force_gain)`` at each of ``airspeed`` (K,) [m/s], each (K, n) (force_gain
        None when the law has none): a scheduled law's rows linear between its airspeeds and
        held beyond them, else its one row."""
        u = np.atleast_1d(np.asarray(airspeed, dtype=float))
        if not self.scheduled:
            rows = np.broadcast_to(self.gain, (u.size, self.states))
            force = None if self.force_gain is None else np.broadcast_to(
                self.force_gain, (u.size, self.states))
            return rows, force
        grid = self.airspeeds
        j = np.clip(np.searchsorted(grid, u, side="right") - 1, 0, grid.size - 2)
        w = np.clip((u - grid[j]) / (grid[j + 1] - grid[j]), 0.0, 1.0)[:, None]

        def blend(m):
            return None if m is None else (1.0 - w) * m[j] + w * m[j + 1]

        return blend(self.gain), blend(self.force_gain)


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




def measured_rms(model: AeroelasticModel, airspeed: float, density: float, damping: float,
                 sample_rate: float, force_std: float) -> np.ndarray:
    """Stationary RMS (4,) of :data:`MEASURED_OUTPUTS` under the white aileron force of
    ``force_std`` [N] per sample, c2 held (the scale of the sensors' noise); ValueError if the
    wing is unstable there."""
    # imported here: reading a gains file (the simulator's start) needs no scipy
    from scipy import linalg

    from aero_dva.flight.discretize import zoh

    a, b = model.matrices(airspeed, density, damping)
    ad, bd = zoh(a, b, 1.0 / sample_rate)
    if np.max(np.abs(np.linalg.eigvals(ad))) >= 1.0:
        raise ValueError(f"the wing is unstable at {airspeed:g} m/s with c2 = {damping:g} N s/m")
    cov = linalg.solve_discrete_lyapunov(ad, force_std**2 * np.outer(bd, bd))
    c, d = measurement_matrices(model, airspeed, density, damping)
    return np.sqrt(np.diag(c @ cov @ c.T) + force_std**2 * d**2)
