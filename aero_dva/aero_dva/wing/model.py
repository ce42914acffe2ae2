"""Pitch-plunge wing with an optional DVA in state-space form (Zhang (2006) eq. 6.1-6.16).

Conventions (Zhang (2006) eq. 6.1, 6.11; REP 103 units)
-----------------------------------------------
- ``w`` [m]: plunge of the gravity centre, positive down; ``alpha`` [rad]: pitch, positive nose
  up; the aileron force ``f_a`` [N] is positive down.
- Chordwise positions ``x`` [m] are measured from the gravity centre, positive toward the
  leading edge, so the point at ``x`` moves ``w - x * alpha`` (eq. 6.11 for the DVA). The
  leading edge is at ``x = c0`` and the trailing edge at ``x = c0 - c``.
- The wing's plunge spring acts at the elastic axis ``x = c_e`` (stiffness matrix of eq. 6.4);
  the aileron force acts at ``x = c_a`` (input vector ``b = [1, -c_a]``).

State vector ``y = [q, q', extra]`` with ``q = [w, alpha]`` or ``[w, alpha, x1]`` (``x1`` the
absorber mass displacement, positive down) and ``extra`` = the Maxwell element's spring
deflection (if any) followed by the aerodynamic lag states (finite-state aerodynamics).

Outputs: displacements ``[w, alpha, w_le, stroke]`` with ``w_le = w - c0 alpha`` the leading
edge and ``stroke = x1 - (w - l_a alpha)`` the absorber mass relative to its attachment;
accelerations ``[w'', alpha'', w_le'']``.

The assembly is affine in a handful of "features" of the flight condition and absorber
setting, ``F = sum_j phi_j F_j`` with ``phi = [1, U, rho U, rho U^2, k1, c_v, r, m_on]``
(see :meth:`AeroelasticModel.features`), so thousands of conditions assemble at once.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.aerodynamics import (
    QuasiSteadyAero,
    TheodorsenAero,
    WagnerAero,
    aero_matrices,
)
from aero_dva.wing.channel_names import ACCELERATION_NAMES, DISPLACEMENT_NAMES
from aero_dva.wing.checks import finite, non_negative, positive, real_array

__all__ = [
    "DISPLACEMENT_NAMES",
    "ACCELERATION_NAMES",
    "LEADING_EDGE",
    "MAXWELL_RATE_LIMIT",
    "AeroelasticModel",
    "StateSpace",
    "WingParameters",
]

#: Row of the leading edge in the displacements and in the accelerations (the same in both).
LEADING_EDGE = DISPLACEMENT_NAMES.index("leading_edge")

MAXWELL_RATE_LIMIT = 1.0e8
"""[1/s] Above this relaxation rate ``k2/c2`` the Maxwell element is replaced by its limit, a
plain damper ``c2`` (relative error ~ omega c2/k2 < 1e-6 in the band of interest); this keeps
``c2 -> 0`` finite and well conditioned instead of dividing by zero."""

N_FEATURES = 8
FEATURE_NAMES = ("one", "U", "rho*U", "rho*U^2", "k1", "c_damper", "maxwell_rate", "maxwell_on")


@dataclass(frozen=True)
class WingParameters:
    """Structural and geometric parameters of the pitch-plunge wing (Zhang (2006) eq. 6.1-6.4).

    Parameters
    ----------
    mass : float
        ``m`` [kg].
    inertia : float
        ``I`` [kg m^2], pitch moment of inertia about the gravity centre.
    plunge_stiffness : float
        ``k`` [N/m].
    pitch_stiffness : float
        ``k_alpha`` [N m/rad].
    damping_factor : float
        ``beta`` [s], structural damping ``C = beta K`` (eq. 6.3).
    chord : float
        ``c`` [m].
    gravity_centre : float
        ``c0`` [m], distance from the leading edge back to the gravity centre, in ``[0, c]``.
    elastic_axis : float
        ``c_e`` [m], position of the plunge spring from the gravity centre, positive toward
        the leading edge.
    aileron_position : float
        ``c_a`` [m], where the aileron force acts, from the gravity centre, positive toward
        the leading edge; must lie on the chord.
    lift_slope : float
        ``dC_L/dalpha`` [1/rad].
    span : float
        [m] The study's forces are per unit span while its masses are totals; ``span``
        multiplies the aerodynamic forces (1.0 reproduces the printed equations). The study is
        inconsistent about its airspeeds (figure list: U_cr ~ 800 m/s; section 7.1.1:
        ~100 m/s); the reference wing keeps 100 m/s with an effective span (docs/wing.md).
    """

    mass: float
    inertia: float
    plunge_stiffness: float
    pitch_stiffness: float
    damping_factor: float
    chord: float
    gravity_centre: float
    elastic_axis: float
    aileron_position: float
    lift_slope: float = 2.0 * np.pi
    span: float = 1.0

    def __post_init__(self):
        for name in ("mass", "inertia", "plunge_stiffness", "pitch_stiffness", "chord",
                     "lift_slope", "span"):
            object.__setattr__(self, name, positive(getattr(self, name), name))
        object.__setattr__(self, "damping_factor",
                           non_negative(self.damping_factor, "damping_factor"))
        for name in ("gravity_centre", "elastic_axis", "aileron_position"):
            object.__setattr__(self, name, finite(getattr(self, name), name))
        if not 0.0 <= self.gravity_centre <= self.chord:
            raise ValueError(
                f"gravity_centre must lie on the chord [0, {self.chord}] m, "
                f"got {self.gravity_centre}"
            )
        self.check_on_chord(self.aileron_position, "aileron_position")

    @property
    def leading_edge(self) -> float:
        """[m] Position of the leading edge from the gravity centre (= ``c0``)."""
        return self.gravity_centre

    @property
    def trailing_edge(self) -> float:
        """[m] Position of the trailing edge from the gravity centre (= ``c0 - c``, < 0)."""
        return self.gravity_centre - self.chord

    def check_on_chord(self, position: float, name: str = "position") -> float:
        """Raise ValueError naming ``name`` unless ``position`` lies on the chord."""
        x = finite(position, name)
        tol = 1e-12 * self.chord
        if not self.trailing_edge - tol <= x <= self.leading_edge + tol:
            raise ValueError(
                f"{name} = {x} m is outside the chord: it must lie between the trailing edge "
                f"{self.trailing_edge:g} m and the leading edge {self.leading_edge:g} m "
                "(measured from the gravity centre, positive toward the leading edge)"
            )
        return x

    def replace(self, **changes) -> WingParameters:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class StateSpace:
    """Continuous-time model ``y' = A y + B f_a`` with its outputs.

    Attributes
    ----------
    a : ndarray, shape (n, n)
    b : ndarray, shape (n,)
        Input vector of the aileron force [N].
    c_displacement : ndarray, shape (4, n)
        Rows: plunge [m], pitch [rad], leading edge [m], absorber stroke [m].
    c_acceleration : ndarray, shape (3, n)
    d_acceleration : ndarray, shape (3,)
        Accelerations ``= c_acceleration @ y + d_acceleration * f_a``: plunge [m/s^2],
        pitch [rad/s^2], leading edge [m/s^2].
    state_names : tuple of str
    """

    a: np.ndarray
    b: np.ndarray
    c_displacement: np.ndarray
    c_acceleration: np.ndarray
    d_acceleration: np.ndarray
    state_names: tuple


def _absorber_vector(position: float) -> np.ndarray:
    """``u`` with ``u @ q = w - l_a alpha - x1`` (eq. 6.11: D = c1 u u^T, G = k1 u u^T)."""
    return np.array([1.0, -position, -1.0])


class AeroelasticModel:
    """The wing, its absorber and its aerodynamics, ready to assemble at any condition.

    Parameters
    ----------
    wing : WingParameters
    absorber : PassiveAbsorber or MaxwellAbsorber or None
    aero : QuasiSteadyAero or WagnerAero
        :class:`TheodorsenAero` has no time-domain form; use
        :meth:`frequency_frozen` (p-k flutter) for it.

    Notes
    -----
    The tunable damper ("damping" below) is ``c2`` of a Maxwell absorber or ``c1`` of a
    passive one; passing ``None`` uses the absorber's own value.
    """

    def __init__(self, wing: WingParameters, absorber=None, aero=None):
        if not isinstance(wing, WingParameters):
            raise TypeError(f"wing must be WingParameters, got {type(wing).__name__}")
        if absorber is not None and not isinstance(absorber, (PassiveAbsorber, MaxwellAbsorber)):
            raise TypeError(f"absorber must be an absorber or None, got {type(absorber).__name__}")
        aero = QuasiSteadyAero() if aero is None else aero
        if not isinstance(aero, (QuasiSteadyAero, WagnerAero, TheodorsenAero)):
            raise TypeError(f"aero must be an aerodynamic model, got {type(aero).__name__}")
        if absorber is not None:
            wing.check_on_chord(absorber.position, "absorber position")
        self.wing = wing
        self.absorber = absorber
        self.aero = aero
        self.n_dof = 2 if absorber is None else 3
        self.has_maxwell = isinstance(absorber, MaxwellAbsorber)
        self.n_lag = 2 if isinstance(aero, WagnerAero) else 0
        self.n_extra = int(self.has_maxwell) + self.n_lag
        self.n_states = 2 * self.n_dof + self.n_extra
        names = ["plunge", "pitch", "absorber"][: self.n_dof]
        self.state_names = tuple(
            names + [f"{n}_rate" for n in names]
            + (["maxwell_deflection"] if self.has_maxwell else [])
            + [f"aero_lag_{i + 1}" for i in range(self.n_lag)]
        )
        self._build()

    # -- assembly ---------------------------------------------------------------------------
    def _structure(self):
        w, n = self.wing, self.n_dof
        mass = np.zeros((n, n))
        stiff = np.zeros((n, n))
        mass[0, 0], mass[1, 1] = w.mass, w.inertia
        k, ce = w.plunge_stiffness, w.elastic_axis
        stiff[:2, :2] = [[k, -k * ce], [-k * ce, w.pitch_stiffness + k * ce**2]]
        if self.absorber is not None:
            mass[2, 2] = self.absorber.mass
        force = np.zeros(n)
        force[:2] = [1.0, -w.aileron_position]
        return mass, stiff, w.damping_factor * stiff, force

    def _build(self):
        n, ns = self.n_dof, self.n_states
        mass, stiff, damp, force = self._structure()
        aero_mats = None
        if not isinstance(self.aero, TheodorsenAero):
            aero_mats = aero_matrices(self.wing, self.aero)
        f = np.zeros((N_FEATURES, ns, ns))
        iq, iv = slice(0, n), slice(n, 2 * n)
        f[0, iq, iv] = np.eye(n)
        f[0, iv, iq] = -stiff
        f[0, iv, iv] = -damp
        mass_rho = np.zeros((n, n))
        if aero_mats is not None:
            mass_rho[:2, :2] = aero_mats.mass
            f[2, n:n + 2, n:n + 2] -= aero_mats.damping
            f[3, n:n + 2, 0:2] -= aero_mats.stiffness
        if self.absorber is not None:
            u = _absorber_vector(self.absorber.position)
            uu = np.outer(u, u)
            f[4, iv, iq] = -uu  # k1
            f[5, iv, iv] = -uu  # c1, or c2 in the plain-damper limit
            if self.has_maxwell:
                i_d = 2 * n
                f[7, iv, i_d] = self.absorber.series_stiffness * u  # k2 * delta on q
                f[0, i_d, iv] = -u  # delta' = x1' - (w' - l_a alpha') - r delta
                f[6, i_d, i_d] = -1.0
        if self.n_lag:
            i0 = 2 * n + int(self.has_maxwell)
            il = slice(i0, i0 + self.n_lag)
            f[3, n:n + 2, il] -= aero_mats.lag_force
            f[0, il, n:n + 2] = aero_mats.lag_velocity
            f[1, il, 0:2] = aero_mats.lag_displacement
            f[1, il, il] = -np.diag(aero_mats.lag_decay)
        self._features = f
        self._mass = mass
        self._mass_rho = mass_rho
        self._force = force
        self._inv_mass = np.linalg.inv(mass)
        self._force_rows = self._inv_mass @ force  # B's velocity rows (air adding no mass)
        self._mass_depends_on_rho = bool(np.any(mass_rho))
        out = np.zeros((4, ns))
        c0 = self.wing.leading_edge
        out[0, 0], out[1, 1] = 1.0, 1.0
        out[2, 0], out[2, 1] = 1.0, -c0
        if self.absorber is not None:
            out[3, :3] = [-1.0, self.absorber.position, 1.0]
        self._c_displacement = out
        acc = np.zeros((3, n))
        acc[0, 0], acc[1, 1] = 1.0, 1.0
        acc[2, 0], acc[2, 1] = 1.0, -c0
        self._acc_select = acc

    # -- features ---------------------------------------------------------------------------
    def features(self, airspeed, density, damping=None, stiffness=None) -> np.ndarray:
        """Feature vectors ``phi`` (..., 8) of the conditions (arguments broadcast together).

        Parameters
        ----------
        airspeed : float or array_like
            ``U`` [m/s], >= 0.
        density : float or array_like
            ``rho`` [kg/m^3], >= 0.
        damping : float or array_like, optional
            Tunable damper [N s/m] (``c2`` Maxwell, ``c1`` passive); default the absorber's.
        stiffness : float or array_like, optional
            Absorber spring ``k1`` [N/m]; default the absorber's.
        """
        u = real_array(airspeed, "airspeed")
        rho = real_array(density, "density")
        if np.any(u < 0):
            raise ValueError("airspeed must be >= 0")
        if np.any(rho < 0):
            raise ValueError("density must be >= 0")
        ab = self.absorber
        k1 = 0.0 if ab is None else (ab.stiffness if stiffness is None else stiffness)
        c = 0.0 if ab is None else (ab.damping if damping is None else damping)
        k1 = real_array(k1, "stiffness")
        c = real_array(c, "damping", allow_inf=self.has_maxwell)
        if np.any(k1 < 0):
            raise ValueError("stiffness must be >= 0")
        if np.any(c < 0):
            raise ValueError("damping must be >= 0")
        return self._features_of(u, rho, k1, c)

    def _features_of(self, u, rho, k1, c) -> np.ndarray:
        """:meth:`features` of float arrays that were already checked."""
        u, rho, k1, c = np.broadcast_arrays(u, rho, k1, c)
        phi = np.zeros(u.shape + (N_FEATURES,))
        phi[..., 0] = 1.0
        phi[..., 1] = u
        phi[..., 2] = rho * u
        phi[..., 3] = rho * u * u
        phi[..., 4] = k1
        if self.has_maxwell:
            k2 = self.absorber.series_stiffness
            # a subnormal c2 overflows the rate: the plain-damper limit below replaces it
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                rate = np.where(np.isinf(c), 0.0, k2 / np.where(c > 0, c, 1.0))
            plain = (c * MAXWELL_RATE_LIMIT < k2) & (k2 > 0)  # includes c = 0
            phi[..., 5] = np.where(plain, c, 0.0)
            phi[..., 6] = np.where(plain, MAXWELL_RATE_LIMIT, rate)
            phi[..., 7] = np.where(plain, 0.0, 1.0)
        else:
            phi[..., 5] = c
        return phi

    def _inv_mass_at(self, density):
        if not self._mass_depends_on_rho:
            return self._inv_mass
        rho = np.asarray(density, dtype=float)[..., None, None]
        return np.linalg.inv(self._mass + rho * self._mass_rho)

    def matrices(self, airspeed, density, damping=None, stiffness=None):
        """System matrices at the given conditions (broadcast, vectorised).

        Returns
        -------
        a : ndarray, shape (..., n, n)
        b : ndarray, shape (..., n)
        """
        phi = self.features(airspeed, density, damping, stiffness)
        rho = np.broadcast_to(np.asarray(density, dtype=float), phi.shape[:-1])
        return self.matrices_from_features(phi, rho)

    def matrices_unchecked(self, airspeed: np.ndarray, density: np.ndarray, damping=None):
        """:meth:`matrices` of float arrays (K,) the caller has already checked (>= 0, no NaN;
        ``damping`` may be inf for a Maxwell absorber, ``None`` for the absorber's own).

        The simulators' hot path: they check a flight's inputs once, then discretise hundreds
        of held conditions, where :meth:`features`' checks would cost more than the assembly.
        """
        ab = self.absorber
        k1 = 0.0 if ab is None else ab.stiffness
        c = 0.0 if ab is None else (ab.damping if damping is None else damping)
        phi = self._features_of(airspeed, density, k1, c)
        rho = np.broadcast_to(density, phi.shape[:-1])
        return self.matrices_from_features(phi, rho)

    def matrices_of(self, conditions) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`matrices_unchecked` of a few conditions ``[(U, rho, damping), ...]`` (floats
        the caller has already checked; ``damping`` is ignored without absorber): ``A`` (K, n,
        n), ``B`` (K, n). The features are built in plain Python, as for
        :meth:`_still_air_features`: for the handful of new conditions of a streamed block the
        array version's broadcasting costs more than the assembly."""
        ab = self.absorber
        k1 = 0.0 if ab is None else ab.stiffness
        row = self._feature_row
        if ab is None:
            phi = [row(u, rho, k1, 0.0) for u, rho, _ in conditions]
        else:
            phi = [row(u, rho, k1, c) for u, rho, c in conditions]
        return self.matrices_from_features(np.array(phi),
                                           np.array([rho for _, rho, _ in conditions]))

    def matrices_from_features(self, phi: np.ndarray, density):
        """``A, B`` from feature vectors ``phi`` (..., 8) and densities (...)."""
        a = np.einsum("...j,jab->...ab", phi, self._features)
        n = self.n_dof
        minv = self._inv_mass_at(density)
        a[..., n:2 * n, :] = minv @ a[..., n:2 * n, :]
        b = np.zeros(a.shape[:-1])
        if minv is self._inv_mass:
            b[..., n:2 * n] = self._force_rows
        else:
            b[..., n:2 * n] = minv @ self._force if minv.ndim == 2 else np.einsum(
                "...ij,j->...i", minv, self._force)
        return a, b

    def polynomial(self, density, damping=None, stiffness=None):
        """``A(U) = A0 + U A1 + U^2 A2`` at fixed density and absorber setting.

        Returns
        -------
        a0, a1, a2 : ndarray, shape (n, n)
        """
        phi = self.features(0.0, density, damping, stiffness)
        return self._polynomial_of(phi, float(density))

    def polynomial_unchecked(self, density: float, damping=None):
        """:meth:`polynomial` of a density and damper setting (floats, ``damping`` may be inf
        for a Maxwell absorber, ``None`` for the absorber's own) the caller has already
        checked: the flutter search's hot path, where :meth:`features`' checks cost more than
        the assembly."""
        ab = self.absorber
        k1 = 0.0 if ab is None else ab.stiffness
        c = 0.0 if ab is None else (ab.damping if damping is None else damping)
        return self._polynomial_of(self._still_air_features(float(density), float(k1), float(c)),
                                   float(density))

    def _still_air_features(self, rho: float, k1: float, c: float) -> np.ndarray:
        """:meth:`_features_of` at ``U = 0`` for one condition, in plain Python (the array
        version's broadcasting costs more than the assembly it feeds)."""
        return np.array(self._feature_row(0.0, 0.0, k1, c))  # U = 0: rho enters no feature

    def _feature_row(self, u: float, rho: float, k1: float, c: float) -> list:
        """:meth:`_features_of` of one checked condition, in plain Python (the same
        operations, so the same values)."""
        phi = [1.0, u, rho * u, rho * u * u, k1, c, 0.0, 0.0]
        if self.has_maxwell:
            k2 = self.absorber.series_stiffness
            if c * MAXWELL_RATE_LIMIT < k2 and k2 > 0:  # includes c = 0
                phi[6] = MAXWELL_RATE_LIMIT
            else:
                phi[5], phi[7] = 0.0, 1.0
                phi[6] = 0.0 if math.isinf(c) else k2 / (c if c > 0 else 1.0)
        return phi

    def _polynomial_of(self, phi, rho: float):
        # Rows: the features of A0 (still air), of dA/dU and of d2A/dU2 / 2.
        p = np.zeros((3, N_FEATURES))
        p[0] = phi
        p[1, 1], p[1, 2], p[2, 3] = 1.0, rho, rho
        ns, n = self.n_states, self.n_dof
        a = (p @ self._features.reshape(N_FEATURES, ns * ns)).reshape(3, ns, ns)
        a[:, n:2 * n] = self._inv_mass_at(rho) @ a[:, n:2 * n]
        return a[0], a[1], a[2]

    def state_space(self, airspeed: float, density: float, damping=None) -> StateSpace:
        """The full :class:`StateSpace` at one condition."""
        a, b = self.matrices(float(airspeed), float(density), damping)
        c_acc, d_acc = self.acceleration_output(a, b)
        return StateSpace(a, b, self._c_displacement.copy(), c_acc, d_acc, self.state_names)

    @property
    def mass_matrix(self) -> np.ndarray:
        """(n_dof, n_dof) Structural mass matrix ``diag(m, I[, m1])`` (without air)."""
        return self._mass

    @property
    def c_displacement(self) -> np.ndarray:
        """(4, n) Displacement outputs (independent of the condition)."""
        return self._c_displacement

    def acceleration_output(self, a, b):
        """Acceleration output matrices from ``A`` (..., n, n) and ``B`` (..., n)."""
        n = self.n_dof
        c_acc = self._acc_select @ a[..., n:2 * n, :]
        d_acc = np.einsum("ij,...j->...i", self._acc_select, b[..., n:2 * n])
        return c_acc, d_acc

    # -- frequency domain -------------------------------------------------------------------
    def frequency_frozen(self, airspeed: float, density: float, reduced_frequency: float,
                         damping=None) -> np.ndarray:
        """``A`` with Theodorsen's C(k) frozen at ``reduced_frequency`` (p-k method).

        Only for :class:`TheodorsenAero`; returns an (n, n) array.
        """
        return self.frequency_frozen_factory(airspeed, density, damping)(reduced_frequency)

    def frequency_frozen_factory(self, airspeed: float, density: float, damping=None):
        """A function ``k -> A(k)`` at one condition (the structural part is built once)."""
        if not isinstance(self.aero, TheodorsenAero):
            raise ValueError("frequency_frozen needs TheodorsenAero")
        phi = self.features(float(airspeed), float(density), damping)
        base = np.einsum("j,jab->ab", phi, self._features)
        n = self.n_dof
        rho, u = float(density), float(airspeed)

        def at(reduced_frequency):
            am = aero_matrices(self.wing, self.aero, reduced_frequency)
            a = base.copy()
            a[n:n + 2, n:n + 2] -= rho * u * am.damping
            a[n:n + 2, 0:2] -= rho * u * u * am.stiffness
            mass = self._mass.copy()
            mass[:2, :2] += rho * am.mass
            a[n:2 * n] = np.linalg.solve(mass, a[n:2 * n])
            return a

        return at
