"""Aerodynamic models of the pitch-plunge section, written about the gravity centre.

Coordinates follow the study (eq. 6.1-6.6): plunge ``w`` [m] of the gravity centre, positive
down; pitch ``alpha`` [rad], positive nose up; lift positive up. The chord ``c`` has its leading
edge ``c0`` ahead of the gravity centre. Forces are per unit span, multiplied by ``span``.

Every model is expressed as generalized forces ``-(rho Ma q'' + rho U Da q' + rho U^2 Ka q)``
on ``q = [w, alpha]`` plus, for the finite-state model, lag states:

- :class:`QuasiSteadyAero` -- the study's eq. 6.2/6.4: circulatory lift at the quarter chord
  driven by the downwash at the three-quarter chord, plus a pitch-rate couple. The study prints
  that couple three ways: eq. 6.4 and 6.6 give ``pi rho U c^3 / 16`` (thin-airfoil theory,
  the default ``pitch_damping="thin_airfoil"``); eq. 6.2 prints ``(pi/8) dCL/dalpha`` inside
  the bracket, which has no length dimension; with the missing ``c^2`` restored it is
  ``pi rho U c^3 (dCL/dalpha)^2 / 16`` (``pitch_damping="printed_6_2"``).
- :class:`TheodorsenAero` -- thin-airfoil theory for harmonic motion (Theodorsen's C(k)),
  used in the frequency domain (p-k flutter). The circulatory part is scaled by
  ``lift_slope / (2 pi)``; the apparent-mass terms are those of the flat plate.
- :class:`WagnerAero` -- the time-domain counterpart: Wagner's indicial function in
  R. T. Jones' two-exponential form, ``phi(s) = 1 - A1 exp(-b1 s) - A2 exp(-b2 s)`` with
  ``s = U t / b``, which gives ``C(k) ~ 1 - A1 ik/(ik + b1) - A2 ik/(ik + b2)`` and two lag
  states per section.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aero_dva.wing.checks import positive

__all__ = [
    "AERO_MODELS",
    "AeroMatrices",
    "QuasiSteadyAero",
    "TheodorsenAero",
    "WagnerAero",
    "aero_from_name",
    "section_geometry",
    "theodorsen_function",
]

PITCH_DAMPING_CHOICES = ("thin_airfoil", "printed_6_2")


@dataclass(frozen=True)
class QuasiSteadyAero:
    """The study's quasi-steady aerodynamics (eq. 6.2, 6.4, 6.6).

    Parameters
    ----------
    pitch_damping : {"thin_airfoil", "printed_6_2"}
        Which reading of the study's pitch-rate couple to use (see the module docstring).
    """

    pitch_damping: str = "thin_airfoil"

    def __post_init__(self):
        if self.pitch_damping not in PITCH_DAMPING_CHOICES:
            raise ValueError(
                f"pitch_damping must be one of {PITCH_DAMPING_CHOICES}, got {self.pitch_damping!r}"
            )

    name = "quasi-steady"


@dataclass(frozen=True)
class TheodorsenAero:
    """Theodorsen's unsteady thin-airfoil theory (frequency domain only)."""

    name = "theodorsen"


@dataclass(frozen=True)
class WagnerAero:
    """Finite-state unsteady aerodynamics from R. T. Jones' approximation of Wagner's function.

    Parameters
    ----------
    a1, b1, a2, b2 : float
        ``phi(s) = 1 - a1 exp(-b1 s) - a2 exp(-b2 s)``; defaults are Jones' 0.165, 0.0455,
        0.335, 0.3.
    """

    a1: float = 0.165
    b1: float = 0.0455
    a2: float = 0.335
    b2: float = 0.3

    def __post_init__(self):
        for name in ("a1", "b1", "a2", "b2"):
            positive(getattr(self, name), name)
        if self.a1 + self.a2 >= 1.0:
            raise ValueError("a1 + a2 must be < 1 (phi(0) > 0)")

    name = "wagner"


AERO_MODELS = {"quasi-steady": QuasiSteadyAero, "theodorsen": TheodorsenAero, "wagner": WagnerAero}


def aero_from_name(name: str):
    """Build the default aerodynamic model called ``name`` (a key of :data:`AERO_MODELS`)."""
    try:
        return AERO_MODELS[name]()
    except KeyError:
        raise ValueError(f"aero must be one of {sorted(AERO_MODELS)}, got {name!r}") from None


def theodorsen_function(k):
    """Theodorsen's function ``C(k) = H1(k) / (H1(k) + i H0(k))`` (Hankel functions, 2nd kind).

    Parameters
    ----------
    k : float or array_like
        Reduced frequency ``omega b / U`` [1], >= 0. ``C(0) = 1``.

    Returns
    -------
    complex or ndarray of complex
    """
    k_arr = np.asarray(k, dtype=float)
    if np.any(~np.isfinite(k_arr)) or np.any(k_arr < 0):
        raise ValueError("k must be finite and >= 0")
    # Imported here: scipy.special costs about a second of start-up for every node process, and
    # only the frequency-domain analyses need C(k).
    from scipy.special import hankel2

    safe = np.where(k_arr > 0, k_arr, 1.0)
    h1 = hankel2(1, safe)
    h0 = hankel2(0, safe)
    c = np.where(k_arr > 0, h1 / (h1 + 1j * h0), 1.0 + 0j)
    return c[()] if c.ndim == 0 else c


