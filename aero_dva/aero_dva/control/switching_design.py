"""Gains of the per-sample switching c2 law and of its observer, from the model (no ROS).

The law (:mod:`aero_dva.flight.per_sample.switching_law`) sets c2 = c_hi when ``F h(x) > 0``,
F = k2 delta the damper force and ``h = gain @ x``. Two designs give the gain, both from an LQR
problem at a design airspeed that weights the leading-edge displacement:

- ``lyapunov``: c2 enters the model only through the Maxwell rate r = k2 / c2 in
  ``delta' = (stroke rate) - r delta``. Around ``r_mid`` (the geometric mean of the two rates)
  the switching is an input ``v = -(r - r_mid) delta`` on the delta row, of either sign. With
  P the Riccati solution of that input, the choice of r that makes ``dV/dt`` of ``V = x'Px``
  most negative is ``c_hi`` when ``F (-P[delta] x) > 0``: ``h = -P[delta] x``. The on-off
  clipped-optimal rule for the same input (v with the sign of the LQR's ``-R^-1 b'P x``) is the
  same rule.
- ``clipped``: Dyke et al. (1996). The Maxwell element is replaced by an ideal force actuator
  ``F`` between wing and absorber mass; the LQR gives the wanted force ``f_c = -K x`` and the
  damper stiffens (c_hi) when more force in its present direction is wanted, ``F (f_c - F) > 0``:
  ``h = -K x - k2 delta``.

The observer is the steady-state Kalman filter of the discrete model at the design airspeed and
the middle c2 (process noise the aileron force, measurement noise the sensors' plus the force's
feed-through into the accelerations). Pure numerics (scipy.linalg Riccati solvers).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import linalg

from aero_dva.flight.discretize import zoh
from aero_dva.flight.per_sample.switching_law import (
    DESIGNS,
    SCHEDULED_DESIGN,
    maxwell_index,
    measured_rms,
    measurement_matrices,
)
from aero_dva.wing.model import AeroelasticModel

__all__ = ["DESIGNS", "SCHEDULED_DESIGN", "desired_force_gain", "kalman_filter_gain", "law_gain",
           "measured_rms", "middle_damping"]


def middle_damping(c_lo: float, c_hi: float) -> float:
    """[N s/m] the c2 of the middle Maxwell rate (geometric mean of the two)."""
    return math.sqrt(c_lo * c_hi)


def _leading_edge_weight(model: AeroelasticModel) -> np.ndarray:
    row = model.c_displacement[2]
    return np.outer(row, row)


def law_gain(model: AeroelasticModel, airspeed: float, density: float, c_lo: float,
             c_hi: float, *, design: str = "lyapunov", effort: float = 1.0) -> np.ndarray:
    """The gain ``h = gain @ x`` of the switching law (module docstring).

    ``effort`` scales the LQR's control weight (relative to a weight that makes the control
    term and the leading-edge term of the cost comparable); the design command searches it.
    """
    if design not in DESIGNS[:2]:
        raise ValueError(f"design must be one of {DESIGNS[:2]}, got {design!r}")
    if not effort > 0:
        raise ValueError(f"effort must be > 0, got {effort}")
    idx = maxwell_index(model)
    a, _ = model.matrices(airspeed, density, middle_damping(c_lo, c_hi))
    q = _leading_edge_weight(model)
    # A tiny weight on every state keeps the Riccati problem well posed (the aerodynamic lag
    # and absorber states are not seen by the leading edge alone).
    q = q + 1e-9 * np.eye(a.shape[0]) * np.trace(q)
    k2 = model.absorber.series_stiffness
    if design == "lyapunov":
        b = np.zeros((a.shape[0], 1))
        b[idx, 0] = 1.0
        r = np.array([[effort * 1e-6]])  # v [m/s] against the leading edge [m]
        p = linalg.solve_continuous_are(a, b, q, r)
        return -p[idx] / np.max(np.abs(p[idx]))
    gain = -desired_force_gain(model, airspeed, density, effort)
    gain[idx] = -k2
    return gain / np.max(np.abs(gain))


def desired_force_gain(model: AeroelasticModel, airspeed: float, density: float,
                       effort: float = 1.0) -> np.ndarray:
    """``K`` (n,) of the force ``f_c = -K x`` [N] an ideal actuator in place of the Maxwell
    element should give (the ``clipped`` design, Dyke et al. 1996): the LQR of the wing with
    its absorber mass and parallel spring, weighting the leading-edge displacement against
    ``effort`` x 1e-12 m^2/N^2 times F^2. Zero in the Maxwell deflection's column."""
    if not effort > 0:
        raise ValueError(f"effort must be > 0, got {effort}")
    idx = maxwell_index(model)
    # c2 enters only the Maxwell row, which the actuator replaces: any c2 > 0 gives the same
    a, _ = model.matrices(airspeed, density, 1000.0)
    q = _leading_edge_weight(model)
    q = q + 1e-9 * np.eye(a.shape[0]) * np.trace(q)
    keep = [i for i in range(a.shape[0]) if i != idx]
    a_s = a[np.ix_(keep, keep)]
    b_s = a[keep, idx][:, None] / model.absorber.series_stiffness  # F = k2 delta enters so
    r = np.array([[effort * 1e-12]])  # F [N] against the leading edge [m]
    p = linalg.solve_continuous_are(a_s, b_s, q[np.ix_(keep, keep)], r)
    gain = np.zeros(a.shape[0])
    gain[keep] = (b_s.T @ p / r[0, 0])[0]
    return gain


def kalman_filter_gain(model: AeroelasticModel, airspeed: float, density: float,
                       damping: float, sample_rate: float, force_std: float,
                       sensor_std) -> np.ndarray:
    """Steady-state filter gain ``M`` (n, 4) on the measured outputs (module docstring).

    ``force_std`` [N] of the white aileron force per sample; ``sensor_std`` (4,) [SI] of the
    sensors' noise, > 0.
    """
    sensor_std = np.asarray(sensor_std, dtype=float)
    if sensor_std.shape != (4,) or not np.all(sensor_std > 0):
        raise ValueError("sensor_std must be 4 positive values")
    a, b = model.matrices(airspeed, density, damping)
    ad, bd = zoh(a, b, 1.0 / sample_rate)
    c, d = measurement_matrices(model, airspeed, density, damping)
    qn = force_std**2 * np.outer(bd, bd) + 1e-12 * np.eye(ad.shape[0]) * np.trace(
        np.outer(bd, bd)) * force_std**2
    rn = force_std**2 * np.outer(d, d) + np.diag(sensor_std**2)
    p = linalg.solve_discrete_are(ad.T, c.T, qn, rn)
    return p @ c.T @ np.linalg.inv(c @ p @ c.T + rn)


def lead_rows(model: AeroelasticModel, airspeed: float, density: float, c_lo: float,
              c_hi: float, gain: np.ndarray, lead: float):
    """``(force_gain, gain)`` evaluated on the state predicted ``lead`` seconds ahead by the
    model at the middle c2 (a lead against the damper's lag; ``lead`` = 0: unchanged)."""
    if not lead >= 0:
        raise ValueError(f"lead must be >= 0 s, got {lead}")
    a, _ = model.matrices(airspeed, density, middle_damping(c_lo, c_hi))
    phi = linalg.expm(a * lead)
    force = np.zeros(a.shape[0])
    force[maxwell_index(model)] = model.absorber.series_stiffness
    return force @ phi, np.asarray(gain, dtype=float) @ phi
