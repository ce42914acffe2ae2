"""The flight domain's whole-flight route: the wing as a linear time-varying system along
the log (pure numerics).

A flight whose c2 changes within a block (a per-sample law: the switching or the
clipped-optimal law) has no segment of constant c2, and a ramp none of constant airspeed. The
whole-flight route fits such a flight as it was flown: the model is simulated along the log
sample by sample, each sample at its block's logged airspeed and density and at its own c2
(:mod:`aero_dva.flight.varying_simulator`), and the segments' H1 estimator is applied to
the simulated accelerations on the same windows as to the measured ones.

The c2 the model flies is the c2 the law *commanded* (``DamperBlock.commanded_damping``, what
the damper's controller logs), through the damper's first-order lag (:func:`lagged_c2`), not the
c2 that acted (which the damper's lag already shaped: an analysis reading it could never find a
lag). Blocks over which c2 was held keep the reported c2 (``DamperState.applied_damping``),
which is what acted over them.

Output error needs a model that forgets its initial state and damps its own errors. Along a
switching flight near its boundary the recorded c2 sequence no longer does that: the law keeps
the wing bounded by feedback on its state, which a replay of its decisions lacks, so a model
error of 1e-3 grows without bound. :func:`analysable_stop` ends the span analysed where the
state transition of the model along the log over :data:`SPAN_WINDOW_S` stops shrinking every
state (its spectral radius reaches :data:`MAX_GROWTH`).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from aero_dva.flight.varying_simulator import VaryingSteps, transitions

SPAN_WINDOW_S = 1.0
"""[s] window of the state transition that decides where the analysable span ends."""
MAX_GROWTH = 1.0
"""Spectral radius of that transition at which the span ends (a state is no longer damped)."""


def law_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Sample ranges [a, b) where ``mask`` is True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def lagged_c2(command: np.ndarray, lagged: np.ndarray, start: np.ndarray,
              time_constant: float, dt: float) -> np.ndarray:
    """[N s/m] the c2 acting over each sample.

    In each run of ``lagged`` samples the ``command`` goes through a first-order lag of
    ``time_constant`` [s]: c2 acting over sample i is the lag's mean over the sample with the
    command held (as a semi-active damper follows its target), the lag starting at the run's
    first sample from ``start`` there (clipped to the run's commanded range: the damper's c2
    when the law was armed). Other samples keep ``command``.
    """
    out = np.array(command, dtype=float)
    tau = float(time_constant)
    if not (math.isfinite(tau) and tau >= 0):
        raise ValueError(f"time_constant must be finite and >= 0 s, got {time_constant}")
    if tau == 0.0:
        return out
    g = math.exp(-dt / tau)
    mean = tau / dt * (1.0 - g)  # (mean over the sample - target) / (start - target)
    for a, b in law_runs(lagged):
        x = out[a:b]
        c0 = float(np.clip(start[a], x.min(), x.max())) if np.isfinite(start[a]) else x[0]
        end, _ = lfilter([1.0 - g], [1.0, -g], x, zi=[g * c0])  # lag state at each end
        before = np.concatenate([[c0], end[:-1]])
        out[a:b] = x + (before - x) * mean
    return out


def analysable_stop(steps: VaryingSteps, condition, rates, start: int, stop: int,
                    window: int) -> tuple[int, np.ndarray]:
    """The sample where the analysable span ends and the spectral radius of the state
    transition over each ``window`` samples from ``start`` (module docstring): the start of
    the first window whose radius reaches :data:`MAX_GROWTH`, else ``stop``."""
    starts = np.arange(start, stop - window + 1, window)
    if starts.size == 0:
        return stop, np.zeros(0)
    phi = transitions(steps, condition, rates, starts, window)
    with np.errstate(all="ignore"):
        radius = np.array([np.max(np.abs(np.linalg.eigvals(p))) if np.all(np.isfinite(p))
                           else np.inf for p in phi])
    grown = np.flatnonzero(~(radius < MAX_GROWTH))
    return (int(starts[grown[0]]) if grown.size else stop), radius
