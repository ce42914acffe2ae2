"""``dva``'s exit codes are the project's table (aero_dva.exits), said in --help and carried as
``exit_code`` in --json; SIGTERM stops a command as SIGINT does; a second run into an output
that another run is writing is refused in one line."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from aero_dva import exits
from dva_offline import cli

DVA = [sys.executable, "-m", "dva_offline.cli"]


def _dva(*args, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([*DVA, *map(str, args)], capture_output=True, text=True,
                          timeout=600, **kwargs)


def test_help_says_every_code_of_the_table(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    for code, meaning in exits.TABLE.items():
        assert f"{code} {' '.join(meaning.split())}" in out


def test_a_bad_input_in_json_mode_is_one_line_and_a_json_object(tmp_path):
    result = _dva("bag", "info", tmp_path / "no_such_bag", "--json")
    assert result.returncode == exits.BAD_INPUT
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("dva bag: error: ") and "no_such_bag" in line
    payload = json.loads(result.stdout)
    assert payload["exit_code"] == exits.BAD_INPUT and "no_such_bag" in payload["error"]


def test_a_result_in_json_mode_carries_its_exit_code():
    result = _dva("wing", "flutter", "--json")
    assert result.returncode == exits.DONE, result.stderr
    assert json.loads(result.stdout)["exit_code"] == exits.DONE


HOLD = textwrap.dedent("""
    import sys
    from aero_dva.atomic_io import output_lock
    with output_lock(sys.argv[1], "--out"):
        print("held", flush=True)
        sys.stdin.readline()
""")


@pytest.mark.parametrize("command", [["control", "schedule"], ["bag", "recover", "BAG"],
                                     ["evaluate", "--seeds", "1"], ["train", "sweep"]])
def test_a_second_run_into_an_output_being_written_is_refused(command, tmp_path):
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert first.stdout.readline().strip() == "held"  # as a first run holds it
        argv = [str(tmp_path / "bag") if a == "BAG" else a for a in command]
        second = _dva(*argv, "--out", out)
    finally:
        first.communicate("\n", timeout=60)
    assert second.returncode == exits.BAD_INPUT, second.stderr
    (line,) = second.stderr.strip().splitlines()
    assert "is being written by another run right now" in line and str(out) in line
    assert not out.exists()  # refused before any work


def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path):
    (tmp_path / "a_file").write_text("")
    result = _dva("control", "schedule", "--out", tmp_path / "a_file" / "schedule.json")
    assert result.returncode == exits.BAD_INPUT, result.stderr
    (line,) = result.stderr.strip().splitlines()  # no progress bar: nothing was computed
    assert line == (f"dva control: error: --out '{tmp_path / 'a_file' / 'schedule.json'}' "
                    f"cannot be made: '{tmp_path / 'a_file'}' is not a directory"), line


def test_sigterm_stops_a_command_like_sigint_in_one_line(tmp_path):
    """``dva evaluate`` says a line as soon as it starts making its inputs; a SIGTERM then
    stops it with exit code 130 and one line, as Ctrl-C would."""
    process = subprocess.Popen([*DVA, "evaluate", "--seeds", "1", "--out", str(tmp_path / "e")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=dict(os.environ, PYTHONUNBUFFERED="1"))
    first = process.stderr.readline()
    assert first.startswith("dva evaluate: "), first
    process.send_signal(signal.SIGTERM)
    _, rest = process.communicate(timeout=300)
    assert process.returncode == exits.INTERRUPTED, rest
    lines = [line for line in rest.strip().splitlines() if line.strip()]
    assert lines[-1] == "dva evaluate: interrupted by SIGTERM", rest
    assert "Traceback" not in rest
