"""Invariants under faults, with nodes run as processes (the trials of bench/bench_faults.py,
few of them here; the bench runs 20 per fault and docs/reliability.md has its figures):

- the recorder stopped by SIGINT or SIGTERM at a random moment loses no block the simulator
  published before the signal, and its bag is closed;
- after SIGKILL, recovery gives back every block inside the chunks complete in the file;
- a controller killed mid-flight leaves its last c2 applied until the damper's stale fallback;
- a 10 kHz burst of valid and invalid commands never gets a NaN, infinite or out-of-range c2
  applied, and is reported on /diagnostics a few times, not once per command;
- run_flight fails at once when a node of the graph exits before the flight ends.
"""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva_sim.run_flight import main as run_flight_main
from bench.faults.command_faults import DAMPER_RANGE, run_burst_session
from bench.faults.controller_faults import run_controller_trial
from bench.faults.recorder_faults import run_recorder_trial

pytestmark = pytest.mark.ros

RNG = np.random.default_rng(16)


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_recorder_signal_loses_nothing(tmp_path, signal_name):
    for i in range(2):
        work = tmp_path / str(i)
        work.mkdir()
        trial = run_recorder_trial(signal_name, float(RNG.uniform(0.3, 1.5)), work)
        assert trial.exit_code == 0 and trial.closed, trial
        assert trial.published_before > 0, trial
        assert trial.lost == 0 and trial.gaps == 0, trial


def test_recorder_sigkill_recovery_keeps_complete_chunks(tmp_path):
    for i in range(2):
        work = tmp_path / str(i)
        work.mkdir()
        trial = run_recorder_trial("SIGKILL", float(RNG.uniform(0.8, 1.5)), work,
                                   flush_period=0.2)
        assert trial.exit_code == -9 and not trial.closed, trial
        assert trial.in_complete_chunks > 0, trial  # flushed several times before the kill
        assert trial.missing_from_complete_chunks == 0, trial
        # (Not compared with the blocks the probe had seen at the kill: the probe, in this
        # process, can lag the recorder by several blocks on a busy machine.)
        assert trial.gaps == 0 and trial.recorded > 0, trial


def test_killed_controller_leaves_its_c2_until_the_fallback(tmp_path):
    trial = run_controller_trial("free", float(RNG.uniform(0.1, 0.8)), tmp_path,
                                 damping=1500.0, damper_timeout=0.5)
    # In sim time, while the dead controller's last command was in force, the damper applied its
    # c2 (stamps, not arrival times: a loaded probe may see the fallback state first).
    assert trial.held_states >= 1, trial
    assert trial.held_min == trial.held_max == 1500.0, trial
    assert trial.fallback == 500.0, trial  # the reference wing's design c2
    # the fallback acts in the first 50 ms block after 0.5 s without a command
    assert 0.5 <= trial.command_age <= 0.5 + 0.05 + 1e-9, trial
    assert "fallback c2 = 500 N s/m" in trial.diagnostic, trial


def test_command_burst_never_applies_an_invalid_c2(tmp_path):
    session = run_burst_session("mixed", 2, tmp_path, burst_seconds=0.2)
    assert session.summary_seen and session.rejected > 100, session
    for burst in session.trials:
        assert burst.applied_valid, burst
        assert DAMPER_RANGE[0] <= burst.applied_min <= burst.applied_max <= DAMPER_RANGE[1]
        assert burst.diagnostics <= 4, burst  # one report per reason, not one per command


def test_run_flight_fails_at_once_when_the_controller_cannot_start(tmp_path, capsys):
    # Before: the controller exited 2 on its file, the simulator waited 30 s for it, flew on
    # the damper's fallback, and run_flight printed a summary under the controller's name.
    bad = tmp_path / "schedule.json"
    bad.write_text('{"format": "something else"}')
    code = run_flight_main(["--controller", "schedule", "--schedule", str(bad), "--output",
                            str(tmp_path / "bag"), "--real-time-factor", "0"])
    assert code == 2  # the controller refused its input: the run's input is bad
    # The cause is the controller's exit (not a wait for it that ran out), and no summary.
    out, err = capsys.readouterr()
    assert "airspeed_controller exited with 2 before the flight ended" in err, err
    assert "format is 'something else'" in err and "divergence" not in out, (out, err)
