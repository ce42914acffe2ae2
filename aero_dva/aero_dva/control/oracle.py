"""The oracle: c2*(U, rho) at the true airspeed and density, the bound no measuring controller
can beat (no ROS).

:class:`OptimalDampingTable` tabulates the exact stationary RMS optimum c2* over airspeed and
density; :class:`OracleLaw`, the ``oracle`` of the controller table
(:mod:`aero_dva.control.controllers`, a reference that runs in process only), commands it at
the conditions of the block its command will act on (the host hands them in as its ``truth``).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from aero_dva.control.controllers import LawStep
from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.flight.damper import DAMPER_RANGE

__all__ = ["OptimalDampingTable", "OracleLaw", "oracle_law"]


@dataclass(frozen=True)
class OptimalDampingTable:
    """c2*(U, rho) on a grid, interpolated bilinearly (the oracle's knowledge).

    Where no c2 keeps the wing stable (no RMS optimum), the table holds the c2 of the lowest
    growth rate instead, so the oracle still does the best a constant-condition analysis can.

    Attributes
    ----------
    airspeed, density : ndarray
        [m/s], [kg/m^3] grid axes (increasing).
    damping : ndarray, shape (n_u, n_rho)
        [N s/m]
    stable : ndarray of bool, shape (n_u, n_rho)
        An RMS optimum exists there.
    """

    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    stable: np.ndarray

    @classmethod
    def build(cls, model, airspeed, density, *, grid=None, sample_rate: float = 1000.0):
        """Tabulate c2* (the exact stationary leading-edge RMS optimum) on the grid."""
        u = np.asarray(airspeed, dtype=float)
        rho = np.asarray(density, dtype=float)
        c = np.linspace(*DAMPER_RANGE, 126) if grid is None else np.asarray(grid, dtype=float)
        table = np.empty((u.size, rho.size))
        stable = np.empty((u.size, rho.size), dtype=bool)
        for k, r in enumerate(rho):
            res = optimal_damping(model, u, c, float(r), sample_rate=sample_rate)
            stable[:, k] = np.isfinite(res.optimal_damping)
            table[:, k] = res.optimal_damping
            bad = ~stable[:, k]
            if bad.any():
                growth = stationary_rms(model, u[bad, None], float(r), c[None, :]).growth_rate
                table[bad, k] = c[np.argmin(growth, axis=1)]
        return cls(airspeed=u, density=rho, damping=table, stable=stable)

    def __call__(self, airspeed, density) -> np.ndarray:
        interp = RegularGridInterpolator((self.airspeed, self.density), self.damping,
                                         bounds_error=False, fill_value=None)
        u = np.clip(np.asarray(airspeed, float), self.airspeed[0], self.airspeed[-1])
        r = np.clip(np.asarray(density, float), self.density[0], self.density[-1])
        u, r = np.broadcast_arrays(u, r)
        return interp(np.stack([u.ravel(), r.ravel()], axis=-1)).reshape(u.shape)


class OracleLaw:
    """c2*(U, rho) of an :class:`OptimalDampingTable` at the true conditions it is handed."""

    counters = ()

    def __init__(self, table: OptimalDampingTable):
        self.table = table

    def condition_law(self) -> OptimalDampingTable:
        """c2(U, rho) (the stability boundaries'): the table."""
        return self.table

    def answer(self, kind: str, stamp_ns: int, value) -> LawStep:
        """``value``: the :class:`~.controllers.Condition` where the command will act."""
        return LawStep.command(float(self.table(np.array([value.airspeed]),
                                                np.array([value.density]))[0]))


def oracle_law(values: Mapping) -> OracleLaw:
    """The oracle of ``values["table"]`` (an :class:`OptimalDampingTable`)."""
    return OracleLaw(values["table"])
