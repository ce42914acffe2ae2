"""A log written by the simulator node (ROS graph) with a hidden plant goes through the CLI."""
from __future__ import annotations

import json
import subprocess

import pytest

from dva_offline.cli import main

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros

SCENARIO = """\
name: hidden_delay
duration: auto
block_size: 50
airspeed: {kind: steps, ratios: [0.6, 0.75, 0.68]}
excitation: {force_std: 1000.0, seed: 3, levels: [1.0, 3.0], level_dwell: 8.0}
sweep: {dwell: 4.0, damping: [200.0, 1200.0]}
plant:
  sensor_delay: {delay: 0.006}
  sensor_noise: {plunge: 0.02, pitch: 0.04, leading_edge: 0.04}
"""


def test_node_log_with_a_hidden_sensor_delay_is_explained(tmp_path, capsys):
    scenario = tmp_path / "hidden.yaml"
    scenario.write_text(SCENARIO)
    bag = tmp_path / "flight"
    result = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--scenario", str(scenario),
         "--controller", "fixed", "--damping", "500", "--output", str(bag), "--json"],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert main(["discrepancy", "flight", str(bag), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"]["status"] == "explained", out["verdict"]
    assert out["verdict"]["effect"] == "sensor_delay"
    (delay,) = out["augmented"]["parameters"]
    assert abs(delay["value"] - 0.006) < 0.0005
    assert out["augmented"]["error"] < 0.5 * out["baseline"]["error"]
