"""Scaled magnitude spectra (Zhang (2006) eq. 7.3) and the sliding-window stream."""

import numpy as np
import pytest

from aero_dva.control.spectrum import (
    DEFAULT_FREQUENCIES,
    ResetReason,
    SlidingSpectrum,
    scaled_spectrum,
)

FS = 1000.0  # [Hz] the study's sampling rate
N = 2000  # 2 s window


def two_sines(n=N, a12=2.0, a7=0.5, phase=0.3):
    t = np.arange(n) / FS
    return a12 * np.sin(2 * np.pi * 12 * t + phase) + a7 * np.sin(2 * np.pi * 7 * t - 1.1)


@pytest.mark.parametrize("window", ["rectangular", "hann"])
def test_two_sines_give_amplitudes_and_eq_7_3_ratio(window):
    s = scaled_spectrum(two_sines(), FS, window=window)
    f = list(s.frequencies)
    i12, i7 = f.index(12.0), f.index(7.0)
    # Single-sided amplitude scaling: an on-bin sine of amplitude A reads A.
    assert s.amplitudes[0, i12] == pytest.approx(2.0, rel=1e-9)
    assert s.amplitudes[0, i7] == pytest.approx(0.5, rel=1e-9)
    others = np.delete(s.amplitudes[0], [i12, i7])
    assert np.all(others < 1e-9)
    # eq. 7.3: p_i = P_i / sum P_i.
    assert s.magnitudes[0, i12] == pytest.approx(2.0 / 2.5, rel=1e-9)
    assert s.magnitudes[0, i12] / s.magnitudes[0, i7] == pytest.approx(4.0, rel=1e-9)
    assert s.band_sums[0] == pytest.approx(2.5, rel=1e-9)
    assert s.window_duration == pytest.approx(2.0)


def test_each_channel_sums_to_one_and_matches_fft_bins():
    rng = np.random.default_rng(3)
    x = rng.standard_normal((3, N)) * np.array([[1.0], [20.0], [1e-3]])
    s = scaled_spectrum(x, FS)
    assert s.magnitudes.shape == (3, 16)
    np.testing.assert_allclose(s.magnitudes.sum(axis=1), 1.0, rtol=1e-12)
    # 5..20 Hz are exact bins (0.5 Hz apart) of a 2 s window: same as the FFT.
    spectrum = np.fft.rfft(x, axis=1)
    bins = (DEFAULT_FREQUENCIES * N / FS).astype(int)
    np.testing.assert_allclose(s.amplitudes, 2 * np.abs(spectrum[:, bins]) / N, rtol=1e-9)


def test_scaling_is_independent_of_gain():
    x = np.random.default_rng(1).standard_normal((2, N))
    a = scaled_spectrum(x, FS)
    b = scaled_spectrum(1e4 * x, FS)
    np.testing.assert_allclose(a.magnitudes, b.magnitudes, rtol=1e-10)
    np.testing.assert_allclose(b.band_sums, 1e4 * a.band_sums, rtol=1e-10)


def test_off_bin_frequency_is_evaluated_not_rounded():
    # A 1.5 s window has bins 2/3 Hz apart; 12 Hz is a bin but 7 Hz is not.
    t = np.arange(1500) / FS
    x = np.sin(2 * np.pi * 7 * t)
    s = scaled_spectrum(x, FS, frequencies=[7.0, 12.0])
    dtft = 2 * abs(np.sum(x * np.exp(-2j * np.pi * 7 * t))) / x.size
    assert s.amplitudes[0, 0] == pytest.approx(dtft, rel=1e-12)
    assert s.amplitudes[0, 1] > 0.0  # leakage into 12 Hz, which an on-bin sine would not cause


def test_zero_signal_gives_nan_magnitudes():
    s = scaled_spectrum(np.zeros((2, N)), FS)
    assert np.all(np.isnan(s.magnitudes))
    np.testing.assert_array_equal(s.band_sums, 0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"frequencies": [5.0, 500.0]}, "Nyquist"),
        ({"frequencies": [0.0, 5.0]}, "Nyquist"),
        ({"frequencies": []}, "frequencies"),
        ({"window": "hamming"}, "window"),
        ({"sample_rate": -1.0}, "sample_rate"),
    ],
)
def test_bad_arguments_are_named(kwargs, match):
    args = {"samples": two_sines(), "sample_rate": FS, **kwargs}
    with pytest.raises(ValueError, match=match):
        scaled_spectrum(**args)


def test_non_finite_samples_raise():
    x = two_sines()
    x[10] = np.nan
    with pytest.raises(ValueError, match="samples"):
        scaled_spectrum(x, FS)


