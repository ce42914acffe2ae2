"""``dva evaluate --graph`` on a tiny subset, through the real node graph (run_flight each)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

# A short, fast ramp: 0.8 -> 1.3 U_cr in 15 s (the study's is 0.8 -> 1.2 in 30 s), so the wing
# without DVA (U_cr) and with the best fixed c2 (1.15 U_cr) both diverge within it. (In 10 s the
# chapter-6 bare wing, growing at 3.4 1/s at 1.05 U_cr, reaches the simulator's stop inside the
# last, partial 1 s window of the divergence test, which then sees no divergence.)
SCENARIO = """\
name: short_ramp
duration: 15.0
sample_rate: 1000.0
block_size: 50
airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 1.3}
density: {base: 1.2, variation: 0.0, frequency: 1.0}
excitation: {force_std: 1000.0, seed: 1}
"""


def _dva(*args):
    return subprocess.run([sys.executable, "-m", "dva_offline.cli", *args], capture_output=True,
                          text=True, timeout=600)


def test_evaluate_flies_the_subset_and_tabulates_it(tmp_path):
    scenario = tmp_path / "short_ramp.yaml"
    scenario.write_text(SCENARIO)
    out = tmp_path / "ev"
    argv = ["evaluate", "--graph", "--out", str(out), "--scenario", str(scenario), "--seeds", "1",
            "--mu", "0,0.1", "--controllers", "none,fixed", "--no-rrd", "--json"]
    # two run_flight at a time, each on a ROS domain of its own: no flight sees another's topics
    result = _dva(*argv, "--workers", "2")
    assert result.returncode == 0, result.stderr[-2000:]
    assert "flights" in result.stderr  # progress on stderr
    payload = json.loads(result.stdout)
    assert payload["flights"] == 4 and payload["flown_now"] == 4 and payload["failed"] == 0
    cases = {(c["controller"], c["mu"]): c for c in payload["cases"]}
    assert set(cases) == {("none", 0.0), ("none", 0.1), ("fixed", 0.0), ("fixed", 0.1)}
    fixed_c2 = payload["inputs"]["fixed_c2"]["damping"]
    assert 300 < fixed_c2 < 700
    for mu in (0.0, 0.1):
        bare, fixed = cases[("none", mu)], cases[("fixed", mu)]
        assert bare["n_diverged"] == fixed["n_diverged"] == 1
        assert 0.95 < bare["mean"] < 1.12  # flutter at U_cr, detected a little later
        assert fixed["mean"] > bare["mean"] + 0.05  # the DVA delays flutter
        assert fixed["mean_damping"] == pytest.approx(fixed_c2, rel=0.01)
    # the table lists what the per-flight records say
    table = (out / "results.md").read_text()
    record = json.loads((out / "flights" / "fixed_mu0.1_seed1.json").read_text())
    assert record["ok"] and record["controller"] == "fixed" and record["mu"] == 0.1
    assert f"| best fixed c2 | 0.1 | 1 | 1 | {record['divergence_ratio']:.3f} |" in table
    # plots and one report per case (report/test_contents.py checks the .rrd)
    assert (out / "divergence_vs_mu.png").is_file() and (out / "traces_mu0.1.png").is_file()
    assert len(payload["reports"]) == 4
    report = (out / "reports" / "fixed_mu0" / "run.md").read_text()
    assert "controller: **fixed**" in report and "excitation seed 1" in report
    # run again: every flight is on record, nothing is flown twice
    again = _dva(*argv[:-1], "--reports", "none", "--json")  # serial
    assert again.returncode == 0, again.stderr[-2000:]
    assert json.loads(again.stdout)["flown_now"] == 0
    assert "resuming" in again.stderr
