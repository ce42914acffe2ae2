"""Frequency responses of flight segments: the estimator and its exact expectation.

Estimator (``estimate_segments``): the flight is cut into segments where airspeed, density
and the reported c2 are nearly constant; each segment into Hann windows of ``N`` samples
overlapping by half (Hann: leakage of the lightly damped modes is 2-7 times smaller than with a
boxcar window of the same length). Per window and accelerometer channel the DFTs X (aileron
force) and Y (acceleration) give

    H1_seg(f_k) = sum_w conj(X_w) Y_w / sum_w |X_w|^2,

and the coherence over the whole run of constant condition gives each point's expected
random relative error ``eps^2 = (1 - g^2) / (2 n_w g^2)`` (Bendat & Piersol), which sets the
weights of the discrepancy engine.

Expectation (``windowed_frf``): for a white force through the sampled (ZOH) wing, with impulse
response h_0 = D, h_m = C A_d^(m-1) B_d, the estimator's expectation is exactly

    E[H1](w) = sum_{m=0}^{N-1} h_m rho(m) e^{-j w m},

the FRF seen through the window's normalised autocorrelation rho (leakage and resolution bias
included). In modal coordinates (A = V diag(s) V^-1, lambda = e^{s dt}) the sum is a few
geometric series in lambda e^{-j w} e^{j 2 pi k/N}, evaluated in closed form. Pure numerics.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def hann(n: int) -> np.ndarray:
    """Periodic Hann window of ``n`` samples."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


@dataclass(frozen=True)
class Taper:
    """A window's normalised autocorrelation rho(m) = r(m)/r(0), 0 <= m < N, written exactly
    as sum_k u^(k m) (a_k + b_k m), u = e^{j 2 pi / N}, k in (-1, 0, 1) (true for the boxcar
    and the Hann window: their products w_t w_(t-m) hold only these harmonics)."""

    n: int
    window: np.ndarray
    a: np.ndarray  # (3,) complex, k = -1, 0, 1
    b: np.ndarray


def taper(window) -> Taper:
    """:class:`Taper` of ``window`` (boxcar or Hann); ValueError if rho is not of that form."""
    w = np.asarray(window, dtype=float)
    n = w.size
    r = np.correlate(w, w, "full")[n - 1:]
    rho = r / r[0]
    m = np.arange(n)
    ks = np.array([-1, 0, 1])
    u = np.exp(2j * np.pi * np.outer(m, ks) / n)
    basis = np.concatenate([u, m[:, None] * u], axis=1)
    coef, *_ = np.linalg.lstsq(basis, rho.astype(complex), rcond=None)
    if np.max(np.abs(basis @ coef - rho)) > 1e-9:
        raise ValueError("window autocorrelation is not of the boxcar/Hann form")
    return Taper(n, w, coef[:3], coef[3:])


def _sums(lam: np.ndarray, lam_m: np.ndarray, lam_m1: np.ndarray, y: np.ndarray, n: int):
    """A0 = sum_{k=0}^{n-2} p^k and A1 = sum_{k=0}^{n-2} k p^k for p = lam y with y^n = 1;
    ``lam_m``, ``lam_m1`` are lam^(n-1), lam^(n-2) (no complex powers over all bins)."""
    m = n - 1
    p = lam * y
    one = 1.0 - p
    near = np.abs(one) < 1e-9
    one = np.where(near, 1.0, one)
    pm = lam_m / y  # p^m with y^m = y^(n-1) = 1 / y
    pm1 = lam_m1 / (y * y)
    a0 = np.where(near, m, (1.0 - pm) / one)
    a1 = np.where(near, m * (m - 1) / 2.0, p * (1.0 - m * pm1 + (m - 1) * pm) / one**2)
    return a0, a1


def windowed_frf(a, b, c_out, d_out, omega_dt, tap: Taper, dt: float,
                 delay_samples=0.0) -> np.ndarray:
    """Expected windowed H1 estimate of ``y = C x + D f`` for ``x' = A x + B f`` (ZOH).

    E[H1](w) = sum_{m=0}^{N-1} h_m rho(m) e^{-j w m} with h_0 = D, h_m = C A_d^(m-1) B_d, in
    modal coordinates a sum of geometric series (closed form, no loop over m).

    Parameters
    ----------
    a : (K, n, n) continuous-time state matrices
    b : (K, n) input vectors
    c_out : (K, p, n), d_out : (K, p) output matrices (accelerations)
    omega_dt : (F,) DFT bin frequencies 2 pi k / N [rad/sample], 0 < omega_dt < pi
    tap : Taper
        Of the estimator's window (N = ``tap.n``).
    dt : float
        Sample interval [s].
    delay_samples : float or (K,)
        Output delay [samples] (sensor delay), applied as e^{-j w d} (the window's taper over
        the d shifted samples is neglected: d << N).

    Returns
    -------
    (K, p, F) complex
    """
    s, v = np.linalg.eig(a)
    bm = np.linalg.solve(v, b[..., None].astype(complex))[..., 0]  # (K, n)
    cm = c_out @ v  # (K, p, n)
    sdt = s * dt
    lam = np.exp(sdt)
    small = np.abs(sdt) < 1e-8
    gain = np.where(small, dt, (lam - 1.0) / np.where(small, 1.0, s))  # ZOH input integral
    bd = gain * bm  # (K, n)
    n = tap.n
    g = 0.0
    lam_c = lam[..., None]
    lam_m = np.exp((n - 1) * sdt)[..., None]
    lam_m1 = np.exp((n - 2) * sdt)[..., None]
    for k, ak, bk in zip((-1, 0, 1), tap.a, tap.b):
        if abs(ak) < 1e-14 and abs(bk) < 1e-14:
            continue
        y = np.exp(-1j * (np.asarray(omega_dt, dtype=float) - 2 * np.pi * k / n))  # (F,)
        a0, a1 = _sums(lam_c, lam_m, lam_m1, y, n)
        # sum_{m>=1} lam^(m-1) y^m (a + b m) = y (a A0 + b (A1 + A0))
        g = g + y * (ak * a0 + bk * (a1 + a0))
    resid = cm * bd[:, None, :]  # (K, p, n)
    h = d_out[..., None] + np.einsum("kpn,knf->kpf", resid, g)
    d = np.asarray(delay_samples, dtype=float)
    if np.any(d != 0):
        d = np.broadcast_to(d, (a.shape[0],))[:, None, None]
        h = np.exp(-1j * d * np.asarray(omega_dt)) * h
    return h


