"""Executables resolve and start the way ``ros2 run`` starts them, and publish over DDS."""
from __future__ import annotations

import contextlib
import os
import shutil
import time
from pathlib import Path

import pytest
from rclpy.node import Node

from aero_dva.control.controllers import controller
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
    assert msg.source == controller("fixed").source
    assert proc.stop() == 0, proc.output()


def test_a_node_removes_the_unsized_port_files_that_would_hang_it(executor, spin, ros_context,
                                                                 ros_domain, start_process):
    """Port files a dead process left at size 0 (docs/reliability.md) on this test's domain,
    for its first four participants: the node removes them before DDS starts, then runs."""
    then = time.time() - 120.0
    planted = []
    for participant in range(4):  # Fast DDS's unicast port: 7400 + 250 domain + 11 + 2 p
        port = Path(f"/dev/shm/fastrtps_port{7400 + 250 * ros_domain + 11 + 2 * participant}")
        if not port.exists():  # an existing one belongs to a live participant
            port.touch()
            os.utime(port, (then, then))
            planted.append(port)
    path = ros2_run_path("dva_controller", "fixed_controller")
    proc = start_process([path, "--ros-args", "-p", "damping:=640.0"])

    def unsized():  # a removed port may come back, sized, as the node's own
        left = []
        for port in planted:
            with contextlib.suppress(FileNotFoundError):
                if port.stat().st_size == 0:
                    left.append(port)
        return left

    deadline = time.monotonic() + 60.0
    while unsized() and time.monotonic() < deadline:
        time.sleep(0.05)  # polling the files: the condition itself
    assert not unsized(), proc.output()
    msg = _first_command(executor, spin, ros_context, "dva/damper_command")
    assert msg is not None and msg.damping == 640.0, proc.output()
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


def test_misspelt_parameter_is_refused_in_one_line(start_process, tmp_path):
    """``-p dampng:=750.0`` (or a parameters file's misspelt key) ends the node with exit 2 and
    one line naming it; the node does not run on its default damping."""
    path = ros2_run_path("dva_controller", "fixed_controller")
    params = tmp_path / "params.yaml"
    params.write_text("fixed_controller:\n  ros__parameters:\n    dampng: 750.0\n")
    for ros_args in (["-p", "dampng:=750.0"], ["--params-file", str(params)]):
        proc = start_process([path, "--ros-args", *ros_args])
        assert proc.proc.wait(timeout=120) == 2
        out = proc.output().strip()
        assert out.splitlines() == [
            "fixed_controller: error: unknown parameter 'dampng': fixed_controller has "
            "damping, rate, hold_until_subscribers (see --help)"], out
