"""The textbook typical section (Hodges & Pierce; Bisplinghoff, Ashley & Halfman; Fung).

A rigid section of semichord ``b`` on a plunge spring and a torsion spring at the elastic axis,
in the usual nondimensional form:

- ``mass_ratio`` ``mu = m / (pi rho b^2)`` (``m`` per unit span),
- ``radius_of_gyration_sq`` ``r^2 = I_ea / (m b^2)`` about the elastic axis,
- ``frequency_ratio`` ``sigma = omega_h / omega_alpha`` of the uncoupled frequencies
  ``omega_h^2 = k_h / m`` and ``omega_alpha^2 = k_alpha / I_ea``,
- ``static_unbalance`` ``x_alpha``: gravity centre aft of the elastic axis, in semichords,
- ``elastic_axis`` ``a``: elastic axis aft of mid-chord, in semichords,
- ``pitch_frequency`` ``omega_alpha`` [rad/s] and ``air_density`` ``rho`` [kg/m^3].

:func:`section_to_wing` turns it into the study's gravity-centre form (per metre of span,
thin-airfoil lift slope ``2 pi``, no structural damping), so the same solvers apply.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from aero_dva.wing.checks import finite, positive
from aero_dva.wing.model import WingParameters

__all__ = ["TypicalSection", "section_to_wing"]


@dataclass(frozen=True)
class TypicalSection:
    """Textbook typical section (see the module docstring for the symbols).

    Parameters
    ----------
    semichord : float
        ``b`` [m].
    mass_ratio : float
        ``mu`` [1].
    radius_of_gyration_sq : float
        ``r^2`` [1], about the elastic axis in semichords^2; must exceed ``x_alpha^2``.
    frequency_ratio : float
        ``sigma = omega_h / omega_alpha`` [1].
    static_unbalance : float
        ``x_alpha`` [1], gravity centre aft of the elastic axis in semichords.
    elastic_axis : float
        ``a`` [1], elastic axis aft of mid-chord in semichords, in ``[-1, 1]``.
    pitch_frequency : float
        ``omega_alpha`` [rad/s].
    air_density : float
        ``rho`` [kg/m^3].
    """

    semichord: float
    mass_ratio: float
    radius_of_gyration_sq: float
    frequency_ratio: float
    static_unbalance: float
    elastic_axis: float
    pitch_frequency: float
    air_density: float

    def __post_init__(self):
        for name in ("semichord", "mass_ratio", "radius_of_gyration_sq", "frequency_ratio",
                     "pitch_frequency", "air_density"):
            object.__setattr__(self, name, positive(getattr(self, name), name))
        for name in ("static_unbalance", "elastic_axis"):
            object.__setattr__(self, name, finite(getattr(self, name), name))
        if not -1.0 <= self.elastic_axis <= 1.0:
            raise ValueError(
                f"elastic_axis must lie in [-1, 1] semichords, got {self.elastic_axis}")
        cg = self.elastic_axis + self.static_unbalance
        if not -1.0 <= cg <= 1.0:
            raise ValueError(
                "static_unbalance puts the gravity centre off the chord "
                f"(a + x_alpha = {cg} semichords)"
            )
        if self.radius_of_gyration_sq <= self.static_unbalance**2:
            raise ValueError(
                "radius_of_gyration_sq must exceed static_unbalance^2 (positive inertia about "
                "the gravity centre)"
            )

    def replace(self, **changes) -> TypicalSection:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    @property
    def reference_speed(self) -> float:
        """``b omega_alpha`` [m/s], the unit of the reduced velocity ``U / (b omega_alpha)``."""
        return self.semichord * self.pitch_frequency


def section_to_wing(section: TypicalSection) -> WingParameters:
    """The section as :class:`WingParameters` (per metre of span, ``dCL/dalpha = 2 pi``)."""
    if not isinstance(section, TypicalSection):
        raise TypeError(f"section must be TypicalSection, got {type(section).__name__}")
    b = section.semichord
    mass = section.mass_ratio * np.pi * section.air_density * b**2
    inertia_ea = section.radius_of_gyration_sq * mass * b**2
    offset = section.static_unbalance * b  # elastic axis ahead of the gravity centre [m]
    return WingParameters(
        mass=mass,
        inertia=inertia_ea - mass * offset**2,
        plunge_stiffness=mass * (section.frequency_ratio * section.pitch_frequency) ** 2,
        pitch_stiffness=inertia_ea * section.pitch_frequency**2,
        damping_factor=0.0,
        chord=2.0 * b,
        gravity_centre=b * (1.0 + section.elastic_axis + section.static_unbalance),
        elastic_axis=offset,
        aileron_position=offset,
        lift_slope=2.0 * np.pi,
        span=1.0,
    )
