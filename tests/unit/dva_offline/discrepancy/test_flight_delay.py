"""The flight domain's sensor-delay candidate: outputs delayed by (fractional) samples."""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy.flight_domain import delay_outputs as delay


def test_delay_shifts_whole_samples_exactly_and_interpolates_between():
    rng = np.random.default_rng(2)
    t = np.arange(4000)
    y = np.stack([np.sin(2 * np.pi * 0.01 * t), rng.standard_normal(4000)])
    shifted = delay(y, 3)
    np.testing.assert_allclose(shifted[:, 3:], y[:, :-3], atol=1e-12)
    np.testing.assert_allclose(shifted[:, :3], 0.0, atol=1e-12)
    half = delay(y[:1], 2.5)[0, 100:-100]  # a slow sine: band-limited interpolation is exact
    np.testing.assert_allclose(half, np.sin(2 * np.pi * 0.01 * (t[100:-100] - 2.5)), atol=1e-3)
