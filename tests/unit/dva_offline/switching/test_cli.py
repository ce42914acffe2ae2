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
