"""Generated bad files (hypothesis, fixed seed) through every loader of the tools: each one is
loaded or refused in one line naming the file (what ``dva`` reports with exit 2), nothing
else, and nothing is left beside it. A few of the issue's classes also run as whole ``dva``
processes. The longer run (>= 1,000 examples per loader) is bench/bench_input_fuzz.py.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from bench.faults import bad_inputs, input_fuzz

LOADERS = sorted(input_fuzz.loaders())
FUZZ = settings(max_examples=30, derandomize=True, deadline=None, database=None,
                suppress_health_check=list(HealthCheck))


@pytest.mark.parametrize("name", LOADERS)
def test_every_generated_file_is_loaded_or_refused_in_one_line(name, tmp_path):
    loader = input_fuzz.loaders()[name]

    @FUZZ
    @given(content=input_fuzz.inputs(loader))
    def check(content):
        outcome = input_fuzz.try_loader(loader, content, tmp_path)
        assert outcome in (None, "refused"), outcome

    check()


def test_the_valid_files_load(tmp_path):
    # the generated files start from these; a loader refusing them would test nothing
    for name in LOADERS:
        loader = input_fuzz.loaders()[name]
        if loader.name == "bag metadata":
            continue  # its MCAP file is absent on purpose
        assert input_fuzz.try_loader(loader, input_fuzz.valid_bytes(loader), tmp_path) is None


def _dva(*argv, cwd):
    env = {k: v for k, v in os.environ.items() if k != "DVA_DEBUG"}
    return subprocess.run([sys.executable, "-m", "dva_offline.cli", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def _one_error_line(result, path) -> str:
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith("dva ") and ": error: " in lines[-1], lines
    assert path.name in lines[-1]
    return lines[-1]


def test_deep_yaml_wing_is_refused_by_dva(tmp_path):
    wing = tmp_path / "deep.yaml"
    wing.write_text("wing: " + "[" * 3000 + "1" + "]" * 3000 + "\n", encoding="utf-8")
    line = _one_error_line(_dva("wing", "flutter", "--wing", str(wing), cwd=tmp_path), wing)
    assert "nested more than 32 levels" in line


def test_huge_integer_in_a_schedule_is_refused_by_dva(tmp_path):
    schedule = tmp_path / "schedule.json"
    data = bad_inputs._schedule_dict()
    data["a0"] = 10**400
    schedule.write_text(json.dumps(data), encoding="utf-8")
    out = tmp_path / "eval"
    result = _dva("evaluate", "--controllers", "schedule", "--schedule", str(schedule),
                  "--out", str(out), "--graph", "--seeds", "1", "--mu", "0", "--reports",
                  "none", cwd=tmp_path)
    assert "out of range" in _one_error_line(result, schedule)
    assert not out.exists()


def test_network_declaring_terabytes_is_refused_by_dva(tmp_path):
    valid = tmp_path / "valid.npz"
    bad_inputs._write_network(valid)
    network = tmp_path / "huge.npz"
    with zipfile.ZipFile(valid) as src, zipfile.ZipFile(network, "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "centres.npy":
                data = bad_inputs.npy_member((600_000, 600_000), "<f8", b"\0" * 64)
            dst.writestr(info.filename, data)
    out = tmp_path / "eval"
    result = _dva("evaluate", "--controllers", "rbf", "--network", str(network), "--out",
                  str(out), "--graph", "--seeds", "1", "--mu", "0", "--reports", "none",
                  cwd=tmp_path)
    assert "declares shape (600000, 600000)" in _one_error_line(result, network)
    assert not out.exists()


def test_a_library_failure_is_internal_a_project_refusal_is_input(tmp_path):
    from scipy.optimize import least_squares

    from aero_dva.wing.wing_io import load_wing
    from dva_offline.cli_failures import is_input_error

    # the message of the discrepancy runs, raised inside scipy: not the input's fault
    with pytest.raises(ValueError, match="outside of provided bounds") as scipy_error:
        least_squares(lambda x: x, x0=[5.0], bounds=([0.0], [1.0]))
    assert not is_input_error(scipy_error.value)
    wing = tmp_path / "wing.yaml"
    wing.write_text("wing: {mass: 1.0}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="missing key") as refusal:
        load_wing(wing)
    assert is_input_error(refusal.value)
    with pytest.raises(RecursionError) as deep:
        json.loads("[" * 100_000 + "]" * 100_000)
    assert not is_input_error(deep.value)


def test_dva_says_internal_error_with_its_own_exit_code(tmp_path, monkeypatch, capsys):
    # a fault inside a library on a valid input is not blamed on the input (exit 3, not 2)
    from dva_offline import cli

    def broken(path=None):
        return np.linalg.inv(np.ones((2, 3)))  # numpy's LinAlgError, a ValueError

    monkeypatch.setattr("aero_dva.wing.wing_io.load_wing", broken)
    monkeypatch.delenv("DVA_DEBUG", raising=False)
    assert cli.main(["wing", "flutter"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dva wing: internal error (LinAlgError")
    assert "DVA_DEBUG=1" in err[0]
