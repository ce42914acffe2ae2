"""Single-mass isolator represented by a general Maxwell model (study eq. 3.1-3.2, 4.1-4.2).

A mass ``m`` sits on a Voigt pair (spring ``k`` parallel to damper ``c``) and ``n`` Maxwell
elements (spring ``k_i`` in series with damper ``c_i``) in parallel. ``n = 0`` is the Voigt model,
``n = 1`` the Maxwell-Voigt (M-V) model, ``n = 2`` the M-M-V model.

Everything here is a pure function of the parameters and the frequency, so other tools (the
model-discrepancy loop) can wrap :func:`dynamic_stiffness` / :func:`frf` directly. SI units:
kg, N/m, N s/m, rad/s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

QUANTITIES = ("receptance", "accelerance", "transmissibility", "stiffness")


@dataclass(frozen=True)
class MaxwellModel:
    """Parameters of a general Maxwell isolator model (study Fig. 4.1).

    Attributes
    ----------
    mass : float
        Isolated mass m [kg], > 0.
    k : float
        Primary spring stiffness [N/m] (the static stiffness of the mount).
    c : float
        Primary damping coefficient [N s/m]. The study allows negative values (Tables 5.5-5.6).
    maxwell_k : tuple of float
        Spring stiffness k_i of each Maxwell element [N/m], each > 0.
    maxwell_c : tuple of float
        Damping coefficient c_i of each Maxwell element [N s/m], each > 0.
    """

    mass: float
    k: float
    c: float
    maxwell_k: tuple[float, ...] = ()
    maxwell_c: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        for name in ("mass", "k", "c"):
            value = getattr(self, name)
            if not isinstance(value, (int, float, np.floating, np.integer)):
                raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
            if not np.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value}")
        if self.mass <= 0:
            raise ValueError(f"mass must be > 0 kg, got {self.mass}")
        if self.k <= 0:
            raise ValueError(f"k must be > 0 N/m, got {self.k}")
        ks = tuple(float(v) for v in self.maxwell_k)
        cs = tuple(float(v) for v in self.maxwell_c)
        if len(ks) != len(cs):
            raise ValueError(
                f"maxwell_k and maxwell_c must have the same length, got {len(ks)} and {len(cs)}"
            )
        for name, values in (("maxwell_k", ks), ("maxwell_c", cs)):
            if not all(np.isfinite(v) and v > 0 for v in values):
                raise ValueError(f"{name} must be finite and > 0, got {values}")
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "k", float(self.k))
        object.__setattr__(self, "c", float(self.c))
        object.__setattr__(self, "maxwell_k", ks)
        object.__setattr__(self, "maxwell_c", cs)

    @property
    def n_elements(self) -> int:
        """Number of Maxwell elements n."""
        return len(self.maxwell_k)

    @property
    def time_constants(self) -> np.ndarray:
        """Time constants tau_i = c_i / k_i [s], shape (n,)."""
        return np.asarray(self.maxwell_c) / np.asarray(self.maxwell_k)

    @property
    def static_stiffness(self) -> float:
        """Static stiffness K(0) [N/m]: Maxwell elements carry no static load, so it is k."""
        return self.k

    def with_elements(self, maxwell_k, maxwell_c) -> MaxwellModel:
        """Return a copy with other Maxwell elements (same m, k, c)."""
        return MaxwellModel(self.mass, self.k, self.c, tuple(maxwell_k), tuple(maxwell_c))


@dataclass(frozen=True)
class ModalProperties:
    """Modal properties from the complex eigenvalue pair of the state matrix (eq. 4.2).

    Attributes
    ----------
    natural_frequency_rad_s : float
        Undamped natural frequency omega_n = |lambda| [rad/s].
    damping_ratio : float
        zeta = -Re(lambda) / |lambda|.
    eigenvalue : complex
        The eigenvalue of the pair with positive imaginary part [1/s].
    eigenvalues : numpy.ndarray
        All n + 2 eigenvalues, shape (n + 2,), complex.
    """

    natural_frequency_rad_s: float
    damping_ratio: float
    eigenvalue: complex
    eigenvalues: np.ndarray

    @property
    def damped_frequency_rad_s(self) -> float:
        """Damped natural frequency Im(lambda) [rad/s]."""
        return float(self.eigenvalue.imag)

    @property
    def is_stable(self) -> bool:
        """True when every eigenvalue has a negative real part."""
        return bool(np.all(self.eigenvalues.real < 0))


def state_matrix(model: MaxwellModel) -> np.ndarray:
    """State matrix A of eq. (4.2) for the state (x', x, x_1, ..., x_n).

    The study's printed matrix has typos in the rows of x_2..x_n; the rows here follow from
    eq. (4.1): c_i x_i' = k_i (x - x_i), i.e. x_i' = (x - x_i) / tau_i.

    Returns
    -------
    numpy.ndarray
        Shape (n + 2, n + 2) [SI, 1/s and 1/s^2 entries].
    """
    if not isinstance(model, MaxwellModel):
        raise TypeError(f"model must be a MaxwellModel, got {type(model).__name__}")
    n = model.n_elements
    ks = np.asarray(model.maxwell_k)
    a = np.zeros((n + 2, n + 2))
    a[0, 0] = -model.c / model.mass
    a[0, 1] = -(model.k + ks.sum()) / model.mass
    a[0, 2:] = ks / model.mass
    a[1, 0] = 1.0
    inv_tau = 1.0 / model.time_constants
    a[2 + np.arange(n), 1] = inv_tau
    a[2 + np.arange(n), 2 + np.arange(n)] = -inv_tau
    return a


def modal_properties(model: MaxwellModel) -> ModalProperties:
    """Natural frequency and damping ratio of the complex eigenvalue pair (section 3.2, 4.1).

    Raises
    ------
    ValueError
        If the state matrix has no complex eigenvalue pair (the mass mode is overdamped).
    """
    eig = np.linalg.eigvals(state_matrix(model))
    scale = np.max(np.abs(eig))
    upper = eig[eig.imag > 1e-9 * scale]
    if upper.size == 0:
        raise ValueError(
            "model has no complex eigenvalue pair (overdamped): natural frequency and damping "
            "ratio are undefined"
        )
    # With negative parameters there can be more than one pair; the mass mode is the one with
    # the largest imaginary part (the Maxwell states alone only give real eigenvalues).
    lam = complex(upper[np.argmax(upper.imag)])
    wn = abs(lam)
    return ModalProperties(float(wn), float(-lam.real / wn), lam, np.sort_complex(eig))


def _as_omega(omega_rad_s) -> np.ndarray:
    omega = np.asarray(omega_rad_s, dtype=float)
    if omega.ndim > 1:
        raise ValueError(f"omega_rad_s must be a scalar or 1-D array, got shape {omega.shape}")
    if not np.all(np.isfinite(omega)) or np.any(omega < 0):
        raise ValueError("omega_rad_s must be finite and >= 0")
    return omega


def maxwell_element_stiffness(k_i, c_i, s) -> np.ndarray:
    """Dynamic stiffness of Maxwell elements, k_i c_i s / (k_i + c_i s) (eq. 4.8 with s = j w).

    Parameters
    ----------
    k_i, c_i : array_like, shape (n,)
        Element stiffness [N/m] and damping [N s/m].
    s : array_like, shape (N,)
        Laplace variable [1/s] (complex).

    Returns
    -------
    numpy.ndarray
        Shape (n, N), complex [N/m].
    """
    k_i = np.asarray(k_i, dtype=float)[:, None]
    c_i = np.asarray(c_i, dtype=float)[:, None]
    s = np.asarray(s, dtype=complex)[None, :]
    return k_i * c_i * s / (k_i + c_i * s)


def dynamic_stiffness(omega_rad_s, k, c, maxwell_k=(), maxwell_c=()) -> np.ndarray:
    """Complex stiffness K(w) = k + j w c + sum_i j w c_i k_i / (k_i + j w c_i).

    A clean function of the parameters and the frequency (no model object needed).

    Parameters
    ----------
    omega_rad_s : array_like, shape (N,)
        Angular frequencies [rad/s], >= 0.
    k, c : float
        Primary stiffness [N/m] and damping [N s/m].
    maxwell_k, maxwell_c : array_like, shape (n,)
        Maxwell element parameters [N/m], [N s/m].

    Returns
    -------
    numpy.ndarray
        Shape (N,), complex [N/m].
    """
    omega = _as_omega(omega_rad_s)
    s = 1j * np.atleast_1d(omega)
    total = k + c * s
    if len(maxwell_k):
        total = total + maxwell_element_stiffness(maxwell_k, maxwell_c, s).sum(axis=0)
    return total.reshape(omega.shape) if omega.ndim else total[0]


def frf_from_stiffness(omega_rad_s, stiffness, mass: float, quantity: str) -> np.ndarray:
    """Convert a complex stiffness K(w) of the mount into an FRF of the mass on that mount.

    receptance x/f = 1 / (K - m w^2); accelerance a/f = -w^2 x/f;
    transmissibility (force to base over applied force, equal to base-motion transmissibility)
    = K / (K - m w^2); stiffness = K.
    """
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")
    omega = _as_omega(omega_rad_s)
    stiffness = np.asarray(stiffness, dtype=complex)
    if quantity == "stiffness":
        return stiffness
    denom = stiffness - mass * omega**2
    if quantity == "receptance":
        return 1.0 / denom
    if quantity == "accelerance":
        return -(omega**2) / denom
    return stiffness / denom


def frf(model: MaxwellModel, omega_rad_s, quantity: str = "receptance") -> np.ndarray:
    """Frequency response of the model at ``omega_rad_s`` [rad/s], shape (N,), complex.

    ``quantity`` is one of ``receptance`` [m/N], ``accelerance`` [(m/s^2)/N],
    ``transmissibility`` [-] or ``stiffness`` [N/m].
    """
    if not isinstance(model, MaxwellModel):
        raise TypeError(f"model must be a MaxwellModel, got {type(model).__name__}")
    stiffness = dynamic_stiffness(
        omega_rad_s, model.k, model.c, model.maxwell_k, model.maxwell_c
    )
    return frf_from_stiffness(omega_rad_s, stiffness, model.mass, quantity)


def characteristic_function(model: MaxwellModel, s) -> np.ndarray:
    """D(s) = m s^2 + c s + k + sum k_i c_i s / (k_i + c_i s); its zeros are the eigenvalues.

    Multiplying by prod(k_i + c_i s) gives the characteristic polynomial of eq. (4.2).
    """
    s = np.atleast_1d(np.asarray(s, dtype=complex))
    total = model.mass * s**2 + model.c * s + model.k
    if model.n_elements:
        total = total + maxwell_element_stiffness(model.maxwell_k, model.maxwell_c, s).sum(0)
    return total


def target_eigenvalue(natural_frequency_rad_s: float, damping_ratio: float) -> complex:
    """lambda = -zeta w_n + j w_n sqrt(1 - zeta^2) for an underdamped pair."""
    if not natural_frequency_rad_s > 0:
        raise ValueError(
            f"natural_frequency_rad_s must be > 0, got {natural_frequency_rad_s}"
        )
    if not 0 <= damping_ratio < 1:
        raise ValueError(f"damping_ratio must be in [0, 1), got {damping_ratio}")
    w, z = natural_frequency_rad_s, damping_ratio
    return complex(-z * w, w * np.sqrt(1.0 - z * z))
