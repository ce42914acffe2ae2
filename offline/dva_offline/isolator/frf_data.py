"""Measured FRF data in memory: validation, conversion to receptance, unit sanity checks.

No file access here (that is :mod:`dva_offline.isolator.files`).
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


def select_points(
    data: FrfData,
    fmin_hz: float | None = None,
    fmax_hz: float | None = None,
    min_coherence: float | None = None,
) -> FrfData:
    """The points of ``data`` inside [fmin_hz, fmax_hz] and with coherence >= min_coherence.

    ``min_coherence`` needs a ``coherence`` covariate (as written by FRF estimation).
    Raises ValueError when fewer than ``MIN_POINTS`` points remain.
    """
    f = data.frequency_hz
    keep = np.ones(f.size, dtype=bool)
    if fmin_hz is not None:
        keep &= f >= fmin_hz
    if fmax_hz is not None:
        keep &= f <= fmax_hz
    if min_coherence is not None:
        if "coherence" not in data.covariates:
            raise ValueError("a coherence threshold needs a 'coherence' column in the FRF file")
        keep &= np.asarray(data.covariates["coherence"]) >= min_coherence
    if keep.all():
        return data
    if keep.sum() < MIN_POINTS:
        raise ValueError(
            f"only {int(keep.sum())} of {f.size} points are inside the frequency band / above "
            f"the coherence threshold (need at least {MIN_POINTS})"
        )
    cov = {name: np.asarray(col)[keep] for name, col in data.covariates.items()}
    return FrfData(f[keep], data.values[keep], data.quantity, cov)


def to_receptance(data: FrfData, mass: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Receptance x/f [m/N] of the mass on the mount, dropping 0 Hz where undefined.

    Parameters
    ----------
    data : FrfData
    mass : float or None
        Isolated mass [kg]; needed only for complex stiffness (receptance = 1/(K - m w^2)).

    Returns
    -------
    omega_rad_s, receptance : numpy.ndarray
        Shapes (M,), M <= N.
    """
    if mass is None and data.quantity == "stiffness":
        raise ValueError("converting complex stiffness to receptance needs the mass (--mass)")
    if mass is not None and not mass > 0:
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
    """w_n from the zero crossing of Re(H), zeta from the half-power points.

    Attributes
    ----------
    natural_frequency_rad_s : float
        Zero crossing of Re(H) nearest the magnitude peak [rad/s].
    damping_ratio : float
        (w_2 - w_1) / (2 w_n) [-].
    half_power_lower_rad_s, half_power_upper_rad_s : float
        Half-power frequencies w_1, w_2 [rad/s] (NaN if not computed).
    peak_rad_s : float
        Frequency of the largest |H| [rad/s] (NaN if not computed).
    """

    natural_frequency_rad_s: float
    damping_ratio: float
    half_power_lower_rad_s: float = float("nan")
    half_power_upper_rad_s: float = float("nan")
    peak_rad_s: float = float("nan")


def estimate_modal(omega_rad_s, receptance) -> ModalEstimate:
    """Natural frequency [rad/s] and damping ratio from a receptance (Table 5.2 method).

    The zero crossing of Re(H) is the same for receptance and accelerance (they differ by the
    real factor -w^2); the half-power points are taken on |receptance|.
    """
    wn = natural_frequency_zero_crossing(omega_rad_s, receptance)
    hp = half_power_damping(omega_rad_s, receptance, wn)
    return ModalEstimate(wn, hp.damping_ratio, hp.lower, hp.upper, hp.peak)


def geometry_factor(
    area_m2: float | None = None,
    thickness_m: float | None = None,
    geometry_factor_m: float | None = None,
) -> float:
    """Stiffness per unit modulus A/h [m] of a compression or shear specimen.

    Give either ``area_m2`` and ``thickness_m`` (loaded area A and thickness h of the rubber
    layer) or ``geometry_factor_m`` = A/h directly, not both. K* = E* A/h holds for a layer
    in simple shear (G*) and for compression with the modulus that applies to the specimen
    (for a bonded block the effective compression modulus, which exceeds Young's modulus as
    the rubber's dimensionless shape factor grows; fold that into ``geometry_factor_m``).
    """
    if geometry_factor_m is not None:
        if area_m2 is not None or thickness_m is not None:
            raise ValueError("give either area and thickness or the geometry factor, not both")
        if not (np.isfinite(geometry_factor_m) and geometry_factor_m > 0):
            raise ValueError(f"geometry factor A/h must be > 0 m, got {geometry_factor_m}")
        return float(geometry_factor_m)
    if area_m2 is None or thickness_m is None:
        raise ValueError(
            "converting a modulus to stiffness needs the specimen geometry: area [m^2] and "
            "thickness [m] (--area, --thickness) or A/h [m] (--geometry-factor)"
        )
    if not (np.isfinite(area_m2) and area_m2 > 0):
        raise ValueError(f"area must be > 0 m^2, got {area_m2}")
    if not (np.isfinite(thickness_m) and thickness_m > 0):
        raise ValueError(f"thickness must be > 0 m, got {thickness_m}")
    return float(area_m2 / thickness_m)


