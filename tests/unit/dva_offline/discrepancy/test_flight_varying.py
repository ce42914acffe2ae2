"""The whole-flight route's pieces: the damper lag the analysis applies to a per-sample law's
commanded c2 is the flight runtime's own, and a log without the commanded c2 is refused."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from aero_dva.control.switching_io import with_switching
from aero_dva.data_files import data_file
from aero_dva.flight.damper import SWITCHING_SOURCE
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from dva_offline.discrepancy.flight_domain import FlightDataError, arrays_from_log
from dva_offline.discrepancy.flight_varying import lagged_c2, law_runs

TAU = 0.01  # [s] the damper's lag in the runtime below
START_C2 = 624.7  # [N s/m] the c2 the damper holds before the law is armed


def switching_flight(tmp_path, tau=TAU):
    """(commanded, acting, law flew) per sample of a switching flight at 1.1 U_cr whose first
    10 blocks hold START_C2."""
    scenario = tmp_path / "hold.yaml"
    scenario.write_text("name: hold\nduration: 1.5\nblock_size: 50\n"
                        "airspeed: {kind: constant, value_ratio: 1.1}\n"
                        "excitation: {force_std: 1000.0, seed: 7}\n")
    config = load_runtime_config({"scenario": str(scenario), "damper_time_constant": tau})
    rt = FlightRuntime(with_switching(config, str(data_file("switching_gains.json"))))
    commanded, acting = [], []
    for b in range(rt.scenario.n_samples // rt.block_size):
        rt.command(START_C2, SWITCHING_SOURCE if b >= 10 else "fixed")
        block = rt.step()
        law = rt.commanded_damping(block)
        commanded.append(block.damping if law is None else law)
        acting.append(block.damping)
        if law is not None:
            assert set(np.unique(law)) <= {100.0, 2500.0}
    commanded, acting = np.concatenate(commanded), np.concatenate(acting)
    flew = np.arange(commanded.size) >= 10 * rt.block_size
    return commanded, acting, flew, rt.sample_rate


def test_the_lag_applied_to_the_commands_is_the_runtime_dampers(tmp_path):
    commanded, acting, flew, fs = switching_flight(tmp_path)
    assert np.unique(commanded[flew]).size == 2 and np.unique(acting[flew]).size > 10
    start = np.full(commanded.size, START_C2)
    # the runtime flies the lag's mean over each sample on a table of levels 5.2 % apart
    half_level = 0.5 * np.log(2500.0 / 100.0) / 64
    err = np.abs(np.log(lagged_c2(commanded, flew, start, TAU, 1 / fs) / acting))[flew]
    assert err.max() < half_level * 1.001
    # a lag three times too slow or none at all does not reproduce it
    for wrong in (3 * TAU, 0.0):
        err = np.abs(np.log(lagged_c2(commanded, flew, start, wrong, 1 / fs) / acting))[flew]
        assert err.max() > 10 * half_level


def test_lagged_c2_leaves_held_samples_and_refuses_a_bad_time_constant():
    command = np.array([500.0, 500.0, 100.0, 2500.0, 2500.0, 700.0])
    mask = np.array([False, False, True, True, True, False])
    out = lagged_c2(command, mask, np.full(6, 500.0), 0.02, 1e-3)
    assert out[0] == out[1] == 500.0 and out[5] == 700.0
    assert 100.0 < out[2] < 500.0 and 100.0 < out[3] < 2500.0 and out[3] < out[4] < 2500.0
    assert law_runs(mask) == [(2, 5)]
    np.testing.assert_array_equal(lagged_c2(command, mask, command, 0.0, 1e-3), command)
    with pytest.raises(ValueError, match="time_constant"):
        lagged_c2(command, mask, command, float("nan"), 1e-3)


class _Log:
    """The fields of a FlightLog that arrays_from_log reads."""

    def __init__(self, n, law_command):
        self.sample_rate = 1000.0
        self.force = np.ones(n)
        self.accelerations = np.ones((3, n))
        self.displacements = np.ones((3, n))
        self.airspeed = np.full(n, 80.0)
        self.density = np.full(n, 1.225)
        self.applied_damping = np.full(n, 600.0)
        self.law_damping = np.where(np.arange(n) >= 10, 300.0, np.nan)
        self.law_command = law_command


def test_a_law_flight_without_its_commanded_c2_is_refused():
    n = 20
    with pytest.raises(FlightDataError, match="commanded_damping"):
        arrays_from_log(_Log(n, np.full(n, np.nan)))
    data = arrays_from_log(_Log(n, np.where(np.arange(n) >= 10, 2500.0, np.nan)), ("switching",))
    assert data.per_sample and data.law_sources == ("switching",)
    # the analysis reads the commanded c2 where the law flew, the reported one elsewhere
    assert np.all(data.damping[10:] == 2500.0) and np.all(data.damping[:10] == 600.0)
    assert dataclasses.replace(data, law_flew=None).per_sample is False
