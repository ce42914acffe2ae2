"""Every ``dva isolator`` subcommand through the installed ``dva`` console script.

The commands run as separate processes, started together (the machine has few cores and each
process spends most of its time importing numpy/scipy), and the tests check their exit codes,
outputs and files. Bad input must give exit code 2 and exactly one line on stderr, no traceback.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dva_offline.isolator import files as isolator_files
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties

KN = 1e3
SYSTEM_F = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 24 * KN), (80.0, 2000.0))  # Table 4.1 F
BUBBLE = MaxwellModel(1.041, 14.01 * KN, 25.81, (22.27 * KN,), (1588.57,))  # Table 5.4
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SUBCOMMANDS = ("modal", "identify", "estimate", "stepped-sine", "static", "plot")


def dva_executable() -> str:
    """The ``dva`` console script installed next to this Python (or on PATH)."""
    beside = Path(sys.executable).with_name("dva")
    found = str(beside) if beside.is_file() else shutil.which("dva")
    if not found:
        pytest.fail("the 'dva' console script is not installed (pip install -e offline)")
    return found


def _frf_rows(n, bad=None):
    f = np.linspace(1.0, 50.0, n)
    h = frf(SYSTEM_F, 2 * np.pi * f)
    rows = [[repr(float(a)), repr(float(b.real)), repr(float(b.imag))] for a, b in zip(f, h)]
    if bad:
        bad(rows)
    return "frequency_hz,real,imag\n" + "".join(",".join(r) + "\n" for r in rows)


def _set(i, j, value):
    def edit(rows):
        rows[i][j] = value
    return edit


def _prepare(d: Path) -> dict[str, list[str]]:
    """Write the input files into ``d``; return the command lines to run, by name."""
    f = np.linspace(0.5, 50.0, 200)
    isolator_files.write_frf_csv(d / "f.csv", f, frf(SYSTEM_F, 2 * np.pi * f),
                              {"temperature_c": np.full(f.size, 23.0)})
    steps = np.arange(3.0, 80.0 + 0.25, 0.5)
    force = np.full(steps.size, 20.0 + 0j)
    isolator_files.write_stepped_sine_csv(d / "steps.csv", steps, force,
                                       force * frf(BUBBLE, 2 * np.pi * steps, "accelerance"))
    fs = 500.0
    rng = np.random.default_rng(0)
    force_t = rng.standard_normal(4000)
    t = np.arange(force_t.size) / fs
    (d / "ts.csv").write_text("time_s,force_n,acc_1\n" + "".join(
        f"{a!r},{b!r},{2 * b!r}\n" for a, b in zip(t.tolist(), force_t.tolist())))
    x = np.linspace(0, 1e-3, 11)
    (d / "ld.csv").write_text("deflection_m,load_n\n" + "".join(
        f"{a!r},{23151 * a + 0.2!r}\n" for a in x.tolist()))
    bad_files = {
        "missing_columns": "frequency_hz,real\n" + "".join(f"{i},1e-4\n" for i in range(1, 20)),
        "nan": _frf_rows(30, _set(7, 1, "nan")),
        "non_increasing": _frf_rows(30, _set(12, 0, "2.0")),
        "too_few": _frf_rows(6),
    }
    for name, text in bad_files.items():
        (d / f"bad_{name}.csv").write_text(text)
    modal = modal_properties(SYSTEM_F)
    fixed = ["--natural-frequency-rad-s", str(modal.natural_frequency_rad_s),
             "--damping-ratio", str(modal.damping_ratio)]
    identify = ["identify", "--mass", "1", "--static-stiffness", "12000"]
    cmds = {
        "help": ["--help"],
        "modal": ["modal", "--mass", "1", "--k", "12000", "--c", "40", "--maxwell", "12000,80",
                  "--maxwell", "24000,2000", "--json"],
        "identify": [*identify, str(d / "f.csv"), "--elements", "2", *fixed, "--json"],
        "estimate": ["estimate", str(d / "ts.csv"), "--out", str(d / "est.csv"), "--nfft",
                     "500", "--json"],
        "stepped_sine": ["stepped-sine", str(d / "steps.csv"), "--quantity", "accelerance",
                         "--json"],
        "static": ["static", str(d / "ld.csv"), "--json"],
        "plot": ["plot", str(d / "f.csv"), "--plot", str(d / "frf.png"), "--mass", "1", "--k",
                 "12000", "--c", "40", "--maxwell", "12000,80", "--maxwell", "24000,2000"],
        **{f"bad_{name}": [*identify, str(d / f"bad_{name}.csv")] for name in bad_files},
        "bad_static_stiffness_in_kn_per_m": ["identify", str(d / "f.csv"), "--mass", "1",
                                             "--static-stiffness", "12", *fixed],
    }
    return {name: ["isolator", *argv] for name, argv in cmds.items()}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """name -> (returncode, stdout, stderr, work dir) for every command of :func:`_prepare`."""
    d = tmp_path_factory.mktemp("dva_entry")
    exe = dva_executable()
    env = {k: v for k, v in os.environ.items() if k != "DVA_DEBUG"}
    env["MPLBACKEND"] = "Agg"
    procs = {
        name: subprocess.Popen([exe, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, env=env, cwd=d)
        for name, argv in _prepare(d).items()
    }
    out = {}
    for name, proc in procs.items():
        stdout, stderr = proc.communicate(timeout=120)
        out[name] = (proc.returncode, stdout, stderr, d)
    return out


def _ok(runs, name):
    code, stdout, stderr, d = runs[name]
    assert code == 0, f"{name}: exit {code}\n{stderr}"
    assert "Traceback" not in stderr
    return stdout, d


def _valid_png(path: Path) -> None:
    import matplotlib.image

    assert path.is_file(), path
    assert path.read_bytes()[:8] == PNG_MAGIC
    image = matplotlib.image.imread(path)  # decodes the whole file
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200


def test_help_lists_every_subcommand(runs):
    stdout, _ = _ok(runs, "help")
    assert stdout.startswith("usage: dva isolator")
    for name in SUBCOMMANDS:
        assert name in stdout


def test_modal_json(runs):
    payload = json.loads(_ok(runs, "modal")[0])
    assert payload["natural_frequency_rad_s"] == pytest.approx(214.806, abs=0.0005)
    assert payload["damping_ratio"] == pytest.approx(0.1815, abs=0.0005)
    assert payload["element_types"] == ["B", "C"]


def test_identify_json(runs):
    stdout, _ = _ok(runs, "identify")
    payload = json.loads(stdout)
    assert payload["c"] == pytest.approx(40.0, rel=1e-4)
    assert [e["type"] for e in payload["elements"]] == ["B", "C"]
    assert payload["elements"][0]["k"] == pytest.approx(12 * KN, rel=1e-4)
    assert payload["elements"][1]["c"] == pytest.approx(2000.0, rel=1e-4)
    assert payload["frf_error"] < 1e-6
    assert payload["covariates"] == ["temperature_c"]


def test_estimate_writes_frf_csv(runs):
    stdout, d = _ok(runs, "estimate")
    payload = json.loads(stdout)
    assert payload["fs_hz"] == pytest.approx(500.0)
    data = isolator_files.read_frf_csv(d / "est.csv", "accelerance")
    np.testing.assert_allclose(data.values, 2.0, rtol=1e-9)


def test_stepped_sine_json(runs):
    stdout, _ = _ok(runs, "stepped_sine")
    payload = json.loads(stdout)
    assert payload["natural_frequency_rad_s"] == pytest.approx(187.15, rel=0.005)
    assert round(payload["damping_ratio"], 2) == 0.09


def test_static_json(runs):
    payload = json.loads(_ok(runs, "static")[0])
    assert payload["static_stiffness_n_per_m"] == pytest.approx(23151, rel=1e-9)


def test_plot_writes_a_valid_png(runs):
    stdout, d = _ok(runs, "plot")
    assert stdout.strip() == "wrote " + str(d / "frf.png")
    _valid_png(d / "frf.png")


@pytest.mark.parametrize(
    "name, message",
    [
        ("bad_missing_columns", "missing column(s) ['imag']"),
        ("bad_nan", "column 'real' is NaN at line 9"),
        ("bad_non_increasing", "frequency_hz must be strictly increasing: line 14 (2 Hz) "
                               "follows line 13"),
        ("bad_too_few", "too few frequency points: 6 (need at least 10)"),
        ("bad_static_stiffness_in_kn_per_m", "static stiffness in kN/m"),
    ],
)
def test_bad_input_exit_2_with_one_line(runs, name, message):
    code, stdout, stderr, _ = runs[name]
    assert code == 2, f"{name}: exit {code}\n{stderr}"
    assert stdout == ""
    assert "Traceback" not in stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("dva isolator: error: ")
    assert message in lines[0], lines[0]
