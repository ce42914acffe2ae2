"""Executables resolve and start the way ``ros2 run`` starts them, and publish over DDS."""
from __future__ import annotations

import os
import shutil

import pytest
from rclpy.node import Node

from dva_msgs.msg import DamperCommand

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros


def _first_command(executor, spin, ros_context, topic: str, timeout: float = 20.0):
    listener = Node("listener", context=ros_context)
    received = []
    listener.create_subscription(DamperCommand, topic, received.append, 10)
    executor.add_node(listener)
    spin(executor, lambda: bool(received), timeout)
    return received[0] if received else None


def test_fixed_controller_resolves_like_ros2_run():
    path = ros2_run_path("dva_controller", "fixed_controller")
    assert path.is_file() and os.access(path, os.X_OK), path


def test_fixed_controller_subprocess_publishes(executor, spin, ros_context, start_process):
    path = ros2_run_path("dva_controller", "fixed_controller")
    proc = start_process([path, "--ros-args", "-p", "damping:=750.0", "-p", "rate:=20.0",
                          "-r", "__ns:=/plant"])
    msg = _first_command(executor, spin, ros_context, "/plant/dva/damper_command")
    assert msg is not None, proc.output()
    assert msg.damping == 750.0
    assert msg.source == DamperCommand.SOURCE_FIXED
    assert proc.stop() == 0, proc.output()


@pytest.mark.skipif(shutil.which("ros2") is None, reason="no ros2 command on PATH")
def test_ros2_run_command_starts_node(executor, spin, ros_context, start_process):
    proc = start_process(["ros2", "run", "dva_controller", "fixed_controller",
                          "--ros-args", "-p", "damping:=321.0"])
    msg = _first_command(executor, spin, ros_context, "dva/damper_command")
    assert msg is not None, proc.output()
    assert msg.damping == 321.0
    assert proc.stop() == 0, proc.output()


def test_bad_parameter_fails_with_clear_message(start_process):
    path = ros2_run_path("dva_controller", "fixed_controller")
    proc = start_process([path, "--ros-args", "-p", "damping:=-5.0"])
    assert proc.proc.wait(timeout=120) == 2
    out = proc.output()
    assert "damping" in out and "Traceback" not in out, out
