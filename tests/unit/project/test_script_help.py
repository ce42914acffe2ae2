"""The README's shell scripts answer --help at once (no setup, no build) with what they do and
the one exit-code table of every executable (aero_dva.exits)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from aero_dva import exits

REPO = Path(__file__).resolve().parents[3]
SCRIPTS = ("run.sh", "test.sh", "scripts/setup.sh", "scripts/stress_tests.sh")


@pytest.mark.parametrize("script", SCRIPTS)
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_a_script_says_the_exit_code_table_in_its_help(script, flag, tmp_path):
    # run from elsewhere, with a venv path that does not exist: --help needs neither
    result = subprocess.run(["bash", str(REPO / script), flag], capture_output=True, text=True,
                            timeout=60, cwd=tmp_path, env={"PATH": "/usr/bin:/bin",
                                                           "DVA_VENV": str(tmp_path / "no")})
    assert result.returncode == exits.DONE, result.stderr
    said = " ".join(result.stdout.split())
    for code, meaning in exits.TABLE.items():
        assert f"{code} {' '.join(meaning.split())}" in said, (script, code)
    assert not (tmp_path / "no").exists() and not result.stderr.strip(), result.stderr
