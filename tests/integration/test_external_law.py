"""A control law from outside the project flies through run_flight and dva evaluate.

The package under tests/data/external_law (c2 proportional to the airspeed) is installed with
pip into a directory of its own, on no project file; with that directory on PYTHONPATH it joins
the controller table through the entry-point group ``aero_dva.controllers``, the generic
controller node hosts it by name, and the in-process evaluation flies it.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from aero_dva.bag.flight_log_io import load_flight_log

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros

LAW = Path(__file__).resolve().parents[1] / "data" / "external_law"
GAIN = 6.0  # [N s^2/m^2] the law's default: c2 = 6 U


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    """The environment of a shell in which the law is installed (a pip --target directory)."""
    root = tmp_path_factory.mktemp("external_law")
    source = shutil.copytree(LAW, root / "source")  # the build writes beside its sources
    target = root / "site"
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                           "--no-build-isolation", "--no-index", "--target", str(target),
                           str(source)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    path = os.pathsep.join(p for p in (str(target), os.environ.get("PYTHONPATH")) if p)
    return dict(os.environ, PYTHONPATH=path)


def test_the_installed_law_joins_the_table(installed):
    code = ("import json; from aero_dva.control import controllers as c; "
            "e = c.controller('proportional'); "
            "print(json.dumps([c.names(), e.origin, e.runs, list(c.load_problems())]))")
    done = subprocess.run([sys.executable, "-c", code], env=installed, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    names, origin, runs, problems = json.loads(done.stdout)
    assert names[-1] == "proportional" and "fixed" in names
    assert (origin, runs, problems) == ("dva-law-example", "block", [])
    # without the package, the project's table alone
    alone = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           timeout=120)
    assert alone.returncode != 0 and "unknown controller 'proportional'" in alone.stderr


def test_run_flight_flies_it_in_the_generic_controller_node(installed, tmp_path):
    scenario = tmp_path / "short.yaml"
    scenario.write_text("name: short\nduration: 4.0\nblock_size: 50\n"
                        "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                        "excitation: {force_std: 1000.0, seed: 2}\n")
    bag = tmp_path / "flight"
    result = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--scenario", str(scenario),
         "--controller", "proportional", "--output", str(bag), "--json"],
        env=installed, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(result.stdout)
    assert summary["controller"] == "proportional" and summary["control_problem"] is None
    assert summary["exit_codes"]["proportional_controller"] == 0
    # one command per flight condition but the last, as for the airspeed schedule
    assert summary["commands_received"] == summary["commands_expected"] == \
        summary["blocks"] - 1 == 79
    log = load_flight_log(bag)
    # from the second block on, c2 is the law's of the block before (the graph's lag)
    u, c2 = log.airspeed, log.applied_damping
    assert c2[-1] == pytest.approx(GAIN * u[-100], rel=1e-9)
    assert c2[2000] == pytest.approx(GAIN * u[1950], rel=1e-9)


def test_dva_evaluate_flies_it_in_process(installed, tmp_path):
    out = tmp_path / "ev"
    result = subprocess.run(
        [sys.executable, "-m", "dva_offline.cli", "evaluate", "--controllers",
         "fixed,proportional", "--cases", "rho0", "--seeds", "2", "--fixed-c2", "625",
         "--out", str(out), "--json"],
        env=installed, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    payload = json.loads(result.stdout)
    assert payload["controllers"] == ["fixed", "proportional"]
    rows = {r["controller"]: r for r in payload["results"]}
    law = rows["proportional"]
    assert law["flights"] == 2 and law["divergence_difference"]["n"] == 2
    # c2 = 6 U over the RMS range 0.8 .. 1.05 U_cr (U_cr = 100 m/s): 480 .. 630 N s/m
    assert 480.0 < law["mean_c2"] < 630.0
    # its eigenvalue boundary, from its law as a function of the flight condition
    assert payload["boundaries"]["rho0"]["proportional"]["frozen"] > 1.0
    assert "c2 proportional to U" in (out / "results.md").read_text()