@dataclass(frozen=True)
class SegmentFrf:
    """H1 estimates of one flight segment.

    Attributes
    ----------
    start, stop : int
        Sample range [start, stop) of the segment.
    windows : numpy.ndarray
        (n_w, 2) sample ranges of its windows.
    window_force_power : numpy.ndarray
        (n_w,) sum |X_w|^2 over the band (weights of the windows in E[H1]).
    h : numpy.ndarray
        (p, F) H1 estimates per channel and bin.
    eps : numpy.ndarray
        (p, F) expected random relative error of each estimate.
    run : int
        Index of the run of constant condition the segment belongs to.
    """

    start: int
    stop: int
    windows: np.ndarray
    window_force_power: np.ndarray
    h: np.ndarray
    eps: np.ndarray
    run: int


def runs_of_constant_condition(columns, tolerance: float = 0.02, min_length: int = 1):
    """Sample ranges where every column stays within ``tolerance`` (relative) of its value at
    the range's start; NaN samples end a range and are skipped.

    Parameters
    ----------
    columns : sequence of (n,) arrays
    tolerance : float
    min_length : int
        Shorter runs are dropped.

    Returns
    -------
    list of (start, stop)
    """
    cols = [np.asarray(c, dtype=float) for c in columns]
    n = cols[0].size
    bad = np.zeros(n, dtype=bool)
    for c in cols:
        bad |= ~np.isfinite(c)
    runs, i = [], 0
    while i < n:
        if bad[i]:
            i += 1
            continue
        ref = [c[i] for c in cols]
        j = i + 1
        # vectorised scan: first sample that leaves the band or is NaN
        stop = n
        for c, r in zip(cols, ref):
            off = np.abs(c[i:] - r) > tolerance * max(abs(r), 1e-12)
            off |= bad[i:]
            hit = np.flatnonzero(off)
            if hit.size:
                stop = min(stop, i + int(hit[0]))
        j = max(stop, i + 1)
        if j - i >= min_length:
            runs.append((i, j))
        i = j
    return runs


def estimate_segments(force, outputs, runs, tap: Taper, bins: np.ndarray,
                      segment_windows: int) -> list[SegmentFrf]:
    """H1 estimates of segments of ``segment_windows`` windows within each run.

    Parameters
    ----------
    force : (n,) [N]
    outputs : (p, n) accelerations
    runs : list of (start, stop)
        From :func:`runs_of_constant_condition`.
    tap : Taper
        The window (N samples); windows overlap by half.
    bins : (F,) int
        DFT bin indices kept (the band).
    segment_windows : int
        Windows per segment; a run's windows are shared out evenly between
        max(1, n_run_windows // segment_windows) segments.
    """
    out = []
    n_window, hop = tap.n, tap.n // 2
    win = tap.window
    for r, (start, stop) in enumerate(runs):
        n_w = (stop - start - n_window) // hop + 1
        if n_w < 2:
            continue
        idx = start + np.arange(n_w)[:, None] * hop + np.arange(n_window)
        x = np.fft.rfft(win * force[idx], axis=-1)[:, bins]  # (n_w, F)
        y = np.fft.rfft(win * outputs[:, idx], axis=-1)[..., bins]  # (p, n_w, F)
        sxy = np.conj(x) * y
        sxx = np.abs(x) ** 2
        syy = np.abs(y) ** 2
        # Coherence over the whole run (more windows, less bias than per segment).
        coh = np.abs(sxy.sum(1)) ** 2 / (sxx.sum(0) * syy.sum(1))
        coh = np.clip(coh, 1e-6, 1.0 - 1e-9)
        n_seg = max(1, n_w // segment_windows)
        edges = np.linspace(0, n_w, n_seg + 1).round().astype(int)
        for a, b in zip(edges[:-1], edges[1:]):
            h = sxy[:, a:b].sum(1) / sxx[a:b].sum(0)
            eps = np.sqrt((1.0 - coh) / (2.0 * (b - a) * coh))
            wins = np.stack([idx[a:b, 0], idx[a:b, -1] + 1], axis=1)
            out.append(SegmentFrf(int(wins[0, 0]), int(wins[-1, 1]), wins,
                                  sxx[a:b].sum(1), h, eps, r))
    return out
