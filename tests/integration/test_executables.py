"""Every executable starts the way ``ros2 run`` starts it; the runner flies a whole graph."""
from __future__ import annotations

import json
import os
import signal
import subprocess

import pytest
from rclpy.node import Node

from aero_dva.bag.flight_log_io import load_flight_log
from dva_msgs.msg import DamperCommand

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros

NODES = {
    ("aero_dva_sim", "simulator"): ["-p", "wait_for_subscribers:=1", "-p", "wait_timeout:=600.0"],
    ("aero_dva_sim", "mcap_recorder"): ["-p", "output:={tmp}/bag"],
    ("dva_controller", "fixed_controller"): [],
    ("dva_controller", "spectrum"): [],
    ("dva_controller", "airspeed_controller"): [],
    ("dva_controller", "switching_controller"): [],
}


# run_node handles SIGINT and SIGTERM with one handler: every node gets SIGINT, and SIGTERM
# goes to the two whose stop does most (the simulator's flight, the recorder's bag).
STOPS = [(signal.SIGINT, node) for node in sorted(NODES)] + [
    (signal.SIGTERM, ("aero_dva_sim", "simulator")),
    (signal.SIGTERM, ("aero_dva_sim", "mcap_recorder"))]


@pytest.mark.parametrize(("stop_signal", "node"), STOPS,
                         ids=[f"{s.name[3:]}-{p}-{e}" for s, (p, e) in STOPS])
def test_node_starts_joins_the_graph_and_stops_cleanly(stop_signal, node, executor, spin,
                                                       ros_context, start_process, tmp_path):
    package, executable = node
    path = ros2_run_path(package, executable)
    assert path.is_file() and os.access(path, os.X_OK), path
    args = [a.format(tmp=tmp_path) for a in NODES[(package, executable)]]
    proc = start_process([path, "--ros-args", "-r", "__node:=under_test", *args])
    observer = Node("observer", context=ros_context)
    executor.add_node(observer)
    joined = spin(executor, lambda: "under_test" in observer.get_node_names(), timeout=30.0)
    assert joined, proc.output()
    # The nodes spin on the events executor, which only notices a shutdown between its slices.
    # A node that runs until stopped ends 0; the simulator, stopped before its flight, 130.
    expected = 130 if executable == "simulator" else 0
    assert proc.stop(signal_number=stop_signal) == expected, proc.output()


@pytest.mark.parametrize("kind", ["single_threaded", "events"])
def test_executor_choice_by_environment(kind, executor, spin, ros_context, start_process,
                                        monkeypatch):
    monkeypatch.setenv("DVA_EXECUTOR", kind)
    proc = start_process([ros2_run_path("dva_controller", "fixed_controller"), "--ros-args",
                          "-r", "__node:=under_test", "-p", "damping:=321.0"])
    observer = Node("observer", context=ros_context)
    executor.add_node(observer)
    got = []
    observer.create_subscription(DamperCommand, "dva/damper_command", got.append, 10)
    assert spin(executor, lambda: len(got) >= 3, timeout=30.0), proc.output()
    assert got[-1].damping == pytest.approx(321.0)
    assert proc.stop() == 0, proc.output()


@pytest.mark.parametrize("executable", ["mcap_recorder", "fixed_controller"])
def test_unknown_executor_is_a_clear_error(executable, start_process, monkeypatch, tmp_path):
    monkeypatch.setenv("DVA_EXECUTOR", "turbo")
    package = "aero_dva_sim" if executable == "mcap_recorder" else "dva_controller"
    proc = start_process([ros2_run_path(package, executable), "--ros-args",
                          "-p", f"output:={tmp_path}/bag"] if executable == "mcap_recorder"
                         else [ros2_run_path(package, executable)])
    assert proc.proc.wait(timeout=120) == 2
    assert "DVA_EXECUTOR='turbo' is not one of" in proc.output()
    assert not (tmp_path / "bag").exists()  # nothing written before the error


def test_every_console_script_is_installed_where_ros2_run_looks():
    from ament_index_python.packages import get_package_prefix

    for package in ("aero_dva_sim", "dva_controller"):
        prefix = get_package_prefix(package)
        installed = set(os.listdir(os.path.join(prefix, "lib", package)))
        expected = {exe for pkg, exe in NODES if pkg == package}
        assert expected <= installed, (package, installed)
    assert "rbf_controller" in os.listdir(
        os.path.join(get_package_prefix("dva_controller"), "lib", "dva_controller"))
    assert "run_flight" in os.listdir(
        os.path.join(get_package_prefix("aero_dva_sim"), "lib", "aero_dva_sim"))


def test_run_flight_flies_the_graph_and_leaves_a_readable_bag(tmp_path):
    scenario = tmp_path / "short.yaml"
    scenario.write_text("name: short\nduration: 4.0\nblock_size: 50\n"
                        "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                        "excitation: {force_std: 1000.0, seed: 2}\n")
    bag = tmp_path / "flight"
    result = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--scenario", str(scenario),
         "--controller", "fixed", "--damping", "600", "--output", str(bag), "--json"],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(result.stdout)
    assert summary["controller"] == "fixed" and summary["divergence_airspeed"] is None
    assert summary["duration"] == pytest.approx(4.0)
    assert 500.0 <= summary["mean_damping"] <= 600.0  # the wing file's c2 until the first command
    assert all(code == 0 for code in summary["exit_codes"].values()), summary["exit_codes"]
    phases = summary["phase_wall_times"]  # where run_flight's wall time went
    assert phases["flight"] == summary["flight_wall_time"]
    assert all(phases[k] > 0 for k in ("start", "flight", "stop"))
    assert phases["start"] + phases["flight"] + phases["stop"] == pytest.approx(
        summary["wall_time"])
    log = load_flight_log(bag)
    assert log.missing_samples == 0 and log.time.size == 4000
    assert log.applied_damping[-1] == 600.0


def test_run_flight_refuses_bad_arguments(tmp_path):
    run_flight = str(ros2_run_path("aero_dva_sim", "run_flight"))
    result = subprocess.run([run_flight, "--controller", "rbf"], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2 and "--network FILE" in result.stderr
    existing = tmp_path / "exists"
    existing.mkdir()
    (tmp_path / "other_logs").mkdir()  # the logs folder of --output other
    (tmp_path / "a_file").write_text("")
    for output, said in ((existing, "exists; choose another name"),
                         (tmp_path / "other", "other_logs' exists; choose another name"),
                         (tmp_path / "a_file" / "bag", "is not a directory")):
        result = subprocess.run([run_flight, "--output", str(output), "--json"],
                                capture_output=True, text=True, timeout=60)
        assert result.returncode == 2, result.stderr
        (line,) = result.stderr.strip().splitlines()  # one line, no traceback
        assert line.startswith("run_flight: error: --output ") and said in line, line
        assert json.loads(result.stdout)["exit_code"] == 2
    assert not (tmp_path / "other").exists()  # refused before any work: nothing made


