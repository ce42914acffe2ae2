"""Labels of the training windows: the c2 the network should command at each window's condition.

``exact`` (the default): every window gets c2*(U, rho) of its recorded airspeed and density,
the c2 minimising the exact stationary leading-edge RMS
(:func:`aero_dva.control.optimal_damping.optimal_damping`, the sampled system as simulated).
This is what the study's experiment estimates by tuning c2 at each condition until the RMS is
lowest (sec. 7.2.1); the model gives it without sampling error.

``measured-argmin`` (the study's procedure as recorded, kept for comparison): every window of a
condition gets the c2 of that condition's window with the lowest *measured* leading-edge RMS.
It does not work, and the numbers say why: one 2 s window estimates the RMS with a standard
error of 13-18 % (docs/training.md), while moving c2 by +-100 N s/m around the optimum changes
the true RMS by 0.1-0.8 % below U_cr; the argmin lands anywhere on the c2 list, and a network
trained on it learns the mean label and nothing else.

Pure numerics on a :class:`~dva_offline.training.rbf.TrainingData`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.flight.damper import DAMPER_RANGE
from dva_offline.training.defaults import LABEL_METHODS

__all__ = ["LABEL_METHODS", "LabelError", "Labels", "conditions_of", "label_exact",
           "label_min_rms"]

_GRID = np.linspace(*DAMPER_RANGE, 126)  # [N s/m] c2 grid of the exact optimum (then refined)


class LabelError(ValueError):
    """Windows cannot be labelled (an unstable condition, too few c2 values); says which."""


@dataclass(frozen=True)
class Labels:
    """One label per condition (U, rho) and per window.

    Attributes
    ----------
    method : str
        One of :data:`LABEL_METHODS`.
    airspeed, density : ndarray, shape (n_conditions,)
        [m/s], [kg/m^3] of each condition, sorted by density then airspeed.
    damping : ndarray, shape (n_conditions,)
        [N s/m] the label of each condition.
    rms : ndarray, shape (n_conditions,)
        [m] the leading-edge RMS at the label: exact stationary (``exact``) or the lowest
        measured one (``measured-argmin``).
    n_damping : ndarray of int, shape (n_conditions,)
        Distinct c2 values recorded at each condition.
    targets : ndarray, shape (n_windows,)
        [N s/m] label of every window.
    condition_index : ndarray of int, shape (n_windows,)
        Index of each window's condition.
    """

    method: str
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    rms: np.ndarray
    n_damping: np.ndarray
    targets: np.ndarray
    condition_index: np.ndarray

    @property
    def n_conditions(self) -> int:
        return int(self.airspeed.size)


def conditions_of(airspeed, density) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct (U, rho) pairs of windows: (airspeed, density) of each, and every window's
    index into them (pairs sorted by density, then airspeed)."""
    pairs = np.column_stack([np.asarray(density, float), np.asarray(airspeed, float)])
    unique, index = np.unique(pairs, axis=0, return_inverse=True)
    return unique[:, 1], unique[:, 0], index.reshape(-1)


def _counts(data, index: np.ndarray, n: int) -> np.ndarray:
    return np.array([np.unique(data.damping[index == k]).size for k in range(n)], dtype=int)


def label_exact(data, model, *, force_std: float = 1000.0, sample_rate: float | None = None,
                grid=_GRID) -> Labels:
    """Label every window with c2*(U, rho) of its recorded condition (exact RMS optimum).

    Parameters
    ----------
    data : TrainingData
    model : AeroelasticModel
        The wing with its tunable Maxwell DVA the windows were flown with.
    force_std : float
        [N] force per sample (the optimum does not depend on it: the RMS scales with it).
    sample_rate : float, optional
        [Hz] default: the data's.
    grid : array_like
        c2 grid [N s/m] of the search (the optimum is refined between grid points).

    Raises
    ------
    LabelError
        A condition at which no c2 of the grid is stable (no optimum exists).
    """
    rate = data.sample_rate if sample_rate is None else float(sample_rate)
    speeds, densities, index = conditions_of(data.airspeed, data.density)
    best = np.full(speeds.size, np.nan)
    rms = np.full(speeds.size, np.nan)
    for rho in np.unique(densities):
        members = np.flatnonzero(densities == rho)
        res = optimal_damping(model, speeds[members], grid, float(rho), force_std=force_std,
                              sample_rate=rate)
        best[members] = res.optimal_damping
        rms[members] = res.min_rms
    bad = np.flatnonzero(~np.isfinite(best))
    if bad.size:
        k = bad[0]
        raise LabelError(f"no c2 in {grid[0]:g}..{grid[-1]:g} N s/m keeps the wing stable at "
                         f"U = {speeds[k]:.3f} m/s, rho = {densities[k]:.4g} kg/m^3 "
                         f"({bad.size} condition(s)): those windows have no optimum to learn")
    return Labels(method="exact", airspeed=speeds, density=densities, damping=best, rms=rms,
                  n_damping=_counts(data, index, speeds.size), targets=best[index],
                  condition_index=index)


def label_min_rms(data, min_damping_values: int = 2) -> Labels:
    """Label every window with the c2 of its condition's lowest measured leading-edge RMS.

    Raises
    ------
    LabelError
        A condition with fewer than ``min_damping_values`` distinct c2 windows (no choice).
    """
    speeds, densities, index = conditions_of(data.airspeed, data.density)
    best = np.empty(speeds.size)
    rms = np.empty(speeds.size)
    counts = _counts(data, index, speeds.size)
    for k in range(speeds.size):
        if counts[k] < min_damping_values:
            raise LabelError(
                f"U = {speeds[k]:.3f} m/s, rho = {densities[k]:.4g} kg/m^3 has windows for "
                f"{counts[k]} c2 value(s); labelling needs at least {min_damping_values}")
        members = np.flatnonzero(index == k)
        j = members[int(np.argmin(data.rms[members]))]
        best[k], rms[k] = data.damping[j], data.rms[j]
    return Labels(method="measured-argmin", airspeed=speeds, density=densities, damping=best,
                  rms=rms, n_damping=counts, targets=best[index], condition_index=index)
