"""Input checks shared by the wing modules: each error names the argument that is wrong."""

from __future__ import annotations

import math
from numbers import Real

import numpy as np


def real_scalar(value, name: str) -> float:
    """Return ``value`` as a float, or raise TypeError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (Real, np.number)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    return float(value)


def finite(value, name: str) -> float:
    """A finite real number."""
    x = real_scalar(value, name)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x}")
    return x


def positive(value, name: str) -> float:
    """A finite real number > 0."""
    x = finite(value, name)
    if x <= 0.0:
        raise ValueError(f"{name} must be > 0, got {x}")
    return x


def non_negative(value, name: str, allow_inf: bool = False) -> float:
    """A real number >= 0 (optionally +inf)."""
    x = real_scalar(value, name)
    if math.isnan(x) or x < 0.0 or (math.isinf(x) and not allow_inf):
        bound = "in [0, inf]" if allow_inf else "finite and >= 0"
        raise ValueError(f"{name} must be {bound}, got {x}")
    return x


def real_array(value, name: str, allow_inf: bool = False) -> np.ndarray:
    """A float array without NaN (and without inf unless allowed)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be an array of real numbers") from exc
    if np.isnan(arr).any() if allow_inf else not np.isfinite(arr).all():
        raise ValueError(f"{name} must not contain NaN{'' if allow_inf else ' or inf'}")
    return arr
