"""The nodes started by hand with config/graph.yaml record what run_flight records (docs/nodes.md).

The recorder, the fixed controller and the simulator, each ``ros2 run`` with
``--ros-args --params-file config/graph.yaml`` as the page says, fly the default ramp; then
``run_flight --controller fixed`` flies it. Every recorded array of the two flights agrees to
1e-9 relative (processes on other schedules may differ in the last bit), and the hand-started
simulator never flew ahead of its controller.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from aero_dva.bag.flight_log_io import load_flight_log

from .conftest import ros2_run_path

pytestmark = [pytest.mark.ros, pytest.mark.slow]

GRAPH = Path(__file__).resolve().parents[2] / "config" / "graph.yaml"
ARRAYS = ("time", "airspeed", "density", "force", "applied_damping", "displacements",
          "accelerations")


def _by_hand(start_process, bag: Path):
    """Start the three nodes as docs/nodes.md does; the simulator's process when it ended."""
    params = ["--ros-args", "--params-file", str(GRAPH)]
    recorder = start_process([ros2_run_path("aero_dva_sim", "mcap_recorder"), *params,
                              "-p", f"output:={bag}"])
    controller = start_process([ros2_run_path("dva_controller", "fixed_controller"), *params])
    simulator = start_process([ros2_run_path("aero_dva_sim", "simulator"), *params])
    assert simulator.proc.wait(timeout=600) == 0, simulator.output()
    assert controller.stop() == 0, controller.output()
    assert recorder.stop() == 0, recorder.output()
    return simulator


def test_the_nodes_by_hand_record_run_flights_flight(start_process, tmp_path):
    simulator = _by_hand(start_process, tmp_path / "by_hand")
    assert "FLYING AHEAD" not in simulator.output()
    result = subprocess.run([str(ros2_run_path("aero_dva_sim", "run_flight")), "--controller",
                             "fixed", "--output", str(tmp_path / "run_flight"), "--json"],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["blocks_fallback"] == 0
    hand, flown = load_flight_log(tmp_path / "by_hand"), load_flight_log(tmp_path / "run_flight")
    for name in ARRAYS:
        a, b = np.asarray(getattr(hand, name)), np.asarray(getattr(flown, name))
        assert a.shape == b.shape, name
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=0.0, equal_nan=True, err_msg=name)
    assert np.isfinite(hand.airspeed).all() and hand.time.size > 20000  # the flight, not a stub
