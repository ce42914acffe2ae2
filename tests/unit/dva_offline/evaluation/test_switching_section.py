"""`dva evaluate --controllers fixed,switching`: the law's paired section, and its cases."""
from __future__ import annotations

import json

import pytest

from dva_offline import cli


@pytest.mark.slow
def test_evaluate_with_the_switching_law_on_three_seeds(tmp_path, capsys):
    out = tmp_path / "ev"
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "3", "--cases", "rho0",
                     "--fixed-c2", "625", "--no-boundaries", "--json"]
                    + ["--controllers", "fixed,switching"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["controllers"] == ["fixed", "switching"]
    section = payload["switching"]
    assert section["seeds"] == [101, 102, 103]  # apart from the design's seeds 0..3
    (row,) = section["rows"]
    assert row["setting"]["case"] == "rho0" and row["seeds"] == 3
    practical = row["practical"]
    # each seed's boundary is a ramp airspeed; the law's lies beyond the fixed damper's
    assert 1.1 < practical["fixed"] < practical["switching"] < 1.4
    assert practical["difference"]["n"] == 3
    assert row["rms_at_1.1"]["change"]["mean"] < 0
    assert row["switches_per_second"]["mean"] > 10
    assert json.loads((out / "results.json").read_text())["switching"] == section


def test_switching_refuses_the_varying_density_cases(tmp_path, capsys):
    assert cli.main(["evaluate", "--out", str(tmp_path / "ev"), "--seeds", "2", "--cases",
                     "rho0,1Hz", "--controllers", "fixed,switching"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "1Hz" in err[0] and "constant-density" in err[0]


def test_a_bad_gains_file_ends_the_run_before_any_flight(tmp_path, capsys):
    gains = tmp_path / "gains.json"
    gains.write_text('{"format": "something else"}')
    out = tmp_path / "ev"
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "2", "--cases", "rho0",
                     "--controllers", "fixed,switching", "--gains", str(gains)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(gains) in err[0]
    assert not out.exists()  # nothing flown, nothing left behind


def test_another_per_sample_law_is_refused_not_flown_as_the_switching_law(tmp_path, capsys):
    out = tmp_path / "ev"
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "1", "--cases", "rho0",
                     "--controllers", "fixed,clipped_optimal"]) == 2
    err = capsys.readouterr().err
    assert "clipped_optimal: in process, a per-sample law is flown by a section" in err
    assert not out.exists()
