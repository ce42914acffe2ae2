"""Noise estimates measured by the test itself: replicate sweeps and an analyzer's coherence.

The second-difference floor (:func:`.residual.noise_floor`) infers the noise from the
smoothness of one sweep; it is a robust (median-like) level, blind to noise that grows near
anti-resonances. When the file holds more, the noise is measured directly, as an RMS over the
points like the held-out error it is compared with:

* **replicates**: sweeps of one nominal condition: every covariate's sweep means differ by
  no more than that covariate's measured scatter within a sweep (its range there: the drift
  of a temperature or strain the instrument shows while it holds the condition) or 1 % of
  its spread over the file, or the user says which (``--replicates COLUMN``: sweeps with one
  value of COLUMN). Sweeps found by their covariates must also differ by noise: the
  relative differences to the first sweep, in frequency order on the lines they share, white
  by the von Neumann ratio (a permutation test at p = 0.001, :func:`white_difference`); a
  smooth difference (a resonance that moved between two levels of a force-controlled shaker
  whose force swings within each sweep by more than the levels differ) is an effect, not
  noise, and those sweeps are no replicates. On the frequency lines they share (at least 5),
  the relative scatter
  ``|y_ij - mean_j|^2 / |mean_j|^2`` summed over the m replicates and divided by m - 1
  estimates the variance of one sweep's relative noise at each line. Sweeps at different
  levels are never pooled: their difference is the effect the loop looks for.
* **coherence** gamma^2 of an H1 estimate from n_avg averages: the normalised random error of
  |H| and of its phase (rad) are both sqrt(1 - gamma^2) / (|gamma| sqrt(2 n_avg)) (Bendat &
  Piersol), so the relative complex variance is (1 - gamma^2) / (gamma^2 n_avg). Without the
  number of averages the level is unknown (it scales with 1 / n_avg): reported, not used.
"""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy.residual import NoiseFloor

__all__ = ["MIN_COMMON_LINES", "coherence_noise", "common_lines", "replicate_noise",
           "replicate_sets", "sweep_replicates", "white_difference"]

MIN_COMMON_LINES = 5  # lines replicates must share for their scatter to count
WHITE_SIGNIFICANCE = 0.001  # the loop's significance: a difference this unlikely as noise
N_PERMUTATIONS = 1999


def white_difference(values: list, frequencies: list) -> tuple[float, float]:
    """(von Neumann ratio, p-value) of the sweeps' relative differences to the first one on
    the lines they share, in frequency order, real and imaginary parts as sequences of their
    own: sum (d_j+1 - d_j)^2 / sum d_j^2, about 2 for replicates (zero-mean white noise),
    small for a smooth difference (or an offset). The p-value is that of a permutation test
    (the same values in random orders, a fixed seed): no assumption on the noise's law or on
    how its level varies along the band."""
    lines = np.sort(common_lines(frequencies))
    ys = []
    for f, v in zip(frequencies, values):
        f, v = np.asarray(f, float), np.asarray(v)
        ys.append(np.array([v[np.flatnonzero(np.isclose(f, x, rtol=1e-6, atol=0.0))[0]]
                            for x in lines]))
    y = np.array(ys)
    mean = np.abs(y.mean(axis=0))
    seqs = [part for d in (y[1:] - y[0]) / mean for part in (d.real, d.imag)]
    den = sum(float(np.sum(q**2)) for q in seqs)
    if not den > 0:
        return 2.0, 1.0
    num = sum(float(np.sum(np.diff(q) ** 2)) for q in seqs)
    rng = np.random.default_rng(0)
    perm = np.zeros(N_PERMUTATIONS)
    for q in seqs:
        perm += np.sum(np.diff(rng.permuted(np.tile(q, (N_PERMUTATIONS, 1)), axis=1),
                               axis=1) ** 2, axis=1)
    p = (1 + int(np.sum(perm <= num))) / (1 + N_PERMUTATIONS)
    return num / den, p