def modulus_to_stiffness(data: FrfData, factor_m: float) -> FrfData:
    """Complex stiffness K* = E* A/h [N/m] from a complex modulus E* = E' + j E'' [Pa].

    ``data.values`` hold the modulus (``data.quantity`` is ``"stiffness"``, the FRF kind the
    modulus maps onto); ``factor_m`` is A/h from :func:`geometry_factor`.
    """
    if data.quantity != "stiffness":
        raise ValueError(f"a modulus maps onto quantity 'stiffness', got {data.quantity!r}")
    if not (np.isfinite(factor_m) and factor_m > 0):
        raise ValueError(f"geometry factor A/h must be > 0 m, got {factor_m}")
    return FrfData(data.frequency_hz, data.values * factor_m, "stiffness", dict(data.covariates))


def stiffness_to_modulus(stiffness, factor_m: float) -> np.ndarray:
    """Complex modulus E* = K* h/A [Pa] from complex stiffness [N/m], shape as the input."""
    if not (np.isfinite(factor_m) and factor_m > 0):
        raise ValueError(f"geometry factor A/h must be > 0 m, got {factor_m}")
    return np.asarray(stiffness, dtype=complex) / factor_m


def frf_from_amplitude_phase(
    force_amplitude, force_phase_rad, response_amplitude, response_phase_rad
) -> np.ndarray:
    """Stepped-sine FRF H = (X/F) exp(j (phi_x - phi_f)) per step.

    Each step's force is F cos(w t + phi_f) and its response X cos(w t + phi_x). All inputs
    shape (N,); amplitudes > 0 (peak or RMS, the same for both), phases [rad].
    """
    fa, fp, ra, rp = (np.asarray(a, dtype=float) for a in
                      (force_amplitude, force_phase_rad, response_amplitude, response_phase_rad))
    if not (fa.shape == fp.shape == ra.shape == rp.shape) or fa.ndim != 1:
        raise ValueError("amplitudes and phases must be 1-D arrays of equal length")
    for name, arr in (("force amplitude", fa), ("response amplitude", ra)):
        bad = np.nonzero(~(arr > 0))[0]
        if bad.size:
            raise ValueError(f"{name} must be > 0 (got {arr[bad[0]]} at step {bad[0]})")
    return ra / fa * np.exp(1j * (rp - fp))


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


def condition_columns(covariates: dict, n_points: int) -> list[str]:
    """Covariate columns that label test conditions (few distinct values), in input order.

    A column with at most ``n_points // MIN_POINTS`` distinct values can split the rows into
    conditions of at least ``MIN_POINTS`` points each (e.g. ``temperature_c``,
    ``excitation_n``); per-point columns such as ``coherence`` have many distinct values and
    are not conditions.
    """
    limit = max(1, n_points // MIN_POINTS)
    return [name for name, col in covariates.items() if np.unique(col).size <= limit]


def split_conditions(
    frequency_hz, values, quantity: str, covariates: dict, columns
) -> list[FrfData]:
    """Split stacked FRF rows (several sweeps in one table) into one :class:`FrfData` each.

    Rows with equal values in every column of ``columns`` form one condition; conditions keep
    the order of their first row. Each condition must have strictly increasing frequencies.

    Parameters
    ----------
    frequency_hz : array_like, shape (N,)
        Frequencies [Hz] of all rows.
    values : array_like, shape (N,)
        Complex FRF values of all rows.
    quantity : str
        ``receptance``, ``accelerance`` or ``stiffness``.
    covariates : dict of str to array_like, each shape (N,)
        Extra columns; every condition keeps all of them (restricted to its rows).
    columns : sequence of str
        Names in ``covariates`` that label the conditions (empty: one condition).

    Returns
    -------
    list of FrfData
        One per condition, with the condition's rows.
    """
    f = np.asarray(frequency_hz, dtype=float)
    v = np.asarray(values, dtype=complex)
    cov = {name: np.asarray(col, dtype=float) for name, col in covariates.items()}
    for name in columns:
        if name not in cov:
            raise ValueError(f"condition column {name!r} not found; have {sorted(cov)}")
    for name, col in cov.items():
        if col.shape != f.shape:
            raise ValueError(f"covariate {name!r} must have {f.size} values")
    if not columns:
        return [FrfData(f, v, quantity, cov)]
    keys = np.column_stack([cov[name] for name in columns])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = np.asarray(inverse).reshape(-1)
    out = []
    for label in np.argsort(first):
        rows = np.nonzero(inverse == label)[0]
        where = ", ".join(f"{name} = {cov[name][rows[0]]:g}" for name in columns)
        try:
            out.append(FrfData(f[rows], v[rows], quantity, {n: c[rows] for n, c in cov.items()}))
        except ValueError as exc:
            raise ValueError(f"condition {where}: {exc}") from None
    return out
