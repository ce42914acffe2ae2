"""``dva switching``: bad inputs give one line and exit code 2."""
from __future__ import annotations

import json

import pytest

from dva_offline import cli


@pytest.mark.parametrize("argv, message", [
    (["switching", "design", "--out", "x.json", "--c-lo", "3000"], "--c-lo"),
    (["switching", "design", "--out", "x.json", "--lag", "-1"], "--lag"),
    (["switching", "design", "--out", "x.json", "--efforts", "a,b"], "--efforts"),
    (["switching", "evaluate", "--gains", "missing.json"], "missing.json"),
    (["switching", "mechanism", "--gains", "missing.json"], "missing.json"),
    (["switching", "mechanism", "--gains", "g.json", "--effort", "0"], "--effort"),
])
def test_bad_input_one_line_exit_2(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err


def test_evaluate_refuses_gains_of_another_wing(tmp_path, capsys):
    from aero_dva.data_files import data_file

    data = json.loads(data_file("switching_gains.json").read_text())
    data["wing_fingerprint"] = "0000"
    path = tmp_path / "other.json"
    path.write_text(json.dumps(data))
    assert cli.main(["switching", "evaluate", "--gains", str(path)]) == 2
    assert "another wing" in capsys.readouterr().err


def test_mechanism_holds_the_laws_against_the_ideal_force(capsys):
    """Two seeds: the ideal actuator's loop is more stable and quieter than the constant c2's,
    its force must inject power part of the time, and both shipped laws land in between."""
    from aero_dva.data_files import data_file

    laws = [str(data_file(n)) for n in ("switching_gains.json", "clipped_optimal_gains.json")]
    argv = ["switching", "mechanism", "--seeds", "2", "--json"]
    for path in laws:
        argv += ["--gains", path]
    assert cli.main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    ideal, fixed = out["ideal"], out["fixed"]
    assert ideal["least_stable_real_part"] < fixed["least_stable_real_part"] < 0
    assert ideal["leading_edge_rms_m"] < 0.7 * fixed["leading_edge_rms_m"]
    assert 0.5 < ideal["absorbing_share"] < 1.0
    flown = out["flown"]
    for path in laws:
        assert ideal["leading_edge_rms_m"] < flown[path]["leading_edge_rms_m"] \
            < flown["fixed"]["leading_edge_rms_m"]
        assert 0.0 < flown[path]["share_of_ideal_gain"] < 1.0