def stream(total, block=25, channels=2, rng=None):
    rng = rng or np.random.default_rng(0)
    x = rng.standard_normal((channels, total))
    return x, [(i, x[:, i : i + block]) for i in range(0, total, block)]


def test_sliding_windows_match_the_batch_function():
    x, blocks = stream(4000)
    sliding = SlidingSpectrum(2, FS, window_duration=2.0, hop=0.5)
    out = []
    for index, block in blocks:
        result = sliding.push(index, block)
        assert result.reset is None
        out.extend(result.spectra)
    # Windows start every 500 samples: (4000 - 2000) / 500 + 1 of them.
    assert [w.first_sample_index for w in out] == [0, 500, 1000, 1500, 2000]
    for w in out:
        assert w.stop_sample_index - w.first_sample_index == 2000
        expected = scaled_spectrum(x[:, w.first_sample_index : w.stop_sample_index], FS)
        np.testing.assert_allclose(w.spectrum.magnitudes, expected.magnitudes, rtol=1e-10)
        np.testing.assert_allclose(w.spectrum.band_sums, expected.band_sums, rtol=1e-10)


def test_gap_resets_the_window_and_says_why():
    _, blocks = stream(6000)
    sliding = SlidingSpectrum(2, FS, hop=0.5)
    windows = []
    resets = []
    for index, block in blocks:
        if 2100 <= index < 2300:  # lose 200 samples
            continue
        result = sliding.push(index, block)
        windows.extend(result.spectra)
        if result.reset is not None:
            resets.append(result.reset)
    assert len(resets) == 1
    event = resets[0]
    assert event.reason is ResetReason.GAP
    assert (event.expected_index, event.received_index) == (2100, 2300)
    assert event.dropped_samples > 0
    assert "gap of 200 samples" in event.describe()
    starts = [w.first_sample_index for w in windows]
    # No window spans the gap; after it, windows restart at the first new sample.
    assert all(s + 2000 <= 2100 or s >= 2300 for s in starts)
    assert 2300 in starts and 2800 in starts


def test_out_of_order_and_repeated_blocks_reset():
    _, blocks = stream(1000)
    sliding = SlidingSpectrum(2, FS)
    for index, block in blocks[:10]:
        sliding.push(index, block)
    repeat = sliding.push(*blocks[9])  # the same block again
    assert repeat.reset.reason is ResetReason.OUT_OF_ORDER
    assert repeat.reset.dropped_samples == 250
    back = sliding.push(0, blocks[0][1])  # a restarted stream
    assert back.reset.reason is ResetReason.OUT_OF_ORDER
    assert sliding.expected_index == 25


def test_non_finite_block_is_dropped_with_a_reset():
    _, blocks = stream(200)
    sliding = SlidingSpectrum(2, FS)
    sliding.push(*blocks[0])
    bad = blocks[1][1].copy()
    bad[1, 3] = np.inf
    result = sliding.push(blocks[1][0], bad)
    assert result.reset.reason is ResetReason.NON_FINITE
    assert sliding.expected_index is None  # nothing kept


def test_mean_damping_per_block_and_per_sample():
    _, blocks = stream(2100, block=100)
    sliding = SlidingSpectrum(2, FS, hop=0.1)
    out = []
    for k, (index, block) in enumerate(blocks):
        if k % 2:
            damping = 1000.0 + k  # one value per block
        else:
            damping = np.full(block.shape[1], 1000.0 + k)  # one value per sample
        out.extend(sliding.push(index, block, damping=damping).spectra)
    assert len(out) == 2
    assert out[0].mean_damping == pytest.approx(1000.0 + np.mean(np.arange(20)))
    assert out[1].mean_damping == pytest.approx(1000.0 + np.mean(np.arange(1, 21)))


def test_mean_damping_is_nan_if_any_sample_lacks_it():
    _, blocks = stream(2000, block=100)
    sliding = SlidingSpectrum(2, FS)
    out = []
    for k, (index, block) in enumerate(blocks):
        out.extend(sliding.push(index, block, damping=None if k == 5 else 800.0).spectra)
    assert len(out) == 1 and np.isnan(out[0].mean_damping)


def test_sliding_parameters_are_validated():
    with pytest.raises(ValueError, match="hop"):
        SlidingSpectrum(2, FS, hop=0.00025)  # a quarter sample
    with pytest.raises(ValueError, match="block"):
        SlidingSpectrum(2, FS).push(0, np.zeros((3, 10)))
    with pytest.raises(ValueError, match="first_sample_index"):
        SlidingSpectrum(2, FS).push(-1, np.zeros((2, 10)))