def sweep_replicates(covariates: list[dict], frequencies: list, tolerance: float = 0.01,
                     declared=None, values=None, notes=None) -> list[list[int]]:
    """Groups of sweeps (indices) that are replicates of one condition; only sets of two or
    more, sharing at least :data:`MIN_COMMON_LINES` frequency lines.

    ``covariates``: per sweep, name -> values per point (as measured); ``frequencies``: per
    sweep, its lines. Two sweeps are replicates when every covariate's sweep means differ by
    no more than the larger of (a) the covariate's measured scatter within a sweep (the
    larger of the two sweeps' ranges: a drift the instrument shows while it holds the
    condition) and (b) ``tolerance`` x its spread over the file. ``declared``: per sweep, the
    value of the user's replicate column (``--replicates COLUMN``): sweeps sharing a value are
    replicates, whatever their covariates. ``values``: per sweep, the measured values; a set
    found by the covariates whose differences are not white (:func:`white_difference`,
    p < 0.001) is dropped and ``notes`` (a list) says why."""
    n = len(covariates)
    names = sorted(set.intersection(*(set(c) for c in covariates))) if n else []
    means = {k: [float(np.mean(c[k])) for c in covariates] for k in names}
    ranges = {k: [float(np.ptp(c[k])) for c in covariates] for k in names}

    def same(a, b):
        if declared is not None:
            return declared[a] == declared[b]
        for k in names:
            allowed = max(ranges[k][a], ranges[k][b],
                          tolerance * (max(means[k]) - min(means[k])))
            if abs(means[k][a] - means[k][b]) > allowed:
                return False
        return True

    sets: list[list[int]] = []
    for g in range(n):
        for st in sets:
            if same(st[0], g):
                st.append(g)
                break
        else:
            sets.append([g])
    sets = [st for st in sets if len(st) >= 2
            and len(common_lines([frequencies[g] for g in st])) >= MIN_COMMON_LINES]
    if declared is not None or values is None:
        return sets
    kept = []
    for st in sets:
        eta, p = white_difference([values[g] for g in st], [frequencies[g] for g in st])
        if p >= WHITE_SIGNIFICANCE:
            kept.append(st)
        elif notes is not None:
            notes.append(f"sweeps {', '.join(map(str, st))}: covariates within their scatter in "
                         f"a sweep, but their difference is no noise (von Neumann ratio "
                         f"{eta:.2f}, about 2 for noise; permutation p = {p:.2g}): no replicates")
    return kept


def common_lines(frequencies: list) -> np.ndarray:
    """The frequency lines every sweep has (relative tolerance 1e-6)."""
    lines = np.asarray(frequencies[0], float)
    for f in frequencies[1:]:
        f = np.asarray(f, float)
        lines = lines[[bool(np.any(np.isclose(f, x, rtol=1e-6, atol=0.0))) for x in lines]]
    return lines


def replicate_sets(obs, tolerance: float = 0.01, declared=None) -> list[list[int]]:
    """:func:`sweep_replicates` of the conditions (group labels) of ``obs``, their values
    checked for a difference that is noise."""
    labels = list(np.unique(obs.groups))
    covs = [{k: np.asarray(c, float)[obs.groups == g] for k, c in obs.covariates.items()}
            for g in labels]
    freqs = [obs.axis[obs.groups == g] for g in labels]
    values = [obs.values[obs.groups == g] for g in labels]
    return [[labels[i] for i in st]
            for st in sweep_replicates(covs, freqs, tolerance, declared, values)]


def replicate_noise(obs, tolerance: float = 0.01, sets=None,
                    how: str = "") -> NoiseFloor | None:
    """RMS relative noise of one sweep from the scatter of replicate sweeps on the lines they
    share (module docstring); None when the file has no replicates. ``sets``: the replicate
    sets (condition labels), default :func:`replicate_sets`; ``how``: how they were found."""
    sets = replicate_sets(obs, tolerance) if sets is None else sets
    if not sets:
        return None
    var_re, var_im, dof = [], [], 0
    for st in sets:
        lines = common_lines([obs.axis[obs.groups == g] for g in st])
        y = []
        for g in st:
            f, v = obs.axis[obs.groups == g], obs.values[obs.groups == g]
            y.append([v[np.flatnonzero(np.isclose(f, x, rtol=1e-6, atol=0.0))[0]]
                      for x in lines])
        y = np.array(y)  # (m, lines)
        mean = y.mean(axis=0)
        rel = (y - mean) / np.abs(mean)
        m = len(st)
        var_re.append(np.sum(rel.real**2, axis=0) / (m - 1))
        var_im.append(np.sum(rel.imag**2, axis=0) / (m - 1))
        dof += (m - 1) * y.shape[1]
    s_re = float(np.sqrt(np.mean(np.concatenate(var_re))))
    s_im = float(np.sqrt(np.mean(np.concatenate(var_im))))
    n_sweeps = sum(len(st) for st in sets)
    return NoiseFloor(float(np.hypot(s_re, s_im)), s_re, s_im, int(dof),
                      f"replicates: scatter of {n_sweeps} sweeps in {len(sets)} set(s) of one "
                      "condition each, RMS over the lines they share"
                      + (f" ({how})" if how else ""))


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
