"""Noise estimates measured by the test itself: replicate sweeps and an analyzer's coherence.

The second-difference floor (:func:`.residual.noise_floor`) infers the noise from the
smoothness of one sweep; it is a robust (median-like) level, blind to noise that grows near
anti-resonances. When the file holds more, the noise is measured directly, as an RMS over the
points like the held-out error it is compared with:

* **replicates**: sweeps of one condition (the same level of every covariate, within 1 % of
  that covariate's spread over the file) on the same frequency lines. At each line the
  relative scatter ``|y_ij - mean_j|^2 / |mean_j|^2`` summed over the m replicates and divided
  by m - 1 estimates the variance of one sweep's relative noise there. Sweeps at different
  levels are never pooled: their difference is the effect the loop looks for.
* **coherence** gamma^2 of an H1 estimate from n_avg averages: the normalised random error of
  |H| and of its phase (rad) are both sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_avg)) (Bendat &
  Piersol), so the relative complex variance is (1 - gamma^2) / (gamma^2 n_avg). Without the
  number of averages the level is unknown (it scales with 1 / n_avg): reported, not used.
"""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy.residual import NoiseFloor

__all__ = ["coherence_noise", "replicate_noise", "replicate_sets"]


def replicate_sets(obs, tolerance: float = 0.01) -> list[list[int]]:
    """Groups of conditions (labels) that are replicates of one another: the same covariate
    levels (condition means within ``tolerance`` of each covariate's spread) and the same
    frequency lines. Only sets of two or more."""
    labels = list(np.unique(obs.groups))
    means = {}
    for name, col in obs.covariates.items():
        col = np.asarray(col, float)
        means[name] = {g: float(col[obs.groups == g].mean()) for g in labels}

    def same(a, b):
        for per in means.values():
            spread = max(per.values()) - min(per.values())
            if abs(per[a] - per[b]) > tolerance * spread:
                return False
        fa, fb = obs.axis[obs.groups == a], obs.axis[obs.groups == b]
        return fa.size == fb.size and bool(np.allclose(fa, fb, rtol=1e-9, atol=0.0))

    sets: list[list[int]] = []
    for g in labels:
        for s in sets:
            if same(s[0], g):
                s.append(g)
                break
        else:
            sets.append([g])
    return [s for s in sets if len(s) >= 2]


def replicate_noise(obs, tolerance: float = 0.01) -> NoiseFloor | None:
    """RMS relative noise of one sweep from the scatter of replicate sweeps (module
    docstring); None when the file has no replicates."""
    sets = replicate_sets(obs, tolerance)
    if not sets:
        return None
    var_re, var_im, dof = [], [], 0
    for s in sets:
        y = np.array([obs.values[obs.groups == g] for g in s])  # (m, lines)
        mean = y.mean(axis=0)
        rel = (y - mean) / np.abs(mean)
        m = len(s)
        var_re.append(np.sum(rel.real**2, axis=0) / (m - 1))
        var_im.append(np.sum(rel.imag**2, axis=0) / (m - 1))
        dof += (m - 1) * y.shape[1]
    s_re = float(np.sqrt(np.mean(np.concatenate(var_re))))
    s_im = float(np.sqrt(np.mean(np.concatenate(var_im))))
    n_sweeps = sum(len(s) for s in sets)
    return NoiseFloor(float(np.hypot(s_re, s_im)), s_re, s_im, int(dof),
                      f"replicates: scatter of {n_sweeps} sweeps in {len(sets)} set(s) of one "
                      "condition each, RMS over the lines")


def coherence_noise(coherence, averages: int | None) -> tuple[NoiseFloor | None, str]:
    """RMS relative noise from an H1 estimate's coherence (module docstring) and a note.

    Returns (None, why) without the number of averages or without a usable coherence."""
    g2 = np.asarray(coherence, float)
    if g2.size == 0 or not np.all(np.isfinite(g2)) or np.any(g2 <= 0) or np.any(g2 > 1 + 1e-9):
        return None, "coherence column not usable (values must be in (0, 1])"
    per_average = float(np.sqrt(np.mean((1 - np.minimum(g2, 1.0)) / g2)))
    if averages is None:
        return None, (f"coherence column present, number of averages unknown (give --averages):"
                      f" relative noise {per_average:.4g} / sqrt(n_avg), not used")
    if not isinstance(averages, (int, np.integer)) or averages < 1:
        raise ValueError(f"averages must be an integer >= 1, got {averages!r}")
    sigma = per_average / np.sqrt(averages)
    return NoiseFloor(sigma, sigma / np.sqrt(2), sigma / np.sqrt(2), int(g2.size),
                      f"coherence: sqrt(mean (1 - gamma^2) / (gamma^2 n_avg)), n_avg = "
                      f"{averages}"), ""
