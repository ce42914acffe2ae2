"""The study's ramp flight and the divergence airspeed read off a flight."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.flight.divergence import divergence_airspeed, ramp_airspeed


def test_ramp_airspeed_is_the_study_flight():
    u = ramp_airspeed(100.0)
    assert u.shape == (30000,)
    assert u[0] == pytest.approx(80.0) and u[-1] == pytest.approx(120.0, abs=2e-3)


def test_divergence_airspeed_reads_the_onset_of_growth():
    rng = np.random.default_rng(6)
    fs, n = 1000.0, 30000
    u = ramp_airspeed(100.0)
    t = np.arange(n) / fs
    x = rng.standard_normal((2, n))
    x[0, t > 20.0] *= np.exp(1.5 * (t[t > 20.0] - 20.0))  # grows from 20 s (U = 106.7)
    x[1, 12000:12300] *= 100.0  # a single burst that does not last
    u_d = divergence_airspeed(u, x, fs)
    # 10x growth takes ln(10)/1.5 = 1.5 s, read at the end of a 1 s window: ~21.5 s, 108.7 m/s
    assert 106.7 < u_d[0] < 110.0
    assert np.isnan(u_d[1])
    assert divergence_airspeed(u, x[0], fs) == u_d[0]  # one flight as in a batch
    with pytest.raises(ValueError, match="three windows"):
        divergence_airspeed(u[:2500], x[0, :2500], fs)


def test_windows_slide_by_a_twentieth_of_a_second():
    """Whole 1 s windows would read U_div on a 1.33 m/s grid of this ramp; the sliding ones
    read it on a 0.067 m/s grid, at the end of the first window that stays above for good."""
    rng = np.random.default_rng(0)
    n, fs = 30000, 1000.0
    u = np.linspace(80.0, 120.0, n, endpoint=False)
    x = rng.normal(0, 1e-3, n)
    t = np.arange(n) / fs
    x[24000:] *= np.exp(3.0 * (t[24000:] - 24.0))
    u_d = divergence_airspeed(u, x, fs)
    # RMS x10 needs ln(10)/3 = 0.77 s of growth after 24 s (U = 112): the window ending there
    assert 112.0 < u_d < 114.0
    end = int(np.flatnonzero(u == u_d)[0]) + 1  # the window ends after this sample
    assert (end - 1000) % 50 == 0
    quiet = rng.normal(0, 1e-3, n)
    assert np.isnan(divergence_airspeed(u, quiet, fs))


def test_a_blown_up_flight_counts_as_diverged():
    u = np.linspace(80.0, 120.0, 10000, endpoint=False)
    x = np.random.default_rng(1).normal(0, 1e-3, 10000)
    x[8000:] = np.inf
    assert 112.0 < divergence_airspeed(u, x, 1000.0) < 113.0
