"""``dva control optimal-c2`` and ``dva control schedule`` (Zhang (2006) section 7.1)."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.schedule_io import load_schedule
from dva_offline import cli

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SMALL = ["--airspeeds", "0.8:1.3:101", "--relative", "--c2-range", "0:2500:51"]


def dva_executable() -> str:
    """The ``dva`` console script installed next to this Python (or on PATH)."""
    beside = Path(sys.executable).with_name("dva")
    found = str(beside) if beside.is_file() else shutil.which("dva")
    if not found:
        pytest.fail("the 'dva' console script is not installed (pip install -e offline)")
    return found


def run_json(capsys, argv) -> dict:
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1  # one JSON object on one line
    return json.loads(out)


def test_optimal_c2_through_the_entry_point(tmp_path):
    plot = tmp_path / "optimal.png"
    result = subprocess.run(
        [dva_executable(), "control", "optimal-c2", "--json", "--airspeeds", "0.8:1.3:51",
         "--relative", "--c2-range", "0:2500:26", "--plot", str(plot)],
        capture_output=True, text=True, timeout=180)
    assert result.returncode == 0, result.stderr
    payload = json.loads(result.stdout)
    for key in ("wing", "density", "objective", "method", "force_std", "sample_rate",
                "critical_airspeed", "c2_grid", "n_airspeeds", "stable_limit", "rms_unit",
                "elapsed_s", "airspeed", "airspeed_ratio", "optimal_c2", "min_rms",
                "at_bound", "plot"):
        assert key in payload, key
    assert payload["objective"] == "leading_edge" and payload["rms_unit"] == "m"
    assert payload["c2_grid"] == {"min": 0.0, "max": 2500.0, "n": 26}
    assert len(payload["optimal_c2"]) == len(payload["min_rms"]) == 51
    ratio = np.array(payload["airspeed_ratio"])
    assert ratio[0] == pytest.approx(0.8) and ratio[-1] == pytest.approx(1.3)
    limit = payload["stable_limit"]["ratio"]
    assert 1.0 < limit < 1.3
    above = ratio > limit
    assert all(v is None for v in np.array(payload["optimal_c2"], dtype=object)[above])
    assert all(v is not None for v in np.array(payload["min_rms"], dtype=object)[~above])
    assert plot.read_bytes()[:8] == PNG_MAGIC


def test_optimal_c2_objectives_surface_and_simulation_check(capsys):
    rot = run_json(capsys, ["control", "optimal-c2", "--json", "--objective", "rotation",
                            "--surface", "--check-simulation", "2", "--sim-duration", "10",
                            "--flights", "2", *SMALL])
    assert rot["objective"] == "rotation" and rot["rms_unit"] == "rad"
    surface = rot["surface"]
    assert surface["outputs"] == ["plunge", "pitch", "leading_edge"]
    assert np.array(surface["rms"], dtype=float).shape == (3, 101, 51)
    check = rot["simulation_check"]
    assert len(check["points"]) == 2
    for point in check["points"]:
        assert abs(point["z"]) < 4.0
        assert point["relative_standard_error"] < 0.2  # 2 x 10 s only
    plunge = run_json(capsys, ["control", "optimal-c2", "--json", "--objective", "plunge",
                               *SMALL])
    a = np.array(plunge["optimal_c2"][:10], dtype=float)
    b = np.array(rot["optimal_c2"][:10], dtype=float)
    assert np.all(np.abs(a - b) > 1.0)  # different objectives, different optima


def test_text_output(capsys):
    assert cli.main(["control", "optimal-c2", *SMALL]) == 0
    out = capsys.readouterr().out
    assert "U_cr" in out and "unstable" in out and "c2 [N s/m]" in out


def test_schedule_round_trip_through_the_file(tmp_path, capsys):
    out = tmp_path / "schedule.json"
    plot = tmp_path / "schedule.png"
    payload = run_json(capsys, ["control", "schedule", "--json", "--out", str(out),
                                "--plot", str(plot), *SMALL])
    for key in ("schedule_file", "a0", "a1", "fit_range", "damping_range", "n_points",
                "rmse", "max_abs_error", "r_squared", "description", "critical_airspeed",
                "stable_limit", "plot"):
        assert key in payload, key
    schedule = load_schedule(out)  # what the airspeed_controller node reads
    assert isinstance(schedule, AirspeedSchedule)
    assert schedule.a0 == payload["a0"] and schedule.a1 == payload["a1"]
    assert list(schedule.airspeed_range) == payload["fit_range"]["airspeed"]
    assert list(schedule.damping_range) == [0.0, 2500.0]
    # default fit range: the top 0.05 U_cr of the stable range
    low, high = payload["fit_range"]["ratio"]
    assert high == pytest.approx(payload["stable_limit"]["ratio"])
    assert high - low == pytest.approx(0.05)
    assert payload["n_points"] == 11  # 0.005 U_cr steps: 0.05 U_cr holds 11 airspeeds
    assert 0.0 <= payload["rmse"] <= payload["max_abs_error"]
    assert 0.0 < payload["r_squared"] <= 1.0
    assert "eq. 7.1" in json.loads(out.read_text())["equation"]
    assert plot.read_bytes()[:8] == PNG_MAGIC
    # the schedule reproduces the optimal c2 it was fitted to, to its residual
    opt = run_json(capsys, ["control", "optimal-c2", "--json", *SMALL])
    speeds = np.array(opt["airspeed"])
    inside = (speeds >= schedule.airspeed_range[0] - 1e-6) & (
        speeds <= schedule.airspeed_range[1] + 1e-6)
    c_opt = np.array(opt["optimal_c2"], dtype=float)[inside]
    resid = schedule.evaluate(speeds[inside]) - c_opt
    assert np.sqrt(np.mean(resid**2)) == pytest.approx(payload["rmse"], rel=1e-6)


def test_schedule_explicit_fit_range_in_m_per_s_and_ratio(tmp_path, capsys):
    out = tmp_path / "s.json"
    p1 = run_json(capsys, ["control", "schedule", "--json", "--out", str(out),
                           "--fit-range", "0.9:1.0", *SMALL])
    u_cr = p1["critical_airspeed"]
    assert p1["fit_range"]["ratio"] == pytest.approx([0.9, 1.0])
    assert p1["fit_range"]["source"] == "--fit-range"
    p2 = run_json(capsys, ["control", "schedule", "--json", "--out", str(out),
                           "--airspeeds", f"{0.8 * u_cr}:{1.3 * u_cr}:101",
                           "--c2-range", "0:2500:51",
                           "--fit-range", f"{0.9 * u_cr}:{1.0 * u_cr}",
                           "--damping-range", "100:2000"])
    assert p2["a0"] == pytest.approx(p1["a0"], rel=1e-6)
    assert p2["a1"] == pytest.approx(p1["a1"], rel=1e-6)
    assert load_schedule(out).damping_range == (100.0, 2000.0)


@pytest.mark.parametrize("argv, message", [
    (["optimal-c2", "--airspeeds", "80:120"], "--airspeeds expects START:STOP:N"),
    (["optimal-c2", "--airspeeds", "1.2:0.8:5", "--relative"], "START < STOP"),
    (["optimal-c2", "--c2-range=-5:100:10"], "--c2-range"),
    (["optimal-c2", "--density", "-1"], "--density"),
    (["optimal-c2", "--curves", "a,b"], "--curves"),
    (["schedule", "--out", "{tmp}/x.json", "--fit-range", "1.5:1.6", "--relative",
      *SMALL], "fit range"),
    (["schedule", "--out", "{tmp}/x.json", "--fit-range", "2:1"], "--fit-range"),
])
def test_bad_arguments_give_one_line_errors(tmp_path, capsys, argv, message):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert cli.main(["control", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1]
    assert err[-1].startswith("dva control: error:")


def test_wing_without_maxwell_absorber_is_refused(tmp_path, capsys):
    from aero_dva.wing.wing_io import load_wing, save_wing

    cfg = load_wing()
    path = tmp_path / "bare.yaml"
    save_wing(path, type(cfg)(cfg.wing, cfg.air_density, cfg.aero, None))
    assert cli.main(["control", "optimal-c2", "--wing", str(path)]) == 2
    assert "Maxwell absorber" in capsys.readouterr().err
