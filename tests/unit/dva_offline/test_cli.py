"""The ``dva`` command: help, version, info, and one-line errors."""
from __future__ import annotations

import json
import subprocess
import sys

from dva_offline import cli


def test_help_lists_subcommands(capsys):
    assert cli.main([]) == 2
    out = capsys.readouterr().out
    for name in cli.COMMANDS:
        assert name in out


def test_info_json_is_one_object():
    result = subprocess.run([sys.executable, "-m", "dva_offline.cli", "info", "--json"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    facts = json.loads(result.stdout)
    assert facts["packages"]["numpy"]
    assert facts["model_packages"]["aero_dva_sim"] is True


def test_unknown_subcommand_is_an_error():
    result = subprocess.run([sys.executable, "-m", "dva_offline.cli", "no-such-command"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2
    assert "invalid choice" in result.stderr
