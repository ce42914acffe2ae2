"""replay_flight's output watch: the replay ends when its outputs have gone by, not after a
fixed time (a busy machine can hold the spectrum node and the controller seconds behind)."""
from __future__ import annotations

import time

import pytest
from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva_sim.replay_flight import OutputWatch, build_parser, watched_channels
from dva_msgs.msg import DamperCommand

from .conftest import TIMEOUT_SCALE

pytestmark = pytest.mark.ros


def test_watch_waits_for_the_expected_count_and_no_longer(ros_domain):
    watch = OutputWatch(ros_domain, watched_channels("schedule"))
    topic = ch.DAMPER_COMMAND.absolute()
    sender = Node("sender", context=watch.context)
    try:
        pub = sender.create_publisher(DamperCommand, topic, 10)
        deadline = time.monotonic() + 30.0 * TIMEOUT_SCALE
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            watch.spin(0.05)
        for _ in range(5):
            pub.publish(DamperCommand(damping=500.0))
        assert watch.wait_for_outputs({topic: 5}, quiet=2.0, timeout=30.0 * TIMEOUT_SCALE)
        assert watch.counts[topic] == 5
        # a sixth never comes: the wait says so when its bound runs out
        assert not watch.wait_for_outputs({topic: 6}, quiet=2.0, timeout=0.5)
        # without an expected count: done once nothing came for the quiet time
        assert watch.wait_for_outputs({}, quiet=0.3, timeout=30.0 * TIMEOUT_SCALE)
        assert time.monotonic() - watch.last >= 0.3
    finally:
        sender.destroy_node()
        watch.close()


def test_what_is_watched_and_the_expected_counts_on_the_command_line():
    assert [c.name for c in watched_channels("rbf")] == ["dva/spectrum", "dva/damper_command"]
    assert [c.name for c in watched_channels("schedule")] == ["dva/damper_command"]
    assert watched_channels("fixed") == []  # its commands come from its own timer
    args = build_parser().parse_args(["bag", "--controller", "rbf", "--network", "n.npz",
                                      "--out", "o", "--expect-spectra", "21",
                                      "--expect-commands", "21"])
    assert (args.expect_spectra, args.expect_commands) == (21, 21)
