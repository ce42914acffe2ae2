"""FRF figures: phases unwrapped (dva_offline.plotting), conditions named by their covariates."""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy.fitting import Observations
from dva_offline.discrepancy.report import QUANTITY_UNITS, _condition_label
from dva_offline.plotting import unwrapped_phase_deg as _unwrapped_deg


def test_a_phase_through_minus_180_degrees_is_drawn_without_a_jump():
    phase = np.linspace(-10.0, -400.0, 60)  # a receptance with two modes: past -180 and -360
    values = np.exp(1j * np.radians(phase))
    drawn = _unwrapped_deg(values)
    np.testing.assert_allclose(drawn, phase, atol=1e-9)
    # measured points go on the model's branch, point by point
    noisy = values * np.exp(1j * np.radians(3.0 * np.sin(np.arange(60))))
    np.testing.assert_allclose(_unwrapped_deg(noisy, drawn) - drawn,
                               3.0 * np.sin(np.arange(60)), atol=1e-9)
    # two sweeps stacked in one table: each unwrapped from its own start
    f = np.tile(np.linspace(1.0, 100.0, 60), 2)
    np.testing.assert_allclose(_unwrapped_deg(np.tile(values, 2), frequency=f),
                               np.tile(phase, 2), atol=1e-9)


def test_conditions_are_named_by_their_covariate_levels():
    groups = np.repeat([0, 1], 10)
    obs = Observations(np.ones(20, complex), np.ones(20), np.tile(np.arange(1.0, 11.0), 2),
                       groups, {"temperature_c": np.repeat([9.0, 37.0], 10)})
    assert [_condition_label(obs, g) for g in (0, 1)] == ["temperature_c 9", "temperature_c 37"]
    assert QUANTITY_UNITS["receptance"] == "m/N"
