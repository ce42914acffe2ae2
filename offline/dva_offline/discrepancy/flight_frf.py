"""Frequency responses of flight segments: the H1 estimator.

The flight is cut into segments where airspeed, density and the reported c2 are nearly
constant; each segment into Hann windows of ``N`` samples overlapping by half (Hann: leakage of
the lightly damped modes is 2-7 times smaller than with a boxcar window of the same length).
Per window and accelerometer channel the DFTs X (aileron force) and Y (acceleration) give

    H1_seg(f_k) = sum_w conj(X_w) Y_w / sum_w |X_w|^2.

The flight domain applies the same estimator, on the same windows of the same force, to the
model's simulated response (:mod:`aero_dva.flight.modal_simulator`), so leakage and transients
are common to both and cancel in the residual. Pure numerics.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def hann(n: int) -> np.ndarray:
    """Periodic Hann window of ``n`` samples."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


@dataclass(frozen=True)
class SegmentFrf:
    """H1 estimates of one flight segment.

    Attributes
    ----------
    start, stop : int
        Sample range [start, stop) of the segment.
    windows : numpy.ndarray
        (n_w, 2) sample ranges of its windows.
    h : numpy.ndarray
        (p, F) H1 estimates per channel and bin.
    run : int
        Index of the run of constant condition the segment belongs to.
    """

    start: int
    stop: int
    windows: np.ndarray
    h: np.ndarray
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


def estimate_segments(force, outputs, runs, window: np.ndarray, bins: np.ndarray,
                      segment_windows: int) -> list[SegmentFrf]:
    """H1 estimates of segments of ``segment_windows`` windows within each run.

    Parameters
    ----------
    force : (n,) [N]
    outputs : (p, n) accelerations
    runs : list of (start, stop)
        From :func:`runs_of_constant_condition`.
    window : (N,) array
        The window (e.g. :func:`hann`); windows overlap by half.
    bins : (F,) int
        DFT bin indices kept (the band).
    segment_windows : int
        Windows per segment; a run's windows are shared out evenly between
        max(1, n_run_windows // segment_windows) segments.
    """
    out = []
    n_window = window.size
    hop = n_window // 2
    for r, (start, stop) in enumerate(runs):
        n_w = (stop - start - n_window) // hop + 1
        if n_w < 2:
            continue
        idx = start + np.arange(n_w)[:, None] * hop + np.arange(n_window)
        x = np.fft.rfft(window * force[idx], axis=-1)[:, bins]  # (n_w, F)
        y = np.fft.rfft(window * outputs[:, idx], axis=-1)[..., bins]  # (p, n_w, F)
        sxy = np.conj(x) * y
        sxx = np.abs(x) ** 2
        n_seg = max(1, n_w // segment_windows)
        edges = np.linspace(0, n_w, n_seg + 1).round().astype(int)
        for a, b in zip(edges[:-1], edges[1:]):
            h = sxy[:, a:b].sum(1) / sxx[a:b].sum(0)
            wins = np.stack([idx[a:b, 0], idx[a:b, -1] + 1], axis=1)
            out.append(SegmentFrf(int(wins[0, 0]), int(wins[-1, 1]), wins, h, r))
    return out
