"""Voigt models matching a measured natural frequency and damping ratio (sections 3.4, 5.3.1).

Voigt Model M (mass consistent): m_v = m, k_v = m w_n^2, c_v = 2 m_v zeta w_n.
Voigt Model K (stiffness consistent): k_v = k, m_v = k_v / w_n^2, c_v = 2 m_v zeta w_n.
Their FRFs bound the FRFs of every M-V model with the same w_n and zeta (section 3.4).
"""
from __future__ import annotations

from dataclasses import dataclass

from dva_offline.isolator.maxwell_model import MaxwellModel


@dataclass(frozen=True)
class VoigtModel:
    """A Voigt model m x'' + c x' + k x = f.

    Attributes
    ----------
    name : str
        ``"M"`` (mass consistent) or ``"K"`` (stiffness consistent).
    mass : float
        [kg]
    k : float
        [N/m]
    c : float
        [N s/m]
    """

    name: str
    mass: float
    k: float
    c: float

    def as_maxwell_model(self) -> MaxwellModel:
        """The same model as a :class:`MaxwellModel` with no Maxwell elements."""
        return MaxwellModel(self.mass, self.k, self.c)


def _check_modal(natural_frequency_rad_s: float, damping_ratio: float) -> None:
    if not natural_frequency_rad_s > 0:
        raise ValueError(f"natural_frequency_rad_s must be > 0, got {natural_frequency_rad_s}")
    if not 0 <= damping_ratio < 1:
        raise ValueError(f"damping_ratio must be in [0, 1), got {damping_ratio}")


def voigt_model_m(mass: float, natural_frequency_rad_s: float, damping_ratio: float) -> VoigtModel:
    """Voigt Model M from the weighed mass [kg] (Tables 3.4, 5.3)."""
    if not mass > 0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    _check_modal(natural_frequency_rad_s, damping_ratio)
    w = natural_frequency_rad_s
    return VoigtModel("M", mass, mass * w**2, 2.0 * mass * damping_ratio * w)


def voigt_model_k(
    static_stiffness: float, natural_frequency_rad_s: float, damping_ratio: float
) -> VoigtModel:
    """Voigt Model K from the static stiffness [N/m] (Tables 3.4, 5.3)."""
    if not static_stiffness > 0:
        raise ValueError(f"static_stiffness must be > 0 N/m, got {static_stiffness}")
    _check_modal(natural_frequency_rad_s, damping_ratio)
    w = natural_frequency_rad_s
    m_v = static_stiffness / w**2
    return VoigtModel("K", m_v, static_stiffness, 2.0 * m_v * damping_ratio * w)
