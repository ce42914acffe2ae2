"""What the figures of several commands share (pure numpy; no matplotlib import here)."""
from __future__ import annotations

import numpy as np

__all__ = ["unwrapped_phase_deg"]


def unwrapped_phase_deg(values, reference=None, frequency=None) -> np.ndarray:
    """Phase [deg] of complex FRF values without 360-degree jumps.

    Unwrapped along the points and started in (-180, 180]; with ``frequency``, each run of
    increasing frequency (the sweeps of a stacked table) is unwrapped on its own. Given
    ``reference`` (an unwrapped phase [deg] at the same points, e.g. a model's), each value is
    put on the branch nearest to it instead: measured points beside their model's curve.
    """
    phase = np.angle(np.asarray(values, dtype=complex))
    if reference is not None:
        ref = np.radians(np.asarray(reference, dtype=float))
        return np.degrees(ref + np.angle(np.exp(1j * (phase - ref))))
    starts = [0]
    if frequency is not None:
        starts += list(np.flatnonzero(np.diff(np.asarray(frequency, dtype=float)) <= 0) + 1)
    out = np.empty_like(phase)
    for a, b in zip(starts, [*starts[1:], phase.size]):
        run = np.unwrap(phase[a:b])
        if run.size:
            run -= 2 * np.pi * np.round(run[0] / (2 * np.pi))
        out[a:b] = run
    return np.degrees(out)
