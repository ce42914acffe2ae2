"""Parameter rows two nodes share, once: the spectra's shape (the spectrum node makes them, the
RBF controller checks its network was trained on them) and the damper's range (the airspeed and
RBF controllers clamp their commands to it), with the checks of their values."""
from __future__ import annotations

import math

import numpy as np

from aero_dva.control.spectrum import DEFAULT_FREQUENCIES, WINDOW_FUNCTIONS
from dva_ros_common.conversions import ACCELERATION_CHANNELS
from dva_ros_common.node_params import Param

MAX_DAMPING = 1.0e6  # [N s/m] far above any damper of this size class; larger is a unit error

#: channels, frequencies, window, window_duration of the eq. 7.3 spectra.
SPECTRUM_SHAPE = (
    Param("channels", ["plunge", "pitch"], "acceleration channels of the spectra, in order",
          choices=ACCELERATION_CHANNELS),
    Param("frequencies", DEFAULT_FREQUENCIES.tolist(),
          "frequencies of the spectra: distinct, below the blocks' Nyquist frequency", "Hz",
          low=1.0e-9, default_text="5, 6, ..., 20 (1 Hz steps)"),
    Param("window", "rectangular", "window function (rectangular: the study's)",
          choices=tuple(WINDOW_FUNCTIONS)),
    Param("window_duration", 2.0,
          "window length; times the blocks' sample rate a whole number of samples", "s",
          1.0e-3, 3600.0),
)

#: damping_min, damping_max: the damper's range; commands are clamped to it.
DAMPER_RANGE = (
    Param("damping_min", 0.0, "damper range, lower end; commands are clamped to it", "N s/m",
          0.0, MAX_DAMPING),
    Param("damping_max", 2500.0, "damper range, upper end (the simulator's default range)",
          "N s/m", 0.0, MAX_DAMPING),
)


def spectrum_shape(values) -> tuple[tuple[str, ...], np.ndarray, str, float]:
    """``channels, frequencies, window, window_duration`` from the declared values of
    :data:`SPECTRUM_SHAPE`, checked."""
    return (checked_channels(values["channels"]), checked_frequencies(values["frequencies"]),
            str(values["window"]), float(values["window_duration"]))


def checked_channels(value) -> tuple[str, ...]:
    """Validate the ``channels`` parameter (known names, at least one, none twice)."""
    channels = tuple(c for c in value if c)
    if not channels:
        raise ValueError("parameter 'channels' must name at least one channel")
    unknown = [c for c in channels if c not in ACCELERATION_CHANNELS]
    if unknown:
        raise ValueError(
            f"parameter 'channels': unknown channel(s) {unknown}, "
            f"expected some of {list(ACCELERATION_CHANNELS)}"
        )
    if len(set(channels)) != len(channels):
        raise ValueError(f"parameter 'channels' lists a channel twice: {list(channels)}")
    return channels


def checked_frequencies(value) -> np.ndarray:
    """Validate the ``frequencies`` parameter (numbers, finite, > 0, distinct)."""
    try:
        freqs = np.array([float(f) for f in value])
    except (TypeError, ValueError):
        raise ValueError(f"parameter 'frequencies' must be numbers, got {value!r}") from None
    if freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs <= 0.0):
        raise ValueError(
            f"parameter 'frequencies' must be finite values > 0 Hz, got {freqs.tolist()}"
        )
    if np.unique(freqs).size != freqs.size:
        raise ValueError(f"parameter 'frequencies' has repeated values: {freqs.tolist()}")
    return freqs


def damping_range(low: float, high: float) -> tuple[float, float]:
    """Validate the ``damping_min``/``damping_max`` pair."""
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 <= low < high):
        raise ValueError(
            f"parameters 'damping_min' and 'damping_max' must satisfy 0 <= min < max, "
            f"got {low}, {high} N s/m"
        )
    return float(low), float(high)
