"""The sweeps of a table pooled into the loop's :class:`~.fitting.Observations` (the FRF and
modal domains alike): every point weighted by 1/|H| (relative errors), its sweep as its group,
and the covariates whose level differs between sweeps."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dva_offline.discrepancy.fitting import Observations

__all__ = ["pool_conditions"]


def pool_conditions(conditions: Sequence, covariates: Sequence[str] | None
                    ) -> tuple[np.ndarray, Observations]:
    """Angular frequencies [rad/s] and observations of ``conditions`` (FrfData).

    ``covariates``: the covariate columns to keep (each must be in every condition), or None
    for every common column whose mean level differs between the sweeps.
    """
    f = np.concatenate([c.frequency_hz for c in conditions])
    if np.any(f <= 0):
        raise ValueError("frequency_hz must be > 0 Hz (drop the 0 Hz point)")
    y = np.concatenate([c.values for c in conditions])
    if np.any(y == 0):
        raise ValueError("FRF values must be nonzero (relative errors divide by |H|)")
    groups = np.concatenate([np.full(c.frequency_hz.size, i)
                             for i, c in enumerate(conditions)])
    names = covariates
    if names is None:
        common = set.intersection(*(set(c.covariates) for c in conditions))
        names = [n for n in conditions[0].covariates if n in common]
    cov = {}
    for name in names:
        if not all(name in c.covariates for c in conditions):
            raise ValueError(f"covariate {name!r} is missing from a condition")
        col = np.concatenate([np.asarray(c.covariates[name], float) for c in conditions])
        if not np.all(np.isfinite(col)):
            raise ValueError(f"covariate {name!r} has NaN values")
        means = np.array([col[groups == g].mean() for g in range(len(conditions))])
        if covariates is not None or np.ptp(means) > 0:
            cov[name] = col
    return 2 * np.pi * f, Observations(y, 1.0 / np.abs(y), f, groups, cov)
