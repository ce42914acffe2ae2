"""Measured FRF data in memory: validation, conversion to receptance, unit sanity checks.

No file access here (that is :mod:`dva_offline.isolator.isolator_io`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dva_offline.isolator.frf_estimation import (
    half_power_damping,
    natural_frequency_zero_crossing,
)

INPUT_QUANTITIES = ("receptance", "accelerance", "stiffness")
MIN_POINTS = 10
# m w_n^2 / k and |K(low f)| / k of real mounts are O(1)-O(10); a factor near 1000 means kN/m,
# mm or g were given where SI was expected.
UNIT_RATIO_LIMIT = 100.0


@dataclass(frozen=True)
class FrfData:
    """A measured FRF.

    Attributes
    ----------
    frequency_hz : numpy.ndarray
        Shape (N,), strictly increasing, >= 0 [Hz].
    values : numpy.ndarray
        Shape (N,), complex; receptance [m/N], accelerance [(m/s^2)/N] or complex dynamic
        stiffness [N/m] according to ``quantity``.
    quantity : str
        One of ``receptance``, ``accelerance``, ``stiffness``.
    covariates : dict of str to numpy.ndarray
        Extra columns kept by name (e.g. excitation level, temperature), each shape (N,).
    """

    frequency_hz: np.ndarray
    values: np.ndarray
    quantity: str
    covariates: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        f = np.asarray(self.frequency_hz, dtype=float)
        v = np.asarray(self.values, dtype=complex)
        if self.quantity not in INPUT_QUANTITIES:
            raise ValueError(f"quantity must be one of {INPUT_QUANTITIES}, got {self.quantity!r}")
        if f.ndim != 1 or v.shape != f.shape:
            raise ValueError(
                f"frequency_hz and values must be 1-D of equal length, got {f.shape}, {v.shape}"
            )
        if f.size < MIN_POINTS:
            raise ValueError(f"too few frequency points: {f.size} (need at least {MIN_POINTS})")
        bad = np.nonzero(~np.isfinite(f))[0]
        if bad.size:
            raise ValueError(f"frequency_hz is NaN or infinite at point {bad[0]}")
        bad = np.nonzero(~np.isfinite(v))[0]
        if bad.size:
            raise ValueError(f"FRF value is NaN or infinite at point {bad[0]}")
        if np.any(f < 0):
            raise ValueError("frequency_hz must be >= 0")
        steps = np.nonzero(np.diff(f) <= 0)[0]
        if steps.size:
            i = steps[0]
            raise ValueError(
                f"frequency_hz must be strictly increasing: point {i + 1} ({f[i + 1]} Hz) "
                f"follows {f[i]} Hz"
            )
        for name, col in self.covariates.items():
            if np.shape(col) != f.shape:
                raise ValueError(f"covariate {name!r} must have {f.size} values")
        object.__setattr__(self, "frequency_hz", f)
        object.__setattr__(self, "values", v)

    @property
    def omega_rad_s(self) -> np.ndarray:
        """Angular frequencies [rad/s], shape (N,)."""
        return 2.0 * np.pi * self.frequency_hz


def to_receptance(data: FrfData, mass: float) -> tuple[np.ndarray, np.ndarray]:
    """Receptance x/f [m/N] of the mass on the mount, dropping 0 Hz where undefined.

    Returns
    -------
    omega_rad_s, receptance : numpy.ndarray
        Shapes (M,), M <= N.
    """
    if not mass > 0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    w = data.omega_rad_s
    if data.quantity == "receptance":
        return w, data.values
    if data.quantity == "accelerance":
        keep = w > 0
        return w[keep], data.values[keep] / -(w[keep] ** 2)
    return w, 1.0 / (data.values - mass * w**2)


@dataclass(frozen=True)
class ModalEstimate:
    """w_n from the zero crossing of Re(H), zeta from the half-power points."""

    natural_frequency_rad_s: float
    damping_ratio: float


def estimate_modal(omega_rad_s, receptance) -> ModalEstimate:
    """Natural frequency [rad/s] and damping ratio from a receptance (Table 5.2 method)."""
    wn = natural_frequency_zero_crossing(omega_rad_s, receptance)
    zeta = half_power_damping(omega_rad_s, receptance, wn).damping_ratio
    return ModalEstimate(wn, zeta)


def check_units(
    omega_rad_s, receptance, mass: float, static_stiffness: float, natural_frequency_rad_s: float
) -> None:
    """Raise ValueError when mass, static stiffness or FRF look off by a factor ~1000.

    Two independent ratios, both O(1)-O(10) for a real mount: m w_n^2 / k (does not involve
    the FRF scale) and Re(1/H) / (k - m w^2) at the lowest nonzero frequency (skipped when that
    frequency is above 0.7 w_static, where inertia dominates).
    """
    if not static_stiffness > 0:
        raise ValueError(f"static stiffness must be > 0 N/m, got {static_stiffness}")
    ratio = mass * natural_frequency_rad_s**2 / static_stiffness
    if ratio > UNIT_RATIO_LIMIT:
        raise ValueError(
            f"mass * natural_frequency^2 / static_stiffness = {ratio:.3g} (expected 0.5-10): "
            "is the static stiffness in kN/m instead of N/m, or the mass in g instead of kg?"
        )
    if ratio < 1.0 / UNIT_RATIO_LIMIT:
        raise ValueError(
            f"mass * natural_frequency^2 / static_stiffness = {ratio:.3g} (expected 0.5-10): "
            "is the static stiffness in N/mm (x1000) or the mass in tonnes?"
        )
    w = np.asarray(omega_rad_s)
    h = np.asarray(receptance)
    i = int(np.argmax(w > 0))
    inertia = mass * w[i] ** 2
    if inertia > 0.5 * static_stiffness:
        return  # lowest frequency too close to resonance for a static comparison
    # Re(1/H) = Re K(w) - m w^2 >= k - m w^2 for a passive mount, and Re K / k = O(1)-O(10).
    k_low = float(np.real(1.0 / h[i]))
    r2 = k_low / (static_stiffness - inertia)
    if r2 > UNIT_RATIO_LIMIT or r2 < 1.0 / UNIT_RATIO_LIMIT:
        raise ValueError(
            f"low-frequency dynamic stiffness of the FRF ({k_low + inertia:.4g} N/m at "
            f"{w[i] / (2 * np.pi):.3g} Hz) is {r2:.3g} x the static stiffness: FRF units look "
            "off by ~1000 (e.g. mm/N, g, or stiffness in kN/m)"
        )
