"""Residual characterisation: noise floor, whiteness, localisation, phase trend, covariates.

Every function works on a *normalised complex residual* sequence
``r_j = w_j (yhat_j - y_j)`` (for frequency responses ``w_j = 1 / |y_j|``, so ``r_j`` is the
relative error of point j), ordered along an axis (frequency, time) within groups (test
conditions: one sweep per temperature or excitation level). Differences and lags never cross a
group boundary. Pure numerics, domain independent.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

MAD_TO_SIGMA = 1.482602218505602  # 1 / Phi^-1(3/4): MAD of a normal sample -> its std


def _check_residual(residual, groups) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(residual, dtype=complex)
    if r.ndim != 1 or r.size < 3:
        raise ValueError(f"residual must be 1-D with >= 3 points, got shape {r.shape}")
    if not np.all(np.isfinite(r)):
        raise ValueError("residual must be finite")
    g = np.zeros(r.size, dtype=int) if groups is None else np.asarray(groups)
    if g.shape != r.shape:
        raise ValueError(f"groups must have shape {r.shape}, got {g.shape}")
    return r, g


def _runs(groups: np.ndarray) -> list[np.ndarray]:
    """Indices of each group, in the order the points are given."""
    return [np.nonzero(groups == label)[0] for label in np.unique(groups)]


@dataclass(frozen=True)
class NoiseFloor:
    """Noise level estimated from the data alone (no model), by the smoothness of the response.

    Attributes
    ----------
    sigma : float
        RMS of the normalised complex noise, sqrt(E|eps|^2) [-] (relative for FRFs).
    sigma_real, sigma_imag : float
        Standard deviation of its real and imaginary parts [-].
    n_differences : int
        Number of second differences used.
    method : str
        Description of the estimator.
    """

    sigma: float
    sigma_real: float
    sigma_imag: float
    n_differences: int
    method: str


def noise_floor(residual, groups=None) -> NoiseFloor:
    """Noise floor from second differences of the residual along the axis.

    The noise-free part of the residual (model error) is smooth along the axis, so the second
    difference ``d_j = r_{j-1} - 2 r_j + r_{j+1}`` (within each group) removes it, while for
    independent noise of variance s^2 per component Var(d) = 6 s^2. The median absolute
    deviation makes the estimate robust to narrow features (a sharp resonance in the residual)
    that second differences do not remove: s = 1.4826 MAD(d) / sqrt(6), per component.

    Parameters
    ----------
    residual : array_like, shape (N,)
        Normalised complex residual (model fitted or not: any smooth part cancels).
    groups : array_like of int, shape (N,), optional
        Condition label of each point; differences stay within a group.
    """
    r, g = _check_residual(residual, groups)
    diffs = [r[idx][:-2] - 2.0 * r[idx][1:-1] + r[idx][2:] for idx in _runs(g) if idx.size >= 3]
    if not diffs:
        raise ValueError("every group has fewer than 3 points: cannot estimate the noise floor")
    d = np.concatenate(diffs)

    def comp(x):
        return MAD_TO_SIGMA * float(np.median(np.abs(x - np.median(x)))) / np.sqrt(6.0)

    s_re, s_im = comp(d.real), comp(d.imag)
    return NoiseFloor(
        float(np.hypot(s_re, s_im)), s_re, s_im, int(d.size),
        "1.4826 MAD of second differences along the axis / sqrt(6), per component",
    )


@dataclass(frozen=True)
class WhitenessTest:
    """Ljung-Box portmanteau test on the real and imaginary parts of the residual.

    Attributes
    ----------
    statistic : float
        Q = sum over both parts of n (n + 2) sum_{k=1..h} rho_k^2 / (n - k).
    dof : int
        Degrees of freedom 2 h of the chi-square reference.
    p_value : float
        P(chi2(dof) >= Q): small means the residual is correlated along the axis (not white).
    lags : int
        h.
    lag1_autocorrelation : float
        rho_1 averaged over the two parts (near 0 for white noise, near 1 for a smooth error).
    """

    statistic: float
    dof: int
    p_value: float
    lags: int
    lag1_autocorrelation: float


def _autocorrelation(x: np.ndarray, runs: list[np.ndarray], lags: int) -> np.ndarray:
    """rho_1..rho_h pooled over groups (lag products only within a group)."""
    x = x - x.mean()
    denom = float(np.sum(x * x))
    rho = np.zeros(lags)
    if denom == 0:
        return rho
    for k in range(1, lags + 1):
        rho[k - 1] = sum(float(np.dot(x[idx][:-k], x[idx][k:])) for idx in runs
                         if idx.size > k) / denom
    return rho


def ljung_box(residual, groups=None, lags: int = 10) -> WhitenessTest:
    """Ljung-Box test of the residual's whiteness along the axis (real and imaginary parts).

    Parameters
    ----------
    residual : array_like, shape (N,)
        Normalised complex residual, ordered along the axis within each group.
    groups : array_like of int, shape (N,), optional
    lags : int
        Number of autocorrelation lags h (>= 1, < the shortest group).
    """
    r, g = _check_residual(residual, groups)
    if not isinstance(lags, (int, np.integer)) or lags < 1:
        raise ValueError(f"lags must be an integer >= 1, got {lags!r}")
    runs = _runs(g)
    n = r.size
    if lags >= min(idx.size for idx in runs):
        raise ValueError(f"lags ({lags}) must be smaller than the shortest group")
    q = 0.0
    rho1 = []
    for part in (r.real, r.imag):
        rho = _autocorrelation(part, runs, lags)
        q += n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, lags + 1))))
        rho1.append(rho[0])
    dof = 2 * lags
    return WhitenessTest(q, dof, float(stats.chi2.sf(q, dof)), int(lags), float(np.mean(rho1)))


@dataclass(frozen=True)
class Localisation:
    """Where along the axis the residual power lies, in bands.

    Attributes
    ----------
    edges : numpy.ndarray
        Band edges, shape (B + 1,) [axis unit].
    rms : numpy.ndarray
        RMS of |r| in each band, shape (B,) [-] (NaN for an empty band).
    excess_fraction : numpy.ndarray
        Share of the residual power above the noise floor that lies in each band, shape (B,).
    peak_band : int
        Band with the largest excess power.
    peak_center : float
        Geometric (log bands) or arithmetic centre of that band [axis unit].
    concentration : float
        Share of the excess power in the two largest bands (2/B for an even spread, 1 for a
        localised error).
    """

    edges: np.ndarray
    rms: np.ndarray
    excess_fraction: np.ndarray
    peak_band: int
    peak_center: float
    concentration: float


def localise(axis, residual, sigma: float, n_bands: int = 8, log: bool = True) -> Localisation:
    """Residual power per band of the axis, relative to the noise floor ``sigma``.

    Parameters
    ----------
    axis : array_like, shape (N,)
        Position of each point (frequency [Hz] for FRFs); > 0 when ``log``.
    residual : array_like, shape (N,)
        Normalised complex residual.
    sigma : float
        Noise floor (:func:`noise_floor`), >= 0.
    n_bands : int
        Number of bands B >= 1, equal width on a log (``log=True``) or linear axis.
    """
    x = np.asarray(axis, dtype=float)
    r, _ = _check_residual(residual, None)
    if x.shape != r.shape:
        raise ValueError(f"axis must have shape {r.shape}, got {x.shape}")
    if not sigma >= 0:
        raise ValueError(f"sigma must be >= 0, got {sigma}")
    if not isinstance(n_bands, (int, np.integer)) or n_bands < 1:
        raise ValueError(f"n_bands must be an integer >= 1, got {n_bands!r}")
    if log and np.any(x <= 0):
        raise ValueError("axis must be > 0 for log bands")
    lo, hi = float(x.min()), float(x.max())
    edges = np.geomspace(lo, hi, n_bands + 1) if log else np.linspace(lo, hi, n_bands + 1)
    band = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bands - 1)
    power = np.abs(r) ** 2
    rms = np.full(n_bands, np.nan)
    excess = np.zeros(n_bands)
    for b in range(n_bands):
        sel = band == b
        if sel.any():
            rms[b] = np.sqrt(power[sel].mean())
            excess[b] = max(power[sel].sum() - sel.sum() * sigma**2, 0.0)
    total = excess.sum()
    frac = excess / total if total > 0 else np.zeros(n_bands)
    peak = int(np.argmax(frac))
    center = (np.sqrt(edges[peak] * edges[peak + 1]) if log
              else 0.5 * (edges[peak] + edges[peak + 1]))
    return Localisation(edges, rms, frac, peak, float(center), float(np.sort(frac)[-2:].sum()))


@dataclass(frozen=True)
class PhaseTrend:
    """Straight-line trends of the phase and log-magnitude of y / yhat along the axis.

    Attributes
    ----------
    phase_slope : float
        d angle(y / yhat) / d axis [rad per axis unit]; a time delay tau gives -2 pi tau per Hz.
    phase_slope_std : float
        Its standard error.
    equivalent_delay_s : float
        -phase_slope / (2 pi) [s] when the axis is frequency in Hz.
    log_magnitude_slope : float
        d ln|y / yhat| / d axis [per axis unit].
    log_magnitude_slope_std : float
    """

    phase_slope: float
    phase_slope_std: float
    equivalent_delay_s: float
    log_magnitude_slope: float
    log_magnitude_slope_std: float


def _line(x, y):
    a = np.column_stack([np.ones_like(x), x])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - a @ coef
    dof = max(x.size - 2, 1)
    cov = np.linalg.pinv(a.T @ a) * float(res @ res) / dof
    return float(coef[1]), float(np.sqrt(max(cov[1, 1], 0.0)))


def phase_trend(axis, ratio) -> PhaseTrend:
    """Least-squares slopes of angle(q) and ln|q| against the axis, q = y / yhat.

    Parameters
    ----------
    axis : array_like, shape (N,)
        Frequency [Hz] (or another axis).
    ratio : array_like, shape (N,)
        Measured over modelled response, complex, nonzero.
    """
    x = np.asarray(axis, dtype=float)
    q = np.asarray(ratio, dtype=complex)
    if x.shape != q.shape or x.ndim != 1 or x.size < 3:
        raise ValueError("axis and ratio must be 1-D of equal length >= 3")
    if np.any(q == 0) or not np.all(np.isfinite(q)):
        raise ValueError("ratio must be finite and nonzero")
    ps, ps_std = _line(x, np.angle(q))
    ms, ms_std = _line(x, np.log(np.abs(q)))
    return PhaseTrend(ps, ps_std, -ps / (2 * np.pi), ms, ms_std)


@dataclass(frozen=True)
class CovariateDependence:
    """Does the residual depend on a covariate (beyond its dependence on the axis)?

    Cells are (covariate level, axis band). The test compares the residual's cell means with
    its band means (pooled over levels): an F test of the extra level-by-band structure.

    Attributes
    ----------
    name : str
    levels : numpy.ndarray
        Distinct covariate values, shape (L,).
    rms_per_level : numpy.ndarray
        RMS of |r| per level, shape (L,) [-].
    f_statistic : float
    p_value : float
        Small: the residual changes with the covariate.
    explained_fraction : float
        Share of the residual power explained by the level-by-band means beyond the band means.
    """

    name: str
    levels: np.ndarray
    rms_per_level: np.ndarray
    f_statistic: float
    p_value: float
    explained_fraction: float


def covariate_dependence(name: str, covariate, axis, residual, n_bands: int = 8,
                         log: bool = True) -> CovariateDependence:
    """Two-way layout test of the residual against a covariate's levels and axis bands.

    Parameters
    ----------
    name : str
        Covariate name (reported).
    covariate : array_like, shape (N,)
        Covariate value of each point (few distinct levels, e.g. temperature per sweep).
    axis : array_like, shape (N,)
        Frequency [Hz] (> 0 for log bands).
    residual : array_like, shape (N,)
        Normalised complex residual.
    """
    c = np.asarray(covariate, dtype=float)
    x = np.asarray(axis, dtype=float)
    r, _ = _check_residual(residual, None)
    if c.shape != r.shape or x.shape != r.shape:
        raise ValueError("covariate, axis and residual must have the same shape")
    levels, level_idx = np.unique(c, return_inverse=True)
    rms = np.array([np.sqrt(np.mean(np.abs(r[level_idx == i]) ** 2))
                    for i in range(levels.size)])
    if levels.size < 2:
        return CovariateDependence(name, levels, rms, 0.0, 1.0, 0.0)
    lo, hi = float(x.min()), float(x.max())
    edges = np.geomspace(lo, hi, n_bands + 1) if log else np.linspace(lo, hi, n_bands + 1)
    band = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bands - 1)
    z = np.column_stack([r.real, r.imag])

    def rss(labels):
        total = 0.0
        for lab in np.unique(labels):
            sel = labels == lab
            total += float(np.sum((z[sel] - z[sel].mean(axis=0)) ** 2))
        return total, np.unique(labels).size

    rss_band, n_band = rss(band)
    rss_cell, n_cell = rss(band * levels.size + level_idx)
    df1 = 2 * (n_cell - n_band)
    df2 = 2 * (r.size - n_cell)
    if df1 <= 0 or df2 <= 0 or rss_cell <= 0:
        return CovariateDependence(name, levels, rms, 0.0, 1.0, 0.0)
    f = ((rss_band - rss_cell) / df1) / (rss_cell / df2)
    frac = (rss_band - rss_cell) / float(np.sum(z**2))
    return CovariateDependence(name, levels, rms, float(f), float(stats.f.sf(f, df1, df2)),
                               float(frac))


@dataclass(frozen=True)
class ResidualFeatures:
    """Everything the loop reports about a residual.

    Attributes
    ----------
    noise : NoiseFloor
    whiteness : WhitenessTest
    localisation : Localisation
    phase : PhaseTrend or None
        None when the domain has no complex ratio y / yhat to offer.
    covariates : tuple of CovariateDependence
    rms : float
        RMS of |r| over the points given [-].
    """

    noise: NoiseFloor
    whiteness: WhitenessTest
    localisation: Localisation
    phase: PhaseTrend | None
    covariates: tuple[CovariateDependence, ...]
    rms: float


def characterise(axis, residual, groups=None, covariates=None, ratio=None, sigma=None,
                 n_bands: int = 8, log: bool = True, lags: int = 10) -> ResidualFeatures:
    """Run all residual tests.

    Parameters
    ----------
    axis : array_like, shape (N,)
        Frequency [Hz] or another ordering axis.
    residual : array_like, shape (N,)
        Normalised complex residual, ordered along the axis within each group.
    groups : array_like of int, shape (N,), optional
    covariates : dict of str to array_like (N,), optional
    ratio : array_like, shape (N,), optional
        y / yhat for the phase trend.
    sigma : float, optional
        Noise floor to use (default: :func:`noise_floor` of this residual).
    """
    r, g = _check_residual(residual, groups)
    noise = noise_floor(r, g)
    s = noise.sigma if sigma is None else float(sigma)
    shortest = min(idx.size for idx in _runs(g))
    white = ljung_box(r, g, max(1, min(lags, shortest // 4)))
    loc = localise(axis, r, s, n_bands, log)
    phase = phase_trend(axis, ratio) if ratio is not None else None
    deps = tuple(covariate_dependence(name, col, axis, r, n_bands, log)
                 for name, col in (covariates or {}).items())
    return ResidualFeatures(noise, white, loc, phase, deps, float(np.sqrt(np.mean(np.abs(r)**2))))
