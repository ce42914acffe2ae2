"""Scaled magnitude spectra of acceleration windows (Zhang (2006) eq. 7.3).

The spectrum-based controller of the study (section 7.2) looks at the magnitude of the wing's
acceleration spectrum at 5..20 Hz in 1 Hz steps over a 2 s window sampled at 1 kHz, per channel,
each channel divided by its sum over those frequencies (eq. 7.3, ``p_i = P_i / sum_i P_i``).

Scaling of the unscaled magnitudes ``P_i`` (reported as ``amplitudes``): single-sided amplitude,
``P(f) = 2 |sum_n w_n x_n exp(-2 pi j f n / fs)| / sum_n w_n``, so a sine ``A sin(2 pi f t)``
whose frequency is an exact DFT bin of the window (a multiple of ``fs / n``) gives ``P(f) = A``
for both the rectangular and the Hann window. The eq. 7.3 ratios do not depend on this constant;
the band sums (``sum_i P_i``) do, and they are published.

The DFT is evaluated directly at the requested frequencies, not by picking FFT bins. With a 2 s
window the FFT bins are 0.5 Hz apart, so 5..20 Hz are exact bins and the result equals the FFT's.
A frequency between bins is still evaluated exactly (the window's DTFT at that frequency), but a
sine there leaks into it with the window's scalloping loss and into the other frequencies.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from aero_dva.control.law_defaults import STUDY_BAND, WINDOW_FUNCTIONS

__all__ = [
    "DEFAULT_FREQUENCIES",
    "WINDOW_FUNCTIONS",
    "PushResult",
    "ResetEvent",
    "ResetReason",
    "ScaledSpectrum",
    "SlidingSpectrum",
    "WindowSpectrum",
    "scaled_spectrum",
]

#: [Hz] the study's band: 5..20 Hz in 1 Hz steps (section 7.2.1).
DEFAULT_FREQUENCIES = np.array(STUDY_BAND)
DEFAULT_FREQUENCIES.setflags(write=False)


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class ScaledSpectrum:
    """Scaled magnitude spectrum of one window (Zhang (2006) eq. 7.3).

    Attributes
    ----------
    frequencies : ndarray, shape (n_freq,)
        [Hz] frequencies at which the DFT was evaluated.
    magnitudes : ndarray, shape (channels, n_freq)
        [1] ``amplitudes / band_sums[:, None]``: each channel sums to 1 over the band. NaN for a
        channel whose band sum is zero (a window with no content in the band).
    amplitudes : ndarray, shape (channels, n_freq)
        Unscaled single-sided amplitudes ``P_i`` in the samples' unit (e.g. m/s^2).
    band_sums : ndarray, shape (channels,)
        ``sum_i P_i`` per channel, in the samples' unit.
    sample_rate : float
        [Hz] sampling rate of the window.
    n_samples : int
        Number of samples in the window.
    window_function : str
        One of :data:`WINDOW_FUNCTIONS`.
    """

    frequencies: np.ndarray
    magnitudes: np.ndarray
    amplitudes: np.ndarray
    band_sums: np.ndarray
    sample_rate: float
    n_samples: int
    window_function: str

    @property
    def window_duration(self) -> float:
        """[s] length of the analysed window, ``n_samples / sample_rate``."""
        return self.n_samples / self.sample_rate


def _validate_sample_rate(sample_rate) -> float:
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, float, np.number)):
        raise TypeError(f"sample_rate must be a real number, got {type(sample_rate).__name__}")
    sample_rate = float(sample_rate)
    if not np.isfinite(sample_rate) or sample_rate <= 0.0:
        raise ValueError(f"sample_rate must be finite and > 0 Hz, got {sample_rate}")
    return sample_rate


def _validate_frequencies(frequencies, sample_rate: float) -> np.ndarray:
    freqs = np.array(frequencies, dtype=float, ndmin=1)
    if freqs.ndim != 1 or freqs.size == 0:
        raise ValueError(f"frequencies must be a non-empty 1-D sequence, got shape {freqs.shape}")
    if not np.all(np.isfinite(freqs)):
        raise ValueError("frequencies must be finite")
    nyquist = 0.5 * sample_rate
    # The factor 2 of the single-sided scaling is only right strictly between 0 and Nyquist.
    if np.any(freqs <= 0.0) or np.any(freqs >= nyquist):
        raise ValueError(
            f"frequencies must lie strictly between 0 and the Nyquist frequency {nyquist} Hz, "
            f"got [{freqs.min()}, {freqs.max()}] Hz"
        )
    return _frozen(freqs)


def _validate_window(window) -> str:
    if not isinstance(window, str):
        raise TypeError(f"window must be a string, got {type(window).__name__}")
    if window not in WINDOW_FUNCTIONS:
        raise ValueError(f"window must be one of {WINDOW_FUNCTIONS}, got {window!r}")
    return window


def _window_weights(window: str, n: int) -> np.ndarray:
    if window == "rectangular":
        return np.ones(n)
    # Periodic Hann (DFT-even): its coherent gain is exactly 1/2 and it vanishes at one end only,
    # so consecutive hops tile without a doubled zero.
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


def _dft_matrix(frequencies: np.ndarray, sample_rate: float, weights: np.ndarray) -> np.ndarray:
    """Windowed DFT kernel with the single-sided amplitude scaling, shape (n_samples, n_freq)."""
    n = np.arange(weights.size)
    kernel = np.exp(-2j * np.pi * np.outer(n, frequencies) / sample_rate)
    return kernel * (2.0 * weights / weights.sum())[:, None]


def _scale(
    amplitudes: np.ndarray, frequencies: np.ndarray, sample_rate: float, n: int, window: str
) -> ScaledSpectrum:
    band_sums = amplitudes.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        magnitudes = np.where(band_sums[:, None] > 0.0, amplitudes / band_sums[:, None], np.nan)
    return ScaledSpectrum(
        frequencies=frequencies,
        magnitudes=_frozen(magnitudes),
        amplitudes=_frozen(amplitudes),
        band_sums=_frozen(band_sums),
        sample_rate=sample_rate,
        n_samples=n,
        window_function=window,
    )


def scaled_spectrum(
    samples, sample_rate: float, frequencies=DEFAULT_FREQUENCIES, window: str = "rectangular"
) -> ScaledSpectrum:
    """Scaled magnitude spectra of a window of samples (Zhang (2006) eq. 7.3).

    Parameters
    ----------
    samples : array_like, shape (channels, n) or (n,)
        Uniformly sampled signals, time on the last axis (e.g. [m/s^2]). Must be finite.
    sample_rate : float
        [Hz] sampling rate.
    frequencies : array_like, shape (n_freq,)
        [Hz] frequencies to evaluate, strictly between 0 and ``sample_rate / 2``.
        Default 5..20 Hz in 1 Hz steps.
    window : {"rectangular", "hann"}
        Window function applied before the DFT (the study does not window: rectangular).

    Returns
    -------
    ScaledSpectrum
        ``magnitudes`` has shape (channels, n_freq); a 1-D input counts as one channel.

    Raises
    ------
    ValueError
        If ``samples`` is empty or not finite, or a frequency is outside (0, Nyquist).
    TypeError
        If ``sample_rate`` is not a number or ``window`` not a string.

    Notes
    -----
    ``P(f) = 2 |sum_n w_n x_n exp(-2 pi j f n / fs)| / sum_n w_n`` (single-sided amplitude) and
    ``p_i = P_i / sum_i P_i`` (eq. 7.3). Frequencies that are not multiples of ``fs / n`` are
    evaluated exactly but are not orthogonal DFT bins (see the module docstring).
    """
    sample_rate = _validate_sample_rate(sample_rate)
    window = _validate_window(window)
    freqs = _validate_frequencies(frequencies, sample_rate)
    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[0] == 0 or x.shape[1] < 2:
        raise ValueError(
            f"samples must have shape (channels, n) with channels >= 1 and n >= 2, got {x.shape}"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError("samples must be finite (found NaN or inf)")
    n = x.shape[1]
    kernel = _dft_matrix(freqs, sample_rate, _window_weights(window, n))
    return _scale(np.abs(x @ kernel), freqs, sample_rate, n, window)


class ResetReason(str, enum.Enum):
    """Why :class:`SlidingSpectrum` dropped its window."""

    GAP = "gap"  # samples are missing between the previous block and this one
    OUT_OF_ORDER = "out_of_order"  # the block starts before the expected sample (late, repeat)
    NON_FINITE = "non_finite"  # the block holds NaN or inf; it is dropped
    REQUESTED = "requested"  # reset() was called


@dataclass(frozen=True)
class ResetEvent:
    """A reset of the sliding window.

    Attributes
    ----------
    reason : ResetReason
        Why the window was dropped.
    expected_index : int or None
        Sample index the next block should have started at (None before the first block).
    received_index : int or None
        ``first_sample_index`` of the block that caused the reset.
    dropped_samples : int
        Samples that were in the window and are discarded.
    """

    reason: ResetReason
    expected_index: int | None
    received_index: int | None
    dropped_samples: int

    def describe(self) -> str:
        """One line for a diagnostic message."""
        if self.reason is ResetReason.GAP:
            what = (
                f"gap of {self.received_index - self.expected_index} samples "
                f"(expected index {self.expected_index}, got {self.received_index})"
            )
        elif self.reason is ResetReason.OUT_OF_ORDER:
            what = (
                f"out-of-order block (expected index {self.expected_index}, "
                f"got {self.received_index})"
            )
        elif self.reason is ResetReason.NON_FINITE:
            what = f"block at index {self.received_index} holds NaN or inf and was dropped"
        else:
            what = "reset requested"
        return f"spectrum window reset: {what}; {self.dropped_samples} samples discarded"


@dataclass(frozen=True)
class WindowSpectrum:
    """Scaled spectrum of one window of a stream.

    Attributes
    ----------
    spectrum : ScaledSpectrum
        The eq. 7.3 spectra of the window.
    first_sample_index : int
        Stream index of the window's first sample.
    stop_sample_index : int
        Stream index one past the window's last sample.
    mean_damping : float
        [N s/m] mean damper coefficient c2 over the window's samples, NaN unless every sample
        of the window came with a damping value.
    """

    spectrum: ScaledSpectrum
    first_sample_index: int
    stop_sample_index: int
    mean_damping: float


@dataclass(frozen=True)
class PushResult:
    """What :meth:`SlidingSpectrum.push` produced.

    Attributes
    ----------
    spectra : tuple of WindowSpectrum
        Windows completed by this block, oldest first.
    reset : ResetEvent or None
        Set if the block reset the window (before any of ``spectra`` were computed).
    """

    spectra: tuple[WindowSpectrum, ...]
    reset: ResetEvent | None


def _as_index(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < 0:
        raise ValueError(f"{name} must be >= 0, got {value}")
    return int(value)


class SlidingSpectrum:
    """Streaming eq. 7.3 spectra over sliding windows of sample blocks.

    Blocks carry the stream index of their first sample. A block that does not start where
    the previous one ended (a gap, or a late/repeated/restarted block) drops the samples
    collected so far and starts a new window at that block; the push reports why. Windows
    start ``hop`` apart from the first sample after a reset.

    Parameters
    ----------
    channels : int
        Number of channels per block.
    sample_rate : float
        [Hz] sampling rate of the blocks.
    window_duration : float
        [s] window length; ``window_duration * sample_rate`` must be a whole number of samples.
    hop : float
        [s] time between the starts of consecutive windows; a whole number of samples.
    frequencies : array_like, shape (n_freq,)
        [Hz] frequencies to evaluate (default 5..20 Hz in 1 Hz steps).
    window : {"rectangular", "hann"}
        Window function.
    """

    def __init__(
        self,
        channels: int,
        sample_rate: float,
        window_duration: float = 2.0,
        hop: float = 0.1,
        frequencies=DEFAULT_FREQUENCIES,
        window: str = "rectangular",
    ):
        if isinstance(channels, bool) or not isinstance(channels, (int, np.integer)):
            raise TypeError(f"channels must be an integer, got {type(channels).__name__}")
        if channels < 1:
            raise ValueError(f"channels must be >= 1, got {channels}")
        self.channels = int(channels)
        self.sample_rate = _validate_sample_rate(sample_rate)
        self.window_function = _validate_window(window)
        self.frequencies = _validate_frequencies(frequencies, self.sample_rate)
        self.window_length = self._whole_samples(window_duration, "window_duration")
        if self.window_length < 2:
            raise ValueError("window_duration must span at least 2 samples")
        self.hop_length = self._whole_samples(hop, "hop")
        self._kernel = _dft_matrix(
            self.frequencies,
            self.sample_rate,
            _window_weights(self.window_function, self.window_length),
        )
        self._samples = np.empty((self.channels, 0))
        self._damping = np.empty(0)
        self._start_index: int | None = None  # stream index of self._samples[:, 0]
        self._next_window_start: int | None = None

    def _whole_samples(self, duration, name: str) -> int:
        if isinstance(duration, bool) or not isinstance(duration, (int, float, np.number)):
            raise TypeError(f"{name} must be a real number, got {type(duration).__name__}")
        count = float(duration) * self.sample_rate
        rounded = round(count)
        if not np.isfinite(count) or rounded < 1 or abs(count - rounded) > 1e-6 * max(1, count):
            raise ValueError(
                f"{name} * sample_rate must be a whole number >= 1 of samples, got "
                f"{duration} s * {self.sample_rate} Hz = {count}"
            )
        return int(rounded)

    @property
    def window_duration(self) -> float:
        """[s] window length."""
        return self.window_length / self.sample_rate

    @property
    def hop(self) -> float:
        """[s] time between window starts."""
        return self.hop_length / self.sample_rate

    @property
    def expected_index(self) -> int | None:
        """Stream index the next block should start at (None before the first block)."""
        if self._start_index is None:
            return None
        return self._start_index + self._samples.shape[1]

    def reset(self) -> ResetEvent:
        """Drop the collected samples; the next block starts a new window."""
        event = ResetEvent(ResetReason.REQUESTED, self.expected_index, None, self._held())
        self._clear()
        return event

    def _held(self) -> int:
        return self._samples.shape[1]

    def _clear(self) -> None:
        self._samples = np.empty((self.channels, 0))
        self._damping = np.empty(0)
        self._start_index = None
        self._next_window_start = None

    def push(self, first_sample_index: int, block, damping=None) -> PushResult:
        """Add a block of samples and return the windows it completes.

        Parameters
        ----------
        first_sample_index : int
            Stream index of the block's first sample (``AccelerationBlock.first_sample_index``).
        block : array_like, shape (channels, n)
            Samples, time on the last axis. ``n`` may be 0.
        damping : float or array_like of shape (n,), optional
            [N s/m] damper coefficient c2 applied during the block, one value for the whole
            block or one per sample. Used for :attr:`WindowSpectrum.mean_damping`.

        Returns
        -------
        PushResult
            Completed windows and the reset this block caused, if any.
        """
        index = _as_index(first_sample_index, "first_sample_index")
        x = np.asarray(block, dtype=float)
        if x.ndim != 2 or x.shape[0] != self.channels:
            raise ValueError(f"block must have shape ({self.channels}, n), got {x.shape}")
        n = x.shape[1]
        if damping is None:
            c2 = np.full(n, np.nan)
        else:
            c2 = np.asarray(damping, dtype=float)
            if c2.ndim == 0:
                c2 = np.full(n, float(c2))
            elif c2.shape != (n,):
                raise ValueError(f"damping must be a scalar or have shape ({n},), got {c2.shape}")

        reset = None
        expected = self.expected_index
        if not np.all(np.isfinite(x)):
            reset = ResetEvent(ResetReason.NON_FINITE, expected, index, self._held())
            self._clear()
            return PushResult((), reset)
        if expected is not None and index != expected:
            reason = ResetReason.GAP if index > expected else ResetReason.OUT_OF_ORDER
            reset = ResetEvent(reason, expected, index, self._held())
            self._clear()
        if n == 0:
            return PushResult((), reset)
        if self._start_index is None:
            self._start_index = index
            self._next_window_start = index

        self._samples = np.concatenate([self._samples, x], axis=1)
        self._damping = np.concatenate([self._damping, c2])
        spectra = []
        stop = self._start_index + self._samples.shape[1]
        while self._next_window_start + self.window_length <= stop:
            spectra.append(self._window_at(self._next_window_start))
            self._next_window_start += self.hop_length
        # Keep only what later windows still need.
        keep_from = self._next_window_start - self._start_index
        if keep_from > 0:
            keep_from = min(keep_from, self._samples.shape[1])
            self._samples = self._samples[:, keep_from:]
            self._damping = self._damping[keep_from:]
            self._start_index += keep_from
        return PushResult(tuple(spectra), reset)

    def _window_at(self, start: int) -> WindowSpectrum:
        offset = start - self._start_index
        x = self._samples[:, offset : offset + self.window_length]
        c2 = self._damping[offset : offset + self.window_length]
        spectrum = _scale(
            np.abs(x @ self._kernel),
            self.frequencies,
            self.sample_rate,
            self.window_length,
            self.window_function,
        )
        # NaN marks samples that came without a damping value.
        mean_damping = float(np.mean(c2))
        return WindowSpectrum(spectrum, start, start + self.window_length, mean_damping)
