"""Flights, scenarios and training plans are held to stated limits on duration x sample rate
and on the memory a flight takes; past them they are refused at the door in one line (exit 2),
and the --help texts state the same numbers as the code."""
from __future__ import annotations

import subprocess
import sys

import pytest

from aero_dva.flight import flight_limits as fl
from aero_dva.flight.scenario_io import load_scenario
from dva_offline import cli
from dva_offline.evaluation.flights import (
    BATCH_MEMORY,
    BATCH_SEEDS,
    FLIGHT_BYTES_PER_SAMPLE,
    batch_seeds,
    flight_memory_problem,
    seed_batches,
)


def scenario(tmp_path, duration="30.0", rate="1000.0", block="50", force="1000.0"):
    path = tmp_path / "s.yaml"
    path.write_text(f"name: s\nduration: {duration}\nsample_rate: {rate}\nblock_size: {block}\n"
                    "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 1.2}\n"
                    f"excitation: {{force_std: {force}, seed: 1}}\n")
    return path


@pytest.mark.parametrize("change, message", [
    ({"duration": "36000.0"}, "more than the 20,000,000 a flight may have"),
    ({"rate": "1.0e+9"}, "sample_rate must be in [100, 20000] Hz"),
    ({"rate": "1.0"}, "sample_rate must be in [100, 20000] Hz"),
    ({"duration": "1.0e-4"}, "shorter than one block"),
    ({"force": "0.0"}, "force_std must be in [1e-06, 1e+06] N"),
    ({"block": "0"}, "block_size must be an integer in [1, 20000]"),
])
def test_scenarios_past_the_limits_are_refused_in_one_line(tmp_path, change, message):
    with pytest.raises(ValueError) as err:
        load_scenario(scenario(tmp_path, **change))
    assert message in str(err.value) and "\n" not in str(err.value)


def test_evaluation_batches_keep_within_their_memory():
    assert batch_seeds(30_000) == BATCH_SEEDS  # the study's ramp: unchanged
    limit = BATCH_MEMORY // FLIGHT_BYTES_PER_SAMPLE
    assert flight_memory_problem(limit) is None
    assert "more than the 1,024 MiB" in flight_memory_problem(limit + 1)
    for samples in (30_000, 300_000, 3_000_000, limit):
        largest = max(len(b) for b in seed_batches(range(100), 1, 1, samples))
        assert largest * samples * FLIGHT_BYTES_PER_SAMPLE <= BATCH_MEMORY or largest == 1


def test_a_ten_hour_evaluation_is_refused_before_anything_is_made(tmp_path, capsys):
    path = scenario(tmp_path, duration="19000.0")  # within the flight limit, past evaluate's
    out = tmp_path / "eval"
    assert cli.main(["evaluate", "--controllers", "fixed", "--cases", "rho0", "--fixed-c2",
                     "624.7", "--scenario", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "would hold about 2,899 MiB of traces" in err[-1], err
    assert not out.exists()


@pytest.mark.parametrize("argv, message", [
    (["--window", "1e5"], "more than the 600,000 a window may have"),
    (["--window", "1e-300"], "window * sample_rate must be a whole number >= 2"),
])
def test_training_plans_past_the_limits_are_refused(tmp_path, capsys, argv, message):
    out = tmp_path / "plan.json"
    assert cli.main(["train", "plan", "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1], err
    assert not out.exists()


def test_help_texts_state_the_limits_of_the_code():
    helps = {tuple(cmd): subprocess.run([sys.executable, "-m", "dva_offline.cli", *cmd, "--help"],
                                        capture_output=True, text=True, timeout=300).stdout
             for cmd in ([], ["evaluate"], ["train", "sweep"], ["train", "plan"])}
    flat = {k: " ".join(v.split()) for k, v in helps.items()}
    assert f"{fl.MAX_FLIGHT_SAMPLES:,} samples" in flat[()]
    assert f"{BATCH_MEMORY // FLIGHT_BYTES_PER_SAMPLE:,} samples" in flat[("evaluate",)]
    assert f"{fl.MAX_FLIGHT_SAMPLES:,} samples" in flat[("train", "sweep")]
    assert f"{fl.MAX_WINDOW_SAMPLES:,} samples" in flat[("train", "plan")]
