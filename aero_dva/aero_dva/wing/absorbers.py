"""Dynamic vibration absorbers (DVA) attached to the wing (Zhang (2006) eq. 6.10-6.16).

Both absorbers are a mass ``m1`` moving vertically (displacement ``x1``, positive down like the
plunge ``w``) and attached at ``position`` ``l_a`` from the wing's gravity centre. The study's
eq. 6.11 fixes the kinematics: the attachment point moves ``w - l_a * alpha``, so with pitch
``alpha`` positive nose up, ``l_a`` is positive toward the leading edge.

- :class:`PassiveAbsorber`: spring ``k1`` and damper ``c1`` in parallel (eq. 6.10-6.12).
- :class:`MaxwellAbsorber`: spring ``k1`` in parallel with a Maxwell element, spring ``k2`` in
  series with the tunable damper ``c2`` (eq. 6.14-6.16). The node between ``k2`` and ``c2`` is
  massless, so the element adds one first-order state. ``c2 = inf`` locks the damper (stiffness
  ``k1 + k2``); ``c2 = 0`` frees it (stiffness ``k1``).

Units are SI inside (N/m, N s/m). The study prints N/mm and N-s/mm: convert with
:data:`N_PER_MM` and :data:`NS_PER_MM` at the boundary.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from aero_dva.wing.checks import finite, non_negative, positive

__all__ = ["N_PER_MM", "NS_PER_MM", "MaxwellAbsorber", "PassiveAbsorber", "Absorber"]

N_PER_MM = 1.0e3
"""[N/m] per [N/mm]: ``k_si = k_seed * N_PER_MM``."""
NS_PER_MM = 1.0e3
"""[N s/m] per [N-s/mm]: ``c_si = c_seed * NS_PER_MM``."""


@dataclass(frozen=True)
class PassiveAbsorber:
    """Mass on a parallel spring and damper (Zhang (2006) eq. 6.10-6.12).

    Parameters
    ----------
    mass : float
        ``m1`` [kg], > 0.
    stiffness : float
        ``k1`` [N/m], >= 0.
    damping : float
        ``c1`` [N s/m], >= 0 and finite.
    position : float
        ``l_a`` [m] from the gravity centre, positive toward the leading edge (eq. 6.11).
    """

    mass: float
    stiffness: float
    damping: float
    position: float

    def __post_init__(self):
        object.__setattr__(self, "mass", positive(self.mass, "mass"))
        object.__setattr__(self, "stiffness", non_negative(self.stiffness, "stiffness"))
        object.__setattr__(self, "damping", non_negative(self.damping, "damping"))
        object.__setattr__(self, "position", finite(self.position, "position"))

    def replace(self, **changes) -> PassiveAbsorber:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class MaxwellAbsorber:
    """Mass on spring ``k1`` in parallel with spring ``k2`` in series with damper ``c2``.

    Parameters
    ----------
    mass : float
        ``m1`` [kg], > 0.
    stiffness : float
        ``k1`` [N/m], the parallel spring, >= 0.
    series_stiffness : float
        ``k2`` [N/m], the spring of the Maxwell element, >= 0.
    damping : float
        ``c2`` [N s/m], the tunable damper, in ``[0, inf]``.
    position : float
        ``l_a`` [m] from the gravity centre, positive toward the leading edge (eq. 6.11).
    """

    mass: float
    stiffness: float
    series_stiffness: float
    damping: float
    position: float

    def __post_init__(self):
        object.__setattr__(self, "mass", positive(self.mass, "mass"))
        object.__setattr__(self, "stiffness", non_negative(self.stiffness, "stiffness"))
        object.__setattr__(
            self, "series_stiffness", non_negative(self.series_stiffness, "series_stiffness")
        )
        object.__setattr__(self, "damping", non_negative(self.damping, "damping", True))
        object.__setattr__(self, "position", finite(self.position, "position"))

    def replace(self, **changes) -> MaxwellAbsorber:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


Absorber = PassiveAbsorber | MaxwellAbsorber
