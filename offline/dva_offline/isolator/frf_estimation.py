"""Measured-data front end of chapter 5: FRF estimation and modal parameter estimation.

* H1 / H2 FRF estimates from force and response time series with Welch's averaged
  periodogram (section 5.2): the study uses 5000 Hz sampling, a 10000-point FFT and no window
  (boxcar), which are the defaults here; segments overlap by half (scipy's default).
* Stepped-sine FRF: least-squares sine fit of force and response at each excitation frequency.
* Natural frequency from the zero crossing of the FRF's real part, damping ratio from the
  half-power points (Table 5.2).
* Static stiffness by least squares from load-deflection data around the static equilibrium
  position (section 5.1, Table 5.1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FrfEstimate:
    """Welch FRF estimate.

    Attributes
    ----------
    frequency_hz : numpy.ndarray
        Shape (F,) [Hz].
    h1 : numpy.ndarray
        S_fx / S_ff, shape (F,), complex [response unit / N]; averaged over response channels.
    h2 : numpy.ndarray
        S_xx / S_xf, shape (F,), complex.
    coherence : numpy.ndarray
        |S_fx|^2 / (S_ff S_xx), shape (F,), averaged over channels, in [0, 1].
    """

    frequency_hz: np.ndarray
    h1: np.ndarray
    h2: np.ndarray
    coherence: np.ndarray


def estimate_frf(
    force,
    response,
    fs: float = 5000.0,
    nfft: int = 10000,
    window: str = "boxcar",
    noverlap: int | None = None,
) -> FrfEstimate:
    """H1 and H2 FRF estimates by Welch's method (section 5.2).

    Parameters
    ----------
    force : array_like, shape (T,)
        Input force [N].
    response : array_like, shape (T,) or (C, T)
        Response channels (e.g. three accelerometers [m/s^2]); time on the last axis. The FRFs
        of the channels are averaged, as the study averages its three accelerometers.
    fs : float
        Sampling frequency [Hz].
    nfft : int
        Segment length and FFT size [samples].
    window : str
        Window name for ``scipy.signal.get_window``; ``"boxcar"`` is no window.
    noverlap : int, optional
        Overlap in samples; default ``nfft // 2``.
    """
    force = np.asarray(force, dtype=float)
    response = np.atleast_2d(np.asarray(response, dtype=float))
    if force.ndim != 1:
        raise ValueError(f"force must be 1-D (samples), got shape {force.shape}")
    if response.ndim != 2 or response.shape[-1] != force.size:
        raise ValueError(
            f"response must have shape (T,) or (C, T) with T = {force.size}, "
            f"got {response.shape}"
        )
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(response))):
        raise ValueError("force and response must be finite (no NaN)")
    if not fs > 0:
        raise ValueError(f"fs must be > 0 Hz, got {fs}")
    if not isinstance(nfft, (int, np.integer)) or nfft < 8:
        raise ValueError(f"nfft must be an integer >= 8, got {nfft!r}")
    if force.size < nfft:
        raise ValueError(f"time series has {force.size} samples, fewer than nfft = {nfft}")
    from scipy import signal  # imported here: scipy.signal costs ~1 s at CLI start-up

    kw = dict(fs=fs, window=window, nperseg=nfft, noverlap=noverlap, nfft=nfft)
    freq, s_ff = signal.welch(force, **kw)
    h1s, h2s, cohs = [], [], []
    for x in response:
        _, s_fx = signal.csd(force, x, **kw)
        _, s_xx = signal.welch(x, **kw)
        with np.errstate(divide="ignore", invalid="ignore"):
            h1s.append(s_fx / s_ff)
            h2s.append(s_xx / np.conj(s_fx))
            cohs.append(np.abs(s_fx) ** 2 / (s_ff * s_xx))
    return FrfEstimate(freq, np.mean(h1s, 0), np.mean(h2s, 0), np.mean(cohs, 0))


def sine_phasor(time_s, x, frequency_hz: float) -> complex:
    """Complex amplitude X of x(t) ~ Re(X exp(j 2 pi f t)) + offset by linear least squares."""
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.shape != x.shape or t.ndim != 1:
        raise ValueError("time_s and x must be 1-D arrays of the same length")
    wt = 2 * np.pi * frequency_hz * t
    basis = np.column_stack([np.cos(wt), -np.sin(wt), np.ones_like(t)])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return complex(coef[0], coef[1])


def stepped_sine_frf(time_s, force, response, frequency_hz) -> np.ndarray:
    """FRF from fixed-frequency sine records (section 5.2: 0.5 Hz steps).

    Parameters
    ----------
    time_s : array_like, shape (T,)
        Sample times [s] shared by all records.
    force, response : array_like, shape (F, T)
        One record per excitation frequency [N] and [response unit].
    frequency_hz : array_like, shape (F,)
        Excitation frequencies [Hz].

    Returns
    -------
    numpy.ndarray
        Shape (F,), complex: response phasor / force phasor.
    """
    force = np.atleast_2d(np.asarray(force, dtype=float))
    response = np.atleast_2d(np.asarray(response, dtype=float))
    freqs = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    if force.shape != response.shape or force.shape[0] != freqs.size:
        raise ValueError(
            "force and response must have shape (F, T) with F = len(frequency_hz), got "
            f"{force.shape}, {response.shape} and {freqs.size}"
        )
    return np.array(
        [sine_phasor(time_s, y, f) / sine_phasor(time_s, x, f)
         for x, y, f in zip(force, response, freqs)]
    )


def _check_frf(frequency, h):
    frequency = np.asarray(frequency, dtype=float)
    h = np.asarray(h, dtype=complex)
    if frequency.ndim != 1 or h.shape != frequency.shape:
        raise ValueError("frequency and h must be 1-D arrays of the same length")
    if frequency.size < 5:
        raise ValueError(f"need at least 5 frequency points, got {frequency.size}")
    if np.any(np.diff(frequency) <= 0):
        raise ValueError("frequency must be strictly increasing")
    return frequency, h


def natural_frequency_zero_crossing(frequency, h) -> float:
    """Frequency where Re(H) changes sign nearest the magnitude peak (Table 5.2).

    For receptance or accelerance of a single-mass system Re(H) vanishes where the dynamic
    stiffness's real part equals m w^2. Linear interpolation between the bracketing points;
    returns the same unit as ``frequency``.
    """
    frequency, h = _check_frf(frequency, h)
    re = h.real
    sign_change = np.nonzero(np.sign(re[:-1]) * np.sign(re[1:]) < 0)[0]
    if sign_change.size == 0:
        raise ValueError(
            "the real part of the FRF does not change sign: no resonance inside the data, so "
            "no natural frequency"
        )
    peak = np.argmax(np.abs(h))
    i = sign_change[np.argmin(np.abs(sign_change - peak))]
    f0, f1, r0, r1 = frequency[i], frequency[i + 1], re[i], re[i + 1]
    return float(f0 - r0 * (f1 - f0) / (r1 - r0))


@dataclass(frozen=True)
class HalfPower:
    """Half-power (-3 dB) damping estimate.

    Attributes
    ----------
    damping_ratio : float
        (f2 - f1) / (2 f_n) [-].
    lower, upper : float
        Half-power frequencies f1, f2 (unit of the input frequency).
    peak : float
        Frequency of the magnitude peak.
    """

    damping_ratio: float
    lower: float
    upper: float
    peak: float


def half_power_damping(frequency, h, natural_frequency: float | None = None) -> HalfPower:
    """Damping ratio from the half-power points of |H| (Table 5.2).

    ``natural_frequency`` (same unit as ``frequency``) defaults to the peak frequency.
    """
    frequency, h = _check_frf(frequency, h)
    mag = np.abs(h)
    p = int(np.argmax(mag))
    level = mag[p] / np.sqrt(2.0)
    below = np.nonzero(mag[:p] < level)[0]
    above = np.nonzero(mag[p:] < level)[0]
    if below.size == 0 or above.size == 0:
        if p == 0 or p == mag.size - 1:
            where = "lowest" if p == 0 else "highest"
            raise ValueError(
                f"the largest |H| is at the {where} frequency: no resonance peak inside the "
                "data, so no half-power damping"
            )
        side = "below" if below.size == 0 else "above"
        raise ValueError(
            f"|H| does not fall to the half-power level (peak / sqrt 2) {side} the resonance "
            "peak inside the data, so no half-power damping"
        )
    i = below[-1]
    f1 = np.interp(level, [mag[i], mag[i + 1]], [frequency[i], frequency[i + 1]])
    j = p + above[0]
    f2 = np.interp(level, [mag[j], mag[j - 1]], [frequency[j], frequency[j - 1]])
    fn = frequency[p] if natural_frequency is None else natural_frequency
    return HalfPower(float((f2 - f1) / (2.0 * fn)), float(f1), float(f2), float(frequency[p]))


@dataclass(frozen=True)
class StaticStiffness:
    """Least-squares static stiffness.

    Attributes
    ----------
    stiffness_n_per_m : float
        Slope of load vs deflection [N/m].
    offset_n : float
        Load at zero deflection of the fitted line [N].
    n_points : int
        Points used.
    rms_residual_n : float
        RMS of the load residuals [N].
    """

    stiffness_n_per_m: float
    offset_n: float
    n_points: int
    rms_residual_n: float


def static_stiffness_from_load_deflection(
    deflection_m, load_n, center_m: float | None = None, half_width_m: float | None = None
) -> StaticStiffness:
    """Static stiffness by least squares over loading and unloading data (section 5.1).

    Parameters
    ----------
    deflection_m, load_n : array_like, shape (P,)
        Deflections [m] and loads [N] (loading and unloading branches together).
    center_m, half_width_m : float, optional
        Use only points with |deflection - center| <= half_width (the range of the frequency
        response experiment about the static equilibrium x_o). Default: all points.
    """
    x = np.asarray(deflection_m, dtype=float)
    f = np.asarray(load_n, dtype=float)
    if x.ndim != 1 or x.shape != f.shape:
        raise ValueError("deflection_m and load_n must be 1-D arrays of the same length")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(f))):
        raise ValueError("deflection_m and load_n must be finite (no NaN)")
    keep = np.ones(x.size, dtype=bool)
    if center_m is not None or half_width_m is not None:
        if center_m is None or half_width_m is None or not half_width_m > 0:
            raise ValueError("give both center_m and a positive half_width_m")
        keep = np.abs(x - center_m) <= half_width_m
    if keep.sum() < 2 or np.ptp(x[keep]) == 0:
        raise ValueError("need at least two distinct deflections to fit a static stiffness")
    a = np.column_stack([x[keep], np.ones(keep.sum())])
    (slope, offset), *_ = np.linalg.lstsq(a, f[keep], rcond=None)
    resid = f[keep] - a @ np.array([slope, offset])
    return StaticStiffness(
        float(slope), float(offset), int(keep.sum()), float(np.sqrt(np.mean(resid**2)))
    )