@dataclass(frozen=True)
class SectionGeometry:
    """Distances used by the aerodynamic matrices [m]; 'aft' distances are from the centre."""

    semichord: float  # b = c/2
    quarter_chord_aft: float  # c/4 - c0: quarter chord aft of the gravity centre
    three_quarter_aft: float  # 3c/4 - c0: three-quarter chord aft of the gravity centre
    centre_aft_of_mid: float  # a_cg: gravity centre aft of mid-chord, in semichords
    lift_factor: float  # span c/2 dCL/dalpha [m^2]: lift = rho U lift_factor downwash


def section_geometry(wing) -> SectionGeometry:
    """Geometry of ``wing`` (a :class:`~aero_dva.wing.model.WingParameters`)."""
    c, c0 = wing.chord, wing.gravity_centre
    return SectionGeometry(
        semichord=c / 2.0,
        quarter_chord_aft=c / 4.0 - c0,
        three_quarter_aft=3.0 * c / 4.0 - c0,
        centre_aft_of_mid=(c0 - c / 2.0) / (c / 2.0),
        lift_factor=wing.span * c / 2.0 * wing.lift_slope,
    )


@dataclass(frozen=True)
class AeroMatrices:
    """Aerodynamic matrices on ``q = [w, alpha]`` (generalized force ``-(...)``).

    ``mass`` multiplies ``rho``, ``damping`` ``rho U``, ``stiffness`` ``rho U^2`` (all 2x2).
    For the finite-state model, ``lag_force`` (2, n_lag) multiplies ``rho U^2`` times the lag
    states, and the lag states obey ``z' = lag_rate_q (n_lag, 2) q' + U lag_rate_alpha q
    - U lag_decay z`` (``lag_decay`` (n_lag,) [1/m]).
    """

    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    lag_force: np.ndarray
    lag_velocity: np.ndarray
    lag_displacement: np.ndarray
    lag_decay: np.ndarray


def _noncirculatory(g: SectionGeometry, span: float):
    """Flat-plate apparent mass and the non-circulatory pitch-rate terms about the centre."""
    b, a = g.semichord, g.centre_aft_of_mid
    f = span * np.pi * b**2
    mass = f * np.array([[1.0, -b * a], [-b * a, b**2 * (1.0 / 8.0 + a**2)]])
    damping = f * np.array([[0.0, 1.0], [0.0, b * (0.5 - a)]])
    return mass, damping


def aero_matrices(wing, aero, reduced_frequency: float | None = None) -> AeroMatrices:
    """Aerodynamic matrices of ``wing`` for ``aero``.

    Parameters
    ----------
    wing : WingParameters
    aero : QuasiSteadyAero, WagnerAero or TheodorsenAero
    reduced_frequency : float, optional
        ``k = omega b / U`` at which Theodorsen's C(k) is frozen (p-k method); required for
        :class:`TheodorsenAero` and ignored otherwise.
    """
    g = section_geometry(wing)
    d34, dac, qc = g.three_quarter_aft, g.quarter_chord_aft, g.lift_factor
    # Lift acts at the quarter chord: generalized force -[1, dac] * L.
    v_lift = np.array([1.0, dac])
    downwash_rate = np.array([1.0, d34])  # Q = w' + U alpha + d34 alpha'
    empty = np.zeros((2, 0))
    if isinstance(aero, QuasiSteadyAero):
        damping = qc * np.outer(v_lift, downwash_rate)
        c = wing.chord
        couple = wing.span * c / 2.0 * np.pi * c**2 / 8.0
        if aero.pitch_damping == "printed_6_2":
            couple *= wing.lift_slope**2
        damping[1, 1] += couple
        stiffness = qc * np.outer(v_lift, [0.0, 1.0])
        return AeroMatrices(np.zeros((2, 2)), damping, stiffness, empty, empty.T, empty.T,
                            np.zeros(0))
    mass_nc, damping_nc = _noncirculatory(g, wing.span)
    if isinstance(aero, WagnerAero):
        a0 = 1.0 - aero.a1 - aero.a2
        b = g.semichord
        damping = damping_nc + qc * a0 * np.outer(v_lift, downwash_rate)
        stiffness = qc * a0 * np.outer(v_lift, [0.0, 1.0])
        amp = np.array([aero.a1 * aero.b1, aero.a2 * aero.b2]) / b
        lag_force = qc * np.outer(v_lift, amp)
        lag_velocity = np.tile(downwash_rate, (2, 1))
        lag_displacement = np.tile([0.0, 1.0], (2, 1))
        lag_decay = np.array([aero.b1, aero.b2]) / b
        return AeroMatrices(mass_nc, damping, stiffness, lag_force, lag_velocity,
                            lag_displacement, lag_decay)
    if isinstance(aero, TheodorsenAero):
        if reduced_frequency is None:
            raise ValueError("reduced_frequency is required for Theodorsen aerodynamics")
        k = max(float(reduced_frequency), 1e-9)
        ck = complex(theodorsen_function(k))
        f_re, g_im = ck.real, ck.imag
        b = g.semichord
        # i G Q = (G b / (k U)) Q' for harmonic motion: apparent mass and damping terms.
        mass = mass_nc + qc * (g_im * b / k) * np.outer(v_lift, downwash_rate)
        damping = damping_nc + qc * np.outer(v_lift, [f_re, f_re * d34 + g_im * b / k])
        stiffness = qc * f_re * np.outer(v_lift, [0.0, 1.0])
        return AeroMatrices(mass, damping, stiffness, empty, empty.T, empty.T, np.zeros(0))
    raise TypeError(f"aero must be an aerodynamic model, got {type(aero).__name__}")
