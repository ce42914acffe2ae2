"""run_flight gives the same record idle, beside busy loops and with four flights started at
once, and never reports a flight its controller did not fly as controlled.

The record (divergence, leading-edge RMS, mean applied c2, commands) is compared digit for digit:
the flights run the same code with the same seed on one machine, and in lockstep the simulator
applies every command at the block the controller answered, so the c2 history, and with it
every sample, is the same whatever the load (docs/reliability.md). A short ramp whose schedule
changes c2 every block makes any difference in timing show in the mean c2.
"""
from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import read_messages
from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.schedule_io import save_schedule
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from dva_ros_common.conversions import time_to_seconds

from .conftest import ros2_run_path

RECORD = ("divergence_ratio", "leading_edge_rms", "mean_damping", "commands_recorded",
          "commands_received", "blocks_startup", "blocks_fallback", "data_published",
          "data_missing", "end_report_recorded")
BUSY_LOOP = "while True:\n    pass\n"
AT_ONCE = 4  # flights started together


def _files(tmp_path):
    scenario = tmp_path / "short.yaml"
    scenario.write_text("name: short\nduration: 3.0\nblock_size: 50\n"
                        "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                        "excitation: {force_std: 1000.0, seed: 5}\n")
    schedule = save_schedule(AirspeedSchedule(a0=-2150.0, a1=31.5, airspeed_range=(0.0, 400.0),
                                              damping_range=(0.0, 2500.0)),
                             tmp_path / "schedule.json")
    return scenario, schedule


def _fly(tmp_path, name: str | None, *args: str, cwd=None) -> subprocess.CompletedProcess:
    """run_flight into ``tmp_path / name`` (None: its default name, in ``cwd``)."""
    output = [] if name is None else ["--output", str(tmp_path / name)]
    return subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), *output, "--json", *args],
        capture_output=True, text=True, timeout=600, cwd=cwd)


def _record(result: subprocess.CompletedProcess) -> tuple:
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(result.stdout)
    return tuple(summary[k] for k in RECORD)


def test_same_record_idle_and_beside_busy_loops(tmp_path):
    scenario, schedule = _files(tmp_path)
    args = ("--scenario", str(scenario), "--controller", "schedule", "--schedule", str(schedule))
    idle = [_record(_fly(tmp_path, "idle", *args))]
    busy = [subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) for _ in range(2)]
    try:
        # AT_ONCE flights started together in one folder with the default bag name, which
        # holds the UTC second: each gets a bag (and logs) of its own and flies the idle
        # record (docs/reliability.md: runs side by side)
        runs = tmp_path / "together"
        runs.mkdir()
        with ThreadPoolExecutor(max_workers=AT_ONCE) as pool:
            results = list(pool.map(lambda _: _fly(None, None, *args, cwd=runs),
                                    range(AT_ONCE)))
    finally:
        for process in busy:
            process.kill()
            process.wait()
    loaded = [_record(r) for r in results]
    assert loaded == [idle[0]] * AT_ONCE, (idle, loaded)
    bags = {json.loads(r.stdout)["bag"] for r in results}
    assert len(bags) == AT_ONCE and all(Path(b).parent == runs / "runs" for b in bags)
    assert len(list((runs / "runs").glob("*_logs"))) == AT_ONCE
    record = dict(zip(RECORD, idle[0]))
    # 60 blocks: the first on the start-up c2, every other one on a command; one command per
    # flight condition in the bag, every one but the last block's received in time
    assert record["blocks_startup"] == 1 and record["blocks_fallback"] == 0
    assert record["commands_received"] == 59 and record["commands_recorded"] == 60
    assert record["divergence_ratio"] is None
    # every data message the simulator published is in the bag: one per block and topic
    assert record["end_report_recorded"] and record["data_missing"] == 0
    assert record["data_published"] == 60 * 5
    # The bag's c2 at each sample is the c2 that sample was flown with: the bag's commands,
    # each handed to the flight runtime before the block after the one it answered (lockstep),
    # give its samples bit for bit, and the replay's c2 is the bag's (the damper state of
    # each block's start).
    log = load_flight_log(tmp_path / "idle")
    runtime = FlightRuntime(load_runtime_config({"scenario": str(scenario)}))
    commands = [(m.message.header.stamp, m.message) for m in read_messages(
        tmp_path / "idle", ["/dva/damper_command"])]
    blocks, k = [], 0
    while not runtime.done:
        while k < len(commands) and time_to_seconds(commands[k][0]) < runtime.time - 1e-9:
            runtime.command(commands[k][1].damping, commands[k][1].source)
            k += 1
        blocks.append(runtime.step())
    np.testing.assert_array_equal(np.concatenate([b.displacements for b in blocks], axis=1),
                                  log.displacements)
    flown = np.concatenate([b.damping for b in blocks])
    np.testing.assert_array_equal(log.applied_damping, flown)
    assert len(np.unique(flown)) == 60  # a new c2 every block


def test_a_flight_mostly_on_the_fallback_fails_and_says_why(tmp_path):
    # The fixed controller commands every 50 ms of sim time (its timer runs on the flight's
    # clock, so no command can come sooner) and each command is stale 10 ms later. In blocks
    # of 20 ms at most one block in two and a half can start on a fresh command, however
    # fast or slow the processes are. (Blocks of 50 ms each start on the command just sent
    # when the controller keeps up, which made the outcome depend on the machine's speed.)
    # In lockstep the flight flies to the controller's first tick before it waits for the
    # first command (it used to wait at 20 ms, for a command due at 50 ms, and fail).
    scenario = tmp_path / "short_blocks.yaml"
    scenario.write_text("name: short_blocks\nduration: 3.0\nblock_size: 20\n"
                        "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                        "excitation: {force_std: 1000.0, seed: 5}\n")
    result = _fly(tmp_path, "stale", "--scenario", str(scenario), "--controller", "fixed",
                  "--damping", "900", "--damper-timeout", "0.01")
    assert result.returncode == 1, result.stdout + result.stderr
    summary = json.loads(result.stdout)  # the summary is still printed, with the counts
    assert summary["exit_code"] == 1
    assert summary["blocks"] == 150 and summary["blocks_startup"] == 3
    assert 0 < summary["blocks_controlled"] <= summary["commands_accepted"]
    assert summary["blocks_fallback"] > 0.02 * summary["blocks"]
    assert "were flown on the fallback c2" in result.stderr.splitlines()[-1]
