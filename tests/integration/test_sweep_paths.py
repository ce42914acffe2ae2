"""The training sweep gives the same data through the ROS graph and through the batch path."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import bag_topics, read_messages

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros

# 3 airspeeds x 2 c2 x 1 s, all stable: a small copy of the study's stepped sweep.
SWEEP = """\
name: mini_sweep
duration: auto
sample_rate: 1000.0
block_size: 50
airspeed: {kind: steps, start_ratio: 0.8, end_ratio: 0.84, step_ratio: 0.02}
density: {base: 1.2}
excitation: {force_std: 1000.0, seed: 11}
sweep: {dwell: 1.0, damping: [300.0, 600.0]}
"""
FLIGHT_TOPICS = ("/wing/acceleration", "/wing/displacement", "/wing/excitation",
                 "/flight/condition", "/dva/damper_state", "/clock")


def test_graph_and_batch_sweeps_record_the_same_flight(tmp_path):
    scenario = tmp_path / "sweep.yaml"
    scenario.write_text(SWEEP)
    graph, batch = tmp_path / "graph", tmp_path / "batch"
    flown = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--scenario", str(scenario),
         "--controller", "none", "--output", str(graph), "--json"],
        capture_output=True, text=True, timeout=300)
    assert flown.returncode == 0, flown.stdout + flown.stderr
    dva = Path(sys.executable).with_name("dva")
    recorded = subprocess.run(
        [str(dva), "train", "sweep", "--scenario", str(scenario), "--as-is", "--out", str(batch),
         "--json"], capture_output=True, text=True, timeout=300)
    assert recorded.returncode == 0, recorded.stdout + recorded.stderr
    assert json.loads(recorded.stdout)["method"] == "parallel"

    graph_topics, batch_topics = bag_topics(graph), bag_topics(batch)
    for topic in FLIGHT_TOPICS:  # same types, and the graph lost no message
        assert graph_topics[topic].type_name == batch_topics[topic].type_name
        assert graph_topics[topic].message_count == batch_topics[topic].message_count == 120
    by_graph, by_batch = load_flight_log(graph), load_flight_log(batch)
    assert by_graph.missing_samples == by_batch.missing_samples == 0
    np.testing.assert_array_equal(by_graph.force, by_batch.force)  # the same seeded noise
    np.testing.assert_array_equal(by_graph.airspeed, by_batch.airspeed)
    np.testing.assert_array_equal(by_graph.applied_damping, by_batch.applied_damping)
    assert set(np.unique(by_graph.applied_damping)) == {300.0, 600.0}
    for name in ("displacements", "accelerations"):  # stepped vs parallel in time: round-off
        for a, b in zip(getattr(by_graph, name), getattr(by_batch, name)):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())

    # `--no-displacement`: the measured topics only, the same messages as the full batch bag.
    measured = tmp_path / "measured"
    recorded = subprocess.run(
        [str(dva), "train", "sweep", "--scenario", str(scenario), "--as-is", "--out",
         str(measured), "--no-displacement", "--json"], capture_output=True, text=True,
        timeout=300)
    assert recorded.returncode == 0, recorded.stdout + recorded.stderr
    assert "/wing/displacement" not in json.loads(recorded.stdout)["topics"]
    assert set(bag_topics(measured)) == set(batch_topics) - {"/wing/displacement"}
    kept = [t for t in FLIGHT_TOPICS if t != "/wing/displacement"]
    for topic in kept:
        assert bag_topics(measured)[topic].message_count == 120
    raw = [(m.topic, m.log_time_ns, m.message)
           for m in read_messages(measured, kept, decode=False)]
    assert raw == [(m.topic, m.log_time_ns, m.message)
                   for m in read_messages(batch, kept, decode=False)]
