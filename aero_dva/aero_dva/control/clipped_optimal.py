"""The clipped-optimal law of Dyke et al. (1996), scheduled with the airspeed: its design (no ROS).

The Maxwell element (spring k2 in series with the damper c2) is replaced by an ideal force
actuator F between the wing and the absorber mass. At each airspeed U of a grid, an LQR design
for that actuator on the wing with its absorber mass and parallel spring gives the desired
force ``f_c = -K(U) x``: it minimises

    J = integral of ( w_LE^2 + r F^2 ) dt,   r = effort x 1e-12 m^2/N^2

with ``w_LE`` the leading-edge displacement (the response every table of the project ranks) and
a tiny weight on every state that keeps the Riccati problem well posed
(:func:`~aero_dva.control.switching_design.desired_force_gain`, the ``clipped`` design's at
one airspeed). The damper, which can
only dissipate, is then commanded each sample (:mod:`aero_dva.flight.per_sample`) to

    c2 = c_hi  when  F (f_c - F) > 0,  else  c_lo,        F = k2 delta (the damper force),

Dyke's rule: more force in the direction the damper already pushes is wanted, so it stiffens;
otherwise it lets go. In the per-sample law's form ``F h > 0`` that is ``h = -K(U) x - k2
delta``. The rows are given at the grid's airspeeds and read, linearly between them, at the
airspeed each sample is flown at (:meth:`SwitchingLaw.rows_at
<aero_dva.flight.per_sample.switching_law.SwitchingLaw.rows_at>`). The state comes from the
switching law's Kalman observer (:func:`~aero_dva.control.switching_design.kalman_filter_gain`),
and F and h may be read on the state predicted ``lead`` seconds ahead against the damper's lag
(:func:`~aero_dva.control.switching_design.lead_rows`). docs/clipped_optimal.md gives the
weights and why. Pure numerics.
"""
from __future__ import annotations

import numpy as np

from aero_dva.control.switching_design import desired_force_gain, lead_rows
from aero_dva.flight.per_sample.switching_law import SwitchingLaw, maxwell_index
from aero_dva.wing.model import AeroelasticModel

__all__ = ["SCHEDULE_RANGE", "schedule_airspeeds", "scheduled_law"]

#: Grid of the schedule, as ratios of U_cr (low, high, step): past the ends of the evaluation's
#: ramps, so that no flown airspeed holds an end row; 0.025 U_cr steps keep the rows read
#: between two airspeeds within 2 % of the exact design there (a test checks it).
SCHEDULE_RANGE = (0.6, 1.6, 0.025)


def schedule_airspeeds(critical_airspeed: float) -> np.ndarray:
    """[m/s] the schedule's grid (:data:`SCHEDULE_RANGE` times U_cr)."""
    low, high, step = SCHEDULE_RANGE
    return critical_airspeed * np.linspace(low, high, int(round((high - low) / step)) + 1)


def scheduled_law(model: AeroelasticModel, airspeeds, density: float, c_lo: float,
                  c_hi: float, *, effort: float, lead: float = 0.0,
                  observer: np.ndarray | None = None) -> SwitchingLaw:
    """The clipped-optimal law with rows at ``airspeeds`` [m/s] (module docstring).

    ``lead`` [s]: F and h read on the state predicted that far ahead by the model at the
    middle c2 of each airspeed (0: the damper force k2 delta itself). ``observer``: the
    Kalman filter gain (n, 4) of the measured outputs, None for a law that sees the state.
    Both rows are divided by k2 (only their signs decide), so they read in metres.
    """
    k2 = model.absorber.series_stiffness
    idx = maxwell_index(model)
    speeds = np.asarray(airspeeds, dtype=float)
    gains, forces = [], []
    for u in speeds:
        h = -desired_force_gain(model, float(u), density, effort)
        h[idx] -= k2  # f_c - F
        force, h = lead_rows(model, float(u), density, c_lo, c_hi, h, lead)
        gains.append(h / k2)
        forces.append(force / k2)
    return SwitchingLaw(np.array(gains), c_lo, c_hi, observer,
                        np.array(forces) if lead else None, speeds)
