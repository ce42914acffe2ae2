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
    # 10x growth takes ln(10)/1.5 = 1.5 s, read at the end of a 1 s window: ~22 s, 109.3 m/s
    assert 106.7 < u_d[0] < 110.0
    assert np.isnan(u_d[1])
    with pytest.raises(ValueError, match="factor"):
        divergence_airspeed(u, x[0], fs, factor=0.5)
