"""A switching-law flight through the ROS graph (c2 set every sample, no segment of constant
c2) goes through ``dva discrepancy flight`` on the whole-flight route: a damper lag the model
does not declare is named ``actuator_lag`` with its time constant, and an ideal damper is
consistent with the wing file's model."""
from __future__ import annotations

import json
import subprocess

import pytest

from dva_offline.cli import main

from .conftest import TIMEOUT_SCALE, ros2_run_path

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def fly_switching(bag, damper_lag: float) -> None:
    """The default 30 s ramp (0.8 -> 1.2 U_cr) flown by the switching law, the damper
    following its commands through a first-order lag ``damper_lag`` [s]."""
    result = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--controller", "switching",
         "--damper-time-constant", str(damper_lag), "--output", str(bag), "--json"],
        capture_output=True, text=True, timeout=300 * TIMEOUT_SCALE)
    assert result.returncode == 0, result.stdout + result.stderr


def analyse(bag, capsys) -> dict:
    capsys.readouterr()
    assert main(["discrepancy", "flight", str(bag), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["route"]["name"] == "whole-flight"
    assert out["damper"]["per_sample_laws"] == ["switching"]
    assert out["damper"]["declared_lag_s"] == 0.0
    return out


def test_a_30_ms_damper_lag_is_named_with_its_time_constant(tmp_path, capsys):
    bag = tmp_path / "lag30"
    fly_switching(bag, 0.03)
    out = analyse(bag, capsys)
    assert out["verdict"]["status"] == "explained", out["verdict"]
    assert out["verdict"]["effect"] == "actuator_lag"
    (tau,) = out["augmented"]["parameters"]
    assert tau["name"] == "time_constant"
    assert abs(tau["value"] - 0.03) < 0.2 * 0.03, tau
    assert out["augmented"]["error"] < 0.5 * out["baseline"]["error"]


def test_an_ideal_damper_is_consistent_with_the_wing_files_model(tmp_path, capsys):
    bag = tmp_path / "lag0"
    fly_switching(bag, 0.0)
    out = analyse(bag, capsys)
    assert out["verdict"]["status"] == "consistent", out["verdict"]
    assert out["verdict"].get("effect") in (None, "")
