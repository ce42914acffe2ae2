"""The clipped-optimal law through the graph: ``run_flight --controller clipped_optimal`` starts
its supervisor (``clipped_optimal_controller``), gives the simulator its gains, its 10 ms damper
lag and 5 % sensor noise, and the damper runs the law every sample of the flight."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from aero_dva.bag.reader import read_messages
from aero_dva.flight.damper import DamperMode

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros


def test_run_flight_flies_the_clipped_optimal_law_in_the_damper_path(tmp_path):
    scenario = tmp_path / "short.yaml"
    scenario.write_text("name: short\nduration: 3.0\nblock_size: 50\n"
                        "airspeed: {kind: ramp, start_ratio: 1.0, end_ratio: 1.2}\n"
                        "excitation: {force_std: 1000.0, seed: 3}\n")
    bag = tmp_path / "flight"
    result = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--scenario", str(scenario),
         "--controller", "clipped_optimal", "--damping", "624.7", "--output", str(bag),
         "--real-time-factor", "0", "--json"],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(result.stdout)
    assert summary["controller"] == "clipped_optimal"
    assert summary["blocks_switching"] >= 0.9 * summary["blocks"]  # armed every block
    assert summary["switching_rate_mean"] > 10.0  # it switches within the blocks
    states = [m.message for m in read_messages(bag, ["/dva/damper_state"])]
    armed = [s for s in states if s.mode == DamperMode.SWITCHING]
    assert armed and all(s.source == "clipped_optimal" for s in armed)
    # the lagged c2 at the blocks' starts moves between the law's levels, 100..2500 N s/m
    c2 = np.array([s.applied_damping for s in armed])
    assert 100.0 <= c2.min() < 600.0 < 1500.0 < c2.max() <= 2500.0
    log = (bag.parent / (bag.name + "_logs") / "simulator.log").read_text()
    assert "clipped-optimal law armed in the damper path" in log
