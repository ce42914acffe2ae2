"""Floquet and frozen-density stability boundaries (control/periodic_stability.py)."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control.periodic_stability import (
    floquet_boundary,
    floquet_growth,
    frozen_boundary,
)
from aero_dva.wing.flutter import flutter_speed, growth_rate
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

CFG = load_wing()
MODEL = AeroelasticModel(CFG.wing, CFG.absorber, CFG.aero)
C2 = 625.0


def test_constant_density_gives_the_eigenvalues():
    u = np.array([90.0, 110.0, 120.0])
    np.testing.assert_allclose(floquet_growth(MODEL, u, 1.2, 0.0, 1.0, C2),
                               growth_rate(MODEL, u, 1.2, C2), rtol=1e-6, atol=1e-9)
    u_f = flutter_speed(MODEL, 1.2, damping=C2).critical_airspeed
    assert floquet_boundary(MODEL, 1.2, 0.0, 1.0, C2) == pytest.approx(u_f, abs=2e-3)
    assert frozen_boundary(MODEL, 1.2, C2) == pytest.approx(u_f, abs=2e-3)
    # a c2 law that is constant is the constant c2
    assert frozen_boundary(MODEL, 1.32, lambda u, rho: np.full(np.shape(u), C2)) == \
        pytest.approx(flutter_speed(MODEL, 1.32, damping=C2).critical_airspeed, abs=2e-3)


def test_very_slow_variation_averages_the_leading_frozen_growth_over_the_cycle():
    """Adiabatic limit: as the period grows the mean growth tends to the cycle mean of the
    frozen largest real part. At 112 m/s two modes take turns at leading the cycle; a 20 s
    period is too fast for the response to follow the switch, so it grows more slowly."""
    u, mu = 112.0, 0.1
    t = (np.arange(2000) + 0.5) / 2000
    frozen = np.mean([growth_rate(MODEL, u, 1.2 * (1 + mu * np.sin(2 * np.pi * s)), C2)
                      for s in t])
    adiabatic = floquet_growth(MODEL, [u], 1.2, mu, 1e-4, C2, max_step=0.5)[0]  # 10 000 s
    assert adiabatic == pytest.approx(frozen, abs=0.01)
    assert floquet_growth(MODEL, [u], 1.2, mu, 0.05, C2)[0] < frozen - 0.3


def test_density_pumped_near_twice_the_flutter_frequency_lowers_the_boundary():
    flutter = flutter_speed(MODEL, 1.2, damping=C2)
    worst = frozen_boundary(MODEL, 1.32, C2)  # the cycle's densest frozen wing
    one_hz = floquet_boundary(MODEL, 1.2, 0.1, 1.0, C2)
    pumped = floquet_boundary(MODEL, 1.2, 0.1, 2 * flutter.flutter_frequency, C2)
    # 1 Hz is fast against the growth: between the mean and the worst frozen boundary
    assert worst < one_hz < flutter.critical_airspeed
    # near twice the flutter frequency the modulation pumps the mode: below the 1 Hz boundary
    assert pumped < one_hz - 0.5


def test_a_fast_growing_period_does_not_overflow():
    g = floquet_growth(MODEL, [190.0], 1.2, 0.1, 0.05, C2)
    assert np.isfinite(g).all() and g[0] > 10.0
