"""The issue's hostile node starts, as ``ros2 run`` starts the nodes: a 0-sample, 1e-4 s,
1 Hz, 1e9 Hz, force-free or ten-hour scenario, absurd absorber and damper parameters, and
topic names a recorder cannot subscribe: each refused in one line, exit 2, no traceback."""
from __future__ import annotations

import pytest

from bench.faults import number_fuzz

pytestmark = pytest.mark.ros


def test_hostile_node_starts_are_refused_in_one_line(tmp_path, ros_domain, monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    trials = list(number_fuzz.node_start_trials(tmp_path, timeout=120.0))
    assert len(trials) == len(number_fuzz.NODE_STARTS)
    bad = [t for t in trials if t.outcome != "refused"]
    assert not bad, bad
    long_name = next(t for t in trials if t.field == "topic of 10,000 characters")
    assert "(9,880 more characters)" in long_name.message and len(long_name.message) < 700
