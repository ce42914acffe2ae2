"""The controllers' command laws: RBF output and airspeed schedule, clamped; rejections."""
from __future__ import annotations

import math

import numpy as np

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.command_laws import RBFLaw, ScheduleLaw
from aero_dva.control.rbf_network import spectrum_input_names, train_rbf_ols


def _network():
    rng = np.random.default_rng(0)
    n = 60
    mags = rng.dirichlet(np.ones(16), size=(n, 2))
    damping = rng.uniform(300.0, 1500.0, n)
    inputs = np.column_stack([mags.reshape(n, 32), damping])
    targets = 400.0 + 3000.0 * mags[:, 0, 7] + 0.3 * damping
    names, units = spectrum_input_names()
    net = train_rbf_ols(inputs, targets, spread=2.0, max_neurons=15, input_names=names,
                        input_units=units).network
    return net, mags, damping


def test_rbf_law_is_the_network_output_clamped():
    net, mags, damping = _network()
    law = RBFLaw(net, (0.0, 2500.0))
    x = np.append(mags[0].ravel(), damping[0])
    c2, activation = law.command(mags[0], damping[0])
    assert c2 == float(net.predict(x)) and 0.0 < activation <= 1.0
    narrow = RBFLaw(net, (0.0, 100.0))
    assert narrow.command(mags[0], damping[0])[0] == 100.0


def test_schedule_law_rejects_bad_airspeeds_and_limits_the_rate():
    schedule = AirspeedSchedule(a0=-2000.0, a1=30.0, airspeed_range=(100.0, 120.0),
                                damping_range=(200.0, 1800.0))
    law = ScheduleLaw(schedule, (200.0, 1000.0), True, 400.0, min_period_ns=100_000_000)
    first = law.step(0, 110.0)
    assert first.kind == "command" and first.damping == 1000.0  # 1300 clamped
    assert law.step(50_000_000, 110.0).kind == "rate_limited"
    assert law.step(100_000_000, 75.0).damping == 250.0
    for bad in (math.nan, math.inf, -1.0, 401.0):
        result = law.step(10**9, bad)
        assert result.kind == "rejected" and "airspeed" in result.reason
