"""Conversions between dva_msgs messages and plain Python values (the only module of this package
that builds or reads messages, so the nodes stay thin and the numerics stay ROS-free).

Times are handled as integer nanoseconds (``time_to_ns`` / ``ns_to_time``) so sample times
derived from a block's header stamp do not accumulate floating-point error.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time

from aero_dva.control.spectrum import ScaledSpectrum as SpectrumResult
from dva_msgs.msg import (
    AccelerationBlock,
    DamperCommand,
    DamperState,
    FlightCondition,
    ScaledSpectrum,
)
from dva_ros_common.conversions import time_to_ns

_NS = 1_000_000_000

#: Channels of ``dva_msgs/AccelerationBlock``, by field name.
ACCELERATION_CHANNELS = ("plunge", "pitch", "leading_edge")

def damper_command(stamp: Time, damping: float, source: str) -> DamperCommand:
    """A ``dva_msgs/DamperCommand`` for c2 = ``damping`` [N s/m] from controller ``source``."""
    msg = DamperCommand()
    msg.header.stamp = stamp
    msg.damping = float(damping)
    msg.source = source
    return msg


@dataclass(frozen=True)
class AccelerationSamples:
    """The content of one ``dva_msgs/AccelerationBlock`` for the chosen channels.

    Attributes
    ----------
    stamp_ns : int
        [ns] time of the first sample (header stamp).
    frame_id : str
        Header frame.
    sample_rate : float
        [Hz] as sent (not validated here).
    first_sample_index : int
        Stream index of the first sample.
    samples : ndarray, shape (channels, n)
        Samples of the requested channels, in the requested order (m/s^2 or rad/s^2).
    """

    stamp_ns: int
    frame_id: str
    sample_rate: float
    first_sample_index: int
    samples: np.ndarray

    def sample_time_ns(self, index: int) -> int:
        """[ns] time of stream sample ``index`` (``header.stamp + (index - first) / rate``)."""
        return self.stamp_ns + round((index - self.first_sample_index) * _NS / self.sample_rate)


def acceleration_samples(msg: AccelerationBlock, channels: Sequence[str]) -> AccelerationSamples:
    """Read the ``channels`` of an acceleration block into an array.

    Raises
    ------
    ValueError
        If a channel is unknown or the block's arrays differ in length.
    """
    for name in channels:
        if name not in ACCELERATION_CHANNELS:
            raise ValueError(f"unknown acceleration channel {name!r}")
    lengths = {name: len(getattr(msg, name)) for name in ACCELERATION_CHANNELS}
    if len(set(lengths.values())) != 1:
        raise ValueError(f"the block's arrays differ in length {lengths}")
    n = lengths[ACCELERATION_CHANNELS[0]]
    samples = np.empty((len(channels), n))
    for row, name in enumerate(channels):
        samples[row] = np.asarray(getattr(msg, name), dtype=float)
    return AccelerationSamples(
        stamp_ns=time_to_ns(msg.header.stamp),
        frame_id=msg.header.frame_id,
        sample_rate=float(msg.sample_rate),
        first_sample_index=int(msg.first_sample_index),
        samples=samples,
    )


def acceleration_block(
    stamp: Time,
    sample_rate: float,
    first_sample_index: int,
    plunge,
    pitch,
    leading_edge,
    frame_id: str = "wing",
) -> AccelerationBlock:
    """A ``dva_msgs/AccelerationBlock`` (arrays in m/s^2, rad/s^2, m/s^2; equal lengths)."""
    msg = AccelerationBlock()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.sample_rate = float(sample_rate)
    msg.first_sample_index = int(first_sample_index)
    msg.plunge = np.asarray(plunge, dtype=float).tolist()
    msg.pitch = np.asarray(pitch, dtype=float).tolist()
    msg.leading_edge = np.asarray(leading_edge, dtype=float).tolist()
    return msg


def scaled_spectrum_message(
    stamp: Time,
    frame_id: str,
    channel_names: Sequence[str],
    spectrum: SpectrumResult,
    hop: float,
    damping: float,
) -> ScaledSpectrum:
    """A ``dva_msgs/ScaledSpectrum`` from an eq. 7.3 spectrum (magnitudes channel-major).

    Parameters
    ----------
    stamp : builtin_interfaces/Time
        Time of the last sample in the window.
    frame_id : str
        Frame of the acceleration blocks.
    channel_names : sequence of str
        One name per row of ``spectrum.magnitudes``.
    spectrum : aero_dva.control.spectrum.ScaledSpectrum
        The window's spectrum.
    hop : float
        [s] time between consecutive window starts.
    damping : float
        [N s/m] c2 applied during the window (NaN if unknown).
    """
    if len(channel_names) != spectrum.magnitudes.shape[0]:
        raise ValueError(
            f"{len(channel_names)} channel names for {spectrum.magnitudes.shape[0]} channels"
        )
    msg = ScaledSpectrum()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.frequencies = spectrum.frequencies.tolist()
    msg.channel_names = list(channel_names)
    msg.magnitudes = spectrum.magnitudes.ravel().tolist()
    msg.band_sums = spectrum.band_sums.tolist()
    msg.window_duration = float(spectrum.window_duration)
    msg.hop = float(hop)
    msg.window_function = spectrum.window_function
    msg.scaling = ScaledSpectrum.SCALING_BAND_SUM
    msg.damping = float(damping)
    return msg


@dataclass(frozen=True)
class SpectrumInput:
    """The content of one ``dva_msgs/ScaledSpectrum``.

    Attributes
    ----------
    stamp_ns : int
        [ns] time of the last sample in the window.
    channel_names : tuple of str
    frequencies : ndarray, shape (n_freq,)
        [Hz]
    magnitudes : ndarray, shape (channels, n_freq)
        [1] scaled magnitudes (eq. 7.3).
    window_duration : float
        [s]
    window_function, scaling : str
    damping : float
        [N s/m] c2 during the window (may be NaN).
    """

    stamp_ns: int
    channel_names: tuple[str, ...]
    frequencies: np.ndarray
    magnitudes: np.ndarray
    window_duration: float
    window_function: str
    scaling: str
    damping: float


def spectrum_input(msg: ScaledSpectrum) -> SpectrumInput:
    """Read a ``dva_msgs/ScaledSpectrum``.

    Raises
    ------
    ValueError
        If ``magnitudes`` does not hold ``len(channel_names) * len(frequencies)`` values.
    """
    names = tuple(msg.channel_names)
    freqs = np.asarray(msg.frequencies, dtype=float)
    mags = np.asarray(msg.magnitudes, dtype=float)
    if mags.size != len(names) * freqs.size:
        raise ValueError(
            f"magnitudes has {mags.size} values, expected {len(names)} channels x "
            f"{freqs.size} frequencies = {len(names) * freqs.size}"
        )
    return SpectrumInput(
        stamp_ns=time_to_ns(msg.header.stamp),
        channel_names=names,
        frequencies=freqs,
        magnitudes=mags.reshape(len(names), freqs.size),
        window_duration=float(msg.window_duration),
        window_function=msg.window_function,
        scaling=msg.scaling,
        damping=float(msg.damping),
    )


@dataclass(frozen=True)
class FlightConditionValues:
    """The content of one ``dva_msgs/FlightCondition`` (SI units, not validated)."""

    stamp_ns: int
    airspeed: float
    air_density: float


def flight_condition_values(msg: FlightCondition) -> FlightConditionValues:
    """Read a ``dva_msgs/FlightCondition``."""
    return FlightConditionValues(
        time_to_ns(msg.header.stamp), float(msg.airspeed), float(msg.air_density)
    )


def flight_condition(stamp: Time, airspeed: float, air_density: float = 1.2) -> FlightCondition:
    """A ``dva_msgs/FlightCondition`` (airspeed [m/s], air density [kg/m^3])."""
    msg = FlightCondition()
    msg.header.stamp = stamp
    msg.airspeed = float(airspeed)
    msg.air_density = float(air_density)
    return msg


def applied_damping(msg: DamperState) -> float:
    """[N s/m] c2 acting in the model according to a ``dva_msgs/DamperState`` (may be NaN)."""
    return float(msg.applied_damping)
