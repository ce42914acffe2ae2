"""Faults injected into the graph runs end in one line and the documented exit code
(aero_dva.exits), with the run named, no traceback, and no node left behind:

- ``run_flight``: a node killed mid-flight (3), SIGTERM to the runner (130), a file system
  with no space left (3), an output that cannot be made (2);
- ``dva evaluate --graph``: a node killed in a flight (the flight fails, the evaluation
  completes with 1), an output that cannot be made (2), no space left (3);
- ``replay_flight``: a node killed mid-replay (3), an output that exists or cannot be made (2).

Each waits for a condition (the first block on the wire, a process in the table), never for
a time.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rclpy.node import Node

from aero_dva import exits
from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.schedule_io import save_schedule
from dva_msgs.msg import AccelerationBlock

from .conftest import TIMEOUT_SCALE, ros2_run_path

pytestmark = pytest.mark.ros

RUN_FLIGHT = str(ros2_run_path("aero_dva_sim", "run_flight"))


def _schedule(tmp_path: Path) -> Path:
    return save_schedule(AirspeedSchedule(a0=-2150.0, a1=31.5, airspeed_range=(0.0, 400.0),
                                          damping_range=(0.0, 2500.0)),
                         tmp_path / "schedule.json")


def _children(pid: int) -> dict[int, str]:
    """pid -> command line of the processes whose parent is ``pid``."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            parent = int(stat.rsplit(")", 1)[1].split()[1])
            if parent == pid:
                found[int(entry.name)] = (entry / "cmdline").read_bytes().replace(
                    b"\0", b" ").decode(errors="replace")
        except (OSError, ValueError, IndexError):
            continue
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _flying(tmp_path, ros_domain, executor, ros_context, spin, name="bag"):
    """run_flight (the 30 s ramp at twice real time) on the test's domain, once its first
    block is on the wire: (process, bag, its nodes' pids by name)."""
    probe = Node("probe", context=ros_context)
    executor.add_node(probe)
    blocks = []
    probe.create_subscription(AccelerationBlock, "wing/acceleration", blocks.append, 1000)
    bag = tmp_path / name
    process = subprocess.Popen(
        [RUN_FLIGHT, "--controller", "schedule", "--schedule", str(_schedule(tmp_path)),
         "--real-time-factor", "2", "--output", str(bag), "--domain-id", str(ros_domain)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert spin(executor, lambda: blocks or process.poll() is not None, timeout=120.0)
    assert process.poll() is None, process.communicate()
    nodes = {}
    for pid, command in _children(process.pid).items():
        for node in ("simulator", "airspeed_controller", "mcap_recorder"):
            if f"/{node} " in command:
                nodes[node] = pid
    assert set(nodes) == {"simulator", "airspeed_controller", "mcap_recorder"}, nodes
    return process, bag, nodes


def _one_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


@pytest.mark.parametrize("node", ["airspeed_controller", "simulator", "mcap_recorder"])
def test_a_node_killed_mid_flight_ends_the_run_in_one_line(node, tmp_path, ros_domain, executor,
                                                         ros_context, spin):
    process, bag, nodes = _flying(tmp_path, ros_domain, executor, ros_context, spin)
    os.kill(nodes[node], signal.SIGKILL)
    _, err = process.communicate(timeout=120 * TIMEOUT_SCALE)
    assert process.returncode == exits.FAILED, err
    line = _one_line(err)
    assert line.startswith(f"run_flight: error: {node} was killed by signal 9 before the "
                           "flight ended"), line
    assert f"{bag}_logs" in line  # the run, named
    assert not any(_alive(pid) for pid in nodes.values())  # every node stopped


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT], ids=["TERM", "INT"])
def test_a_signal_to_run_flight_stops_it_in_one_line_like_ctrl_c(stop, tmp_path, ros_domain,
                                                                 executor, ros_context, spin):
    process, bag, nodes = _flying(tmp_path, ros_domain, executor, ros_context, spin)
    process.send_signal(stop)
    _, err = process.communicate(timeout=120 * TIMEOUT_SCALE)
    assert process.returncode == exits.INTERRUPTED, err
    assert _one_line(err) == f"run_flight: interrupted by {stop.name} (run {bag})"
    assert not any(_alive(pid) for pid in nodes.values())
    assert (bag / "metadata.yaml").is_file()  # the recorder closed what it had


