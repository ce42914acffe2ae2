"""A per-sample law records what acted: its flight's bag holds the c2 and the damper force of
every sample it flew (dva/damper_block), and ``dva replay --offline`` flies the wing again with
them to the recorded accelerations (within 1e-9 of their peak)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from aero_dva.bag import channels as ch
from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import bag_topics

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros

# 1.0 -> 1.15 U_cr in 6 s: above the best constant c2's flutter airspeed by the end.
SCENARIO = ("name: ramp\nduration: 6.0\nblock_size: 50\n"
            "airspeed: {kind: ramp, start_ratio: 1.0, end_ratio: 1.15}\n"
            "excitation: {force_std: 1000.0, seed: 3}\n")


@pytest.mark.parametrize("law", ["switching", "clipped_optimal"])
def test_a_per_sample_flight_replays_to_its_recorded_accelerations(law, tmp_path):
    scenario = tmp_path / "ramp.yaml"
    scenario.write_text(SCENARIO)
    bag = tmp_path / "flight"
    flown = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--controller", law, "--scenario",
         str(scenario), "--output", str(bag), "--json"],
        capture_output=True, text=True, timeout=300)
    assert flown.returncode == 0, flown.stdout + flown.stderr
    summary = json.loads(flown.stdout)
    assert summary["data_missing"] == 0 and summary["blocks_switching"] > 100
    # one damper block beside each block the law flew
    counts = {t: info.message_count for t, info in bag_topics(bag).items()}
    assert counts[ch.DAMPER_BLOCK.absolute()] == summary["blocks_switching"]
    log = load_flight_log(bag)
    law_samples = np.isfinite(log.law_damping)
    assert law_samples.sum() == 50 * summary["blocks_switching"]
    assert np.all(np.isfinite(log.damper_force[law_samples]))
    assert np.all(log.damping[law_samples] == log.law_damping[law_samples])
    assert np.unique(log.law_damping[law_samples]).size > 10  # c2 moved sample by sample
    # what the law commanded: its two targets, before the damper's lag
    commanded = log.law_command[law_samples]
    assert np.unique(commanded).size == 2
    assert commanded.min() <= log.law_damping[law_samples].min()
    assert commanded.max() >= log.law_damping[law_samples].max()
    decoded = load_flight_log(bag, indexed=False)  # both reading routes give the same
    np.testing.assert_array_equal(decoded.law_damping, log.law_damping)
    np.testing.assert_array_equal(decoded.law_command, log.law_command)
    np.testing.assert_array_equal(decoded.damper_force, log.damper_force)

    def replay(*extra):
        return subprocess.run([sys.executable, "-m", "dva_offline.cli", "replay", str(bag),
                               "--controller", law, "--offline", *extra, "--json"],
                              capture_output=True, text=True, timeout=300)

    again = replay("--scenario", str(scenario), "--out", str(tmp_path / "again"))
    assert again.returncode == 0, again.stderr
    result = json.loads(again.stdout)
    assert result["law_blocks"] == summary["blocks_switching"]
    assert 0 <= result["relative_to_peak"] <= 1e-9 and result["agrees"]
    flown_again = load_flight_log(tmp_path / "again")
    np.testing.assert_allclose(flown_again.accelerations, log.accelerations, rtol=0,
                               atol=1e-9 * np.abs(log.accelerations).max())
    # the package's ramp is another flight: refused, one line, nothing written
    wrong = replay("--out", str(tmp_path / "wrong"))
    assert wrong.returncode == 2 and "airspeeds are not the recorded flight's" in wrong.stderr
    assert len(wrong.stderr.strip().splitlines()) == 1 and not (tmp_path / "wrong").exists()
