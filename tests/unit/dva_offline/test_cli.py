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


def test_a_closed_pipe_ends_a_command_quietly_with_141():
    """stdout's reader is gone before the command writes (``| head`` that has read its fill):
    no error line, exit code 141 (128 + SIGPIPE), as a Unix tool that SIGPIPE ends."""
    import os

    read_end, write_end = os.pipe()
    os.close(read_end)  # closed before the command starts: its first write meets it
    try:
        result = subprocess.run([sys.executable, "-m", "dva_offline.cli", "wing", "flutter"],
                                stdout=write_end, stderr=subprocess.PIPE, timeout=300)
    finally:
        os.close(write_end)
    assert result.returncode == cli.CLOSED_PIPE_EXIT == 141
    assert result.stderr == b""


def test_bag_info_into_head_says_nothing_on_stderr(tmp_path):
    """The README's ``dva bag info BAG | head -1``: the first line, nothing else."""
    from tests.unit.aero_dva.bag.reference_bag import write_batch_bag

    bag = write_batch_bag(tmp_path / "bag")
    result = subprocess.run(
        ["bash", "-c", f'"{sys.executable}" -m dva_offline.cli bag info "{bag}" | head -1; '
                       'echo "exit ${PIPESTATUS[0]}" >&2'],
        capture_output=True, text=True, timeout=300)
    assert result.stdout == f"bag        {bag}\n"
    assert result.stderr in ("exit 0\n", "exit 141\n")


def test_an_error_naming_hostile_text_is_one_escaped_bounded_line(tmp_path, capsys):
    """A file name with escape codes and a newline, and thousands of characters, reaches
    the error line escaped and cut: one line, no raw control character."""
    name = "\x1b[31mred\nINJECTED " + "y" * 3000
    assert cli.main(["wing", "flutter", "--wing", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\x1b" not in err and len(err) < 1200, err
    assert "\\x1b[31m" in err or "\\\\x1b[31m" in err


def test_an_error_raised_while_an_interrupt_unwinds_is_an_interrupt(monkeypatch, capsys):
    """Code on the way out that breaks because of the interrupt (tqdm stopped inside its
    lock raises AttributeError) does not turn an interrupt into an internal error."""
    from dva_offline.wing import cli as wing_cli

    def broken_by_the_interrupt(args):
        try:
            raise KeyboardInterrupt
        finally:
            raise AttributeError("type object 'tqdm' has no attribute '_lock'")

    monkeypatch.setattr(wing_cli, "_flutter", broken_by_the_interrupt, raising=False)
    parser = cli.build_parser()
    args = parser.parse_args(["wing", "flutter"])
    monkeypatch.setattr(args, "func", broken_by_the_interrupt)
    monkeypatch.setattr(cli, "build_parser", lambda: _Fixed(args))
    assert cli.main(["wing", "flutter"]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == "dva wing: interrupted"


class _Fixed:
    """A parser that returns the given arguments."""

    def __init__(self, args):
        self.args = args

    def parse_args(self, argv):
        return self.args