def _in_small_file_system(tmp_path: Path, argv: list[str], size: str = "300k"):
    """``argv`` run with ``tmp_path/small`` a tmpfs of ``size`` (in a mount namespace of its
    own, as root there); skipped where mount namespaces are not allowed."""
    small = tmp_path / "small"
    small.mkdir()
    if not shutil.which("unshare") or subprocess.run(
            ["unshare", "-rm", "true"], capture_output=True).returncode != 0:
        pytest.skip("no mount namespace here (unshare -rm) for a small file system")
    script = f'mount -t tmpfs -o size={size} tmpfs "$1" && shift && exec "$@"'
    return subprocess.run(["unshare", "-rm", "sh", "-c", script, "sh", str(small), *argv],
                          capture_output=True, text=True, timeout=600 * TIMEOUT_SCALE)


def test_run_flight_on_a_full_file_system_fails_in_one_line(tmp_path):
    result = _in_small_file_system(tmp_path, [
        RUN_FLIGHT, "--controller", "schedule", "--schedule", str(_schedule(tmp_path)),
        "--output", str(tmp_path / "small" / "bag")])
    assert result.returncode == exits.FAILED, result.stderr
    line = _one_line(result.stderr)
    assert "no space left on the device" in line and "mcap_recorder" in line, line
    assert str(tmp_path / "small" / "bag") in line


# ---------------------------------------------------------------- dva evaluate --graph

def _evaluate(tmp_path, out, *more, **popen):
    argv = [sys.executable, "-m", "dva_offline.cli", "evaluate", "--graph", "--out", str(out),
            "--seeds", "1", "--mu", "0", "--controllers", "fixed", "--fixed-c2", "624.7",
            "--retries", "0", "--reports", "none", "--no-rrd", *more]
    if popen:
        return subprocess.Popen(argv, text=True, **popen)
    return subprocess.run(argv, capture_output=True, text=True, timeout=600 * TIMEOUT_SCALE)


def test_evaluate_graph_refuses_an_output_it_cannot_make(tmp_path):
    (tmp_path / "a_file").write_text("")
    result = _evaluate(tmp_path, tmp_path / "a_file" / "ev", "--json")
    assert result.returncode == exits.BAD_INPUT, result.stderr
    line = _one_line(result.stderr)
    assert line.startswith("dva evaluate: error: ") and "a_file" in line, line
    assert json.loads(result.stdout)["exit_code"] == exits.BAD_INPUT


def test_evaluate_graph_with_a_node_killed_completes_with_the_flight_failed(tmp_path):
    """A flight whose recorder is killed fails (one line in the log and the table), the
    evaluation completes with what it has: exit code 1."""
    out = tmp_path / "ev"
    process = _evaluate(tmp_path, out, "--real-time-factor", "1", "--json",
                        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 300 * TIMEOUT_SCALE
    killed = None
    while killed is None and process.poll() is None and time.monotonic() < deadline:
        for runner in _children(process.pid):  # run_flight, then its nodes
            for pid, command in _children(runner).items():
                # (the recorder's executable: the simulator's command line names the node)
                if "/mcap_recorder " in command and str(out) in command:
                    os.kill(pid, signal.SIGKILL)
                    killed = pid
        time.sleep(0.05)  # polling the process table, not a wait for the flight
    assert killed is not None, process.communicate()
    stdout, err = process.communicate(timeout=600 * TIMEOUT_SCALE)
    assert process.returncode == exits.PARTIAL, err
    assert "Traceback" not in err
    payload = json.loads(stdout)
    assert payload["exit_code"] == exits.PARTIAL and payload["failed"] == 1
    record = json.loads((out / "flights" / "fixed_mu0_seed1.json").read_text())
    assert not record["ok"] and "mcap_recorder was killed by signal 9" in record["error"]


def test_evaluate_graph_on_a_full_file_system_fails_in_one_line(tmp_path):
    out = tmp_path / "small" / "ev"
    result = _in_small_file_system(tmp_path, [
        sys.executable, "-m", "dva_offline.cli", "evaluate", "--graph", "--out", str(out),
        "--seeds", "1", "--mu", "0", "--controllers", "fixed", "--fixed-c2", "624.7",
        "--retries", "0", "--reports", "none", "--no-rrd"], size="400k")
    assert result.returncode == exits.FAILED, result.stderr
    errors = [line for line in result.stderr.splitlines() if "error" in line]
    assert errors and errors[-1].startswith("dva evaluate: error: no space left on the device")
    assert "Traceback" not in result.stderr


# ---------------------------------------------------------------- replay_flight

REPLAY_FLIGHT = str(ros2_run_path("aero_dva_sim", "replay_flight"))


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A 4 s schedule flight recorded by run_flight, and its schedule."""
    root = tmp_path_factory.mktemp("replayed")
    scenario = root / "short.yaml"
    scenario.write_text("name: short\nduration: 4.0\nblock_size: 50\n"
                        "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                        "excitation: {force_std: 1000.0, seed: 2}\n")
    schedule = _schedule(root)
    bag = root / "flight"
    result = subprocess.run([RUN_FLIGHT, "--scenario", str(scenario), "--controller",
                             "schedule", "--schedule", str(schedule), "--output", str(bag)],
                            capture_output=True, text=True, timeout=600 * TIMEOUT_SCALE)
    assert result.returncode == 0, result.stderr
    return bag, schedule


def _replay(recorded, out, *more, **popen):
    bag, schedule = recorded
    argv = [REPLAY_FLIGHT, str(bag), "--controller", "schedule", "--schedule", str(schedule),
            "--out", str(out), *more]
    if popen:
        return subprocess.Popen(argv, text=True, **popen)
    return subprocess.run(argv, capture_output=True, text=True, timeout=600 * TIMEOUT_SCALE)


def test_replay_flight_refuses_outputs_it_cannot_make_in_one_line(recorded, tmp_path):
    (tmp_path / "taken").mkdir()
    (tmp_path / "other_logs").mkdir()
    (tmp_path / "a_file").write_text("")
    for out, said in ((tmp_path / "taken", "exists; choose another name"),
                      (tmp_path / "other", "other_logs' exists; choose another name"),
                      (tmp_path / "a_file" / "out", "is not a directory")):
        result = _replay(recorded, out, "--json")
        assert result.returncode == exits.BAD_INPUT, result.stderr
        line = _one_line(result.stderr)
        assert line.startswith("replay_flight: error: --out ") and said in line, line
        assert json.loads(result.stdout)["exit_code"] == exits.BAD_INPUT
    assert not (tmp_path / "other").exists()  # refused before any work: nothing made


def test_a_node_killed_mid_replay_ends_it_in_one_line(recorded, tmp_path):
    out = tmp_path / "replayed"
    process = _replay(recorded, out, "--rate", "0.25", stdout=subprocess.PIPE,
                      stderr=subprocess.PIPE)
    deadline = time.monotonic() + 300 * TIMEOUT_SCALE
    nodes: dict[str, int] = {}
    while len(nodes) < 3 and process.poll() is None and time.monotonic() < deadline:
        for pid, command in _children(process.pid).items():
            for node in ("bag_player", "airspeed_controller", "mcap_recorder"):
                if f"/{node} " in command:
                    nodes[node] = pid
        time.sleep(0.05)  # polling the process table, not a wait for the replay
    assert len(nodes) == 3, process.communicate()
    # the player plays the 4 s bag in 16 s only once the controller is in the graph: this
    # kill comes before the bag was played
    os.kill(nodes["airspeed_controller"], signal.SIGKILL)
    _, err = process.communicate(timeout=120 * TIMEOUT_SCALE)
    assert process.returncode == exits.FAILED, err
    line = _one_line(err)
    assert line.startswith("replay_flight: error: airspeed_controller was killed by signal 9 "
                           "before the bag was played"), line
    assert f"{out}_logs" in line
    assert not any(_alive(pid) for pid in nodes.values())
