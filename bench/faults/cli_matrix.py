"""Malformed inputs to every ``dva`` command that reads a file, run as the user runs them.

A case is one command line with one bad (or oddly named) input file. An error case passes when
the command exits with code 2, ends with exactly one error line on stderr (``dva <command>:
error: ...``) that names the input file (progress lines such as "reading X ..." may come
before it), prints no traceback or warning, and leaves none of its output paths behind (a
file or a directory that exists after a failure would claim a result that was never made).
An ``ok`` case (valid content at a path with spaces and non-ASCII letters) passes when the
command exits 0.

Input kinds (not every kind applies to every format): empty, binary (random bytes with NULs
and invalid UTF-8), missing columns or keys, NaN, duplicate or negative frequencies (for time
series: duplicate times), negative values, a file of ten million lines, and a bag without the
topics the command needs.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from aero_dva.flight.damper import DAMPER_RANGE
from bench.faults.bad_inputs import (
    CSV_FORMATS,
    HUGE_LINES,
    ODD_DIR,
    ODD_NAME,
    SMALL_PLAN,
    SUFFIX,
    WRITERS,
    kinds_of,
    write_binary,
    write_huge,
)

C2_RANGE = "{:g}:{:g}:6".format(*DAMPER_RANGE)  # a short c2 grid over the damper's range

# --------------------------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Command:
    """One way a ``dva`` command reads one input file.

    ``argv(file, out)`` builds the arguments after ``dva`` for the input ``file`` with outputs
    under the directory ``out``; ``outputs`` name what the command would create in ``out``.
    ``odd_path_ok``: a valid file at an odd path is cheap enough to run to success.
    ``ok_kinds``: kinds of input the command must accept (a bag without flight topics is a
    valid bag for ``dva bag info``).
    """

    name: str
    option: str
    fmt: str
    argv: Callable[[str, Path], list[str]]
    outputs: tuple[str, ...] = ()
    odd_path_ok: bool = False
    ok_kinds: tuple[str, ...] = ()  # kinds that are valid input for this command


_EVAL = ["--graph", "--seeds", "1", "--mu", "0", "--reports", "none"]  # the graph's options

COMMANDS: tuple[Command, ...] = (
    Command("wing modal", "--wing", "wing", lambda f, o: [
        "wing", "modal", "--wing", f, "--points", "5", "--plot", str(o / "modal.png")],
        ("modal.png",), odd_path_ok=True),
    Command("wing flutter", "--section", "section", lambda f, o: [
        "wing", "flutter", "--section", f, "--aero", "theodorsen"], odd_path_ok=True),
    Command("wing flutter", "--wing", "wing", lambda f, o: ["wing", "flutter", "--wing", f],
            odd_path_ok=True),
    Command("wing design", "--wing", "wing", lambda f, o: [
        "wing", "design", "--wing", f, "--plot", str(o / "design.png")], ("design.png",)),
    Command("wing simulate", "--wing", "wing", lambda f, o: [
        "wing", "simulate", "--wing", f, "--duration", "0.5", "--plot", str(o / "sim.png")],
        ("sim.png",)),
    Command("control optimal-c2", "--wing", "wing", lambda f, o: [
        "control", "optimal-c2", "--wing", f, "--airspeeds", "0.8:1.0:3", "--relative",
        "--c2-range", C2_RANGE, "--plot", str(o / "c2.png")], ("c2.png",)),
    Command("control schedule", "--wing", "wing", lambda f, o: [
        "control", "schedule", "--wing", f, "--airspeeds", "0.9:1.1:5", "--relative",
        "--c2-range", C2_RANGE, "--out", str(o / "schedule.json")], ("schedule.json",)),
    Command("isolator identify", "FILE", "frf", lambda f, o: [
        "isolator", "identify", f, "--mass", "1", "--static-stiffness", "12000", "--elements",
        "2", "--plot", str(o / "fit.png")], ("fit.png",), odd_path_ok=True),
    Command("isolator identify", "FILE (UFF 58)", "uff", lambda f, o: [
        "isolator", "identify", f, "--mass", "1", "--static-stiffness", "12000", "--plot",
        str(o / "fit.png")], ("fit.png",)),
    Command("isolator stepped-sine", "FILE", "stepped", lambda f, o: [
        "isolator", "stepped-sine", f, "--out", str(o / "frf.csv"), "--plot",
        str(o / "steps.png")], ("frf.csv", "steps.png"), odd_path_ok=True),
    Command("isolator estimate", "FILE", "series", lambda f, o: [
        "isolator", "estimate", f, "--nfft", "1000", "--out", str(o / "frf.csv")],
        ("frf.csv",), odd_path_ok=True),
    Command("isolator static", "FILE", "static", lambda f, o: ["isolator", "static", f],
            odd_path_ok=True),
    Command("isolator plot", "FILE", "frf", lambda f, o: [
        "isolator", "plot", f, "--plot", str(o / "frf.png")], ("frf.png",), odd_path_ok=True),
    Command("discrepancy frf", "FILE", "frf", lambda f, o: [
        "discrepancy", "frf", f, "--elements", "1", "--plot-dir", str(o / "plots")],
        ("plots",)),
    Command("discrepancy modal", "FILE", "frf", lambda f, o: [
        "discrepancy", "modal", f, "--plot-dir", str(o / "plots")], ("plots",)),
    Command("discrepancy flight", "FILE", "bag", lambda f, o: [
        "discrepancy", "flight", f, "--plot-dir", str(o / "plots")], ("plots",)),
    Command("train plan", "--wing", "wing", lambda f, o: [
        "train", "plan", "--wing", f, *SMALL_PLAN, "--out", str(o / "plan.json")],
        ("plan.json",), odd_path_ok=True),
    Command("train sweep", "--plan", "plan", lambda f, o: [
        "train", "sweep", "--plan", f, "--out", str(o / "sweep")], ("sweep",)),
    Command("train sweep", "--scenario", "scenario", lambda f, o: [
        "train", "sweep", "--scenario", f, "--out", str(o / "sweep")], ("sweep",)),
    Command("train rbf", "BAG", "bag", lambda f, o: [
        "train", "rbf", f, "--out", str(o / "net.npz"), "--plot", str(o / "fig.png")],
        ("net.npz", "fig.png")),
    Command("report", "RUN", "bag", lambda f, o: [
        "report", f, "--out", str(o / "report"), "--no-rrd"], ("report",)),
    Command("replay", "BAG", "bag", lambda f, o: [
        "replay", f, "--controller", "fixed", "--offline", "--out", str(o / "replay")],
        ("replay",)),
    Command("bag info", "BAG", "bag", lambda f, o: ["bag", "info", f],
            ok_kinds=("missing-topics",)),
    Command("bag recover", "BAG", "bag", lambda f, o: [
        "bag", "recover", f, "--out", str(o / "recovered")], ("recovered",),
        ok_kinds=("missing-topics",)),
    Command("evaluate", "--scenario", "scenario", lambda f, o: [
        "evaluate", "--controllers", "none", "--scenario", f, "--out", str(o / "eval"), *_EVAL],
        ("eval",)),
    Command("evaluate", "--schedule", "schedule", lambda f, o: [
        "evaluate", "--controllers", "schedule", "--schedule", f, "--out", str(o / "eval"),
        *_EVAL], ("eval",)),
    Command("evaluate", "--network", "network", lambda f, o: [
        "evaluate", "--controllers", "rbf", "--network", f, "--out", str(o / "eval"), *_EVAL],
        ("eval",)),
    Command("evaluate", "--sweep-bag", "bag", lambda f, o: [
        "evaluate", "--controllers", "rbf", "--sweep-bag", f, "--out", str(o / "eval"),
        *_EVAL], ("eval",)),
)


def command(name: str, option: str) -> Command:
    """The command of :data:`COMMANDS` with this name and input option."""
    for found in COMMANDS:
        if (found.name, found.option) == (name, option):
            return found
    raise KeyError(f"no command {name!r} {option!r} in the matrix")


@dataclass(frozen=True)
class CliCase:
    """One command line with one input file; ``expect_ok`` for the odd-path valid cases."""

    command: Command
    kind: str
    input_path: Path
    out_dir: Path
    expect_ok: bool = False

    @property
    def argv(self) -> list[str]:
        return self.command.argv(str(self.input_path), self.out_dir)

    @property
    def outputs(self) -> list[Path]:
        return [self.out_dir / name for name in self.command.outputs]

    @property
    def label(self) -> str:
        return f"{self.command.name} {self.command.option}: {self.kind}"


@dataclass
class CaseFiles:
    """Writes the input files of the cases under ``root``; the huge files once per format."""

    root: Path
    huge_lines: int = HUGE_LINES
    _huge_files: dict[str, Path] = field(default_factory=dict)

    def huge(self, fmt: str) -> Path:
        content = fmt if fmt in CSV_FORMATS else "text"  # one text file serves the others
        if content not in self._huge_files:
            path = self.root / "write_huge" / f"{content}.lines"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_huge(path, content)
            self._huge_files[content] = path
        return self._huge_files[content]

    def write(self, fmt: str, kind: str, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        if kind == "empty":
            path.write_bytes(b"")
        elif kind == "binary":
            write_binary(path)
        elif kind == "ten-million-lines":
            os.link(self.huge(fmt), path)  # the same 10-million-line file, not a copy
        else:
            WRITERS[fmt][kind](path)


def build_cases(root: Path, commands: Iterable[Command] = COMMANDS,
                kinds: Iterable[str] | None = None) -> list[CliCase]:
    """Write the inputs of every (command, kind) case under ``root``; the cases.

    ``kinds`` limits the kinds (default all that apply, plus the odd-path cases).
    """
    files = CaseFiles(root)
    wanted = None if kinds is None else set(kinds)
    cases = []
    for number, command in enumerate(commands):
        fmt_kinds = kinds_of(command.fmt)
        odd = ["odd-path"] if "valid" in WRITERS[command.fmt] else []
        for kind in [*fmt_kinds, *odd]:
            if wanted is not None and kind not in wanted:
                continue
            slug = f"{number:02d}_{command.name.replace(' ', '_')}_{kind}"
            case_dir = root / slug / (ODD_DIR if kind == "odd-path" else "")
            name = (ODD_NAME if kind == "odd-path" else "input") + SUFFIX[command.fmt]
            path = case_dir / name
            if kind == "odd-path":
                files.write(command.fmt, "valid", path)
                expect_ok = command.odd_path_ok
                if not expect_ok:  # too costly to run to success: a bad file at the odd path
                    path.unlink()
                    files.write(command.fmt, "binary", path)
            else:
                files.write(command.fmt, kind, path)
                expect_ok = kind in command.ok_kinds
            out_dir = case_dir / "out"
            out_dir.mkdir()
            cases.append(CliCase(command, kind, path, out_dir, expect_ok))
    return cases


# --------------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CliOutcome:
    """What one case did: exit code (None: killed at the timeout), stderr, time, memory."""

    case: CliCase
    code: int | None
    stderr: str
    seconds: float
    peak_rss_mb: float
    left_behind: tuple[str, ...]

    @property
    def error_lines(self) -> list[str]:
        """Lines of stderr that report a problem (progress lines such as "reading X ..."
        are not counted)."""
        words = ("error", "Error", "Traceback", "Warning", "warning", "Exception")
        return [line for line in self.stderr.splitlines() if any(w in line for w in words)]

    def problems(self) -> list[str]:
        """Why the case fails its contract; empty when it passes."""
        if self.case.expect_ok:
            return [] if self.code == 0 else [f"exit {self.code}: {self.stderr.strip()[-300:]}"]
        found = []
        if self.code != 2:
            found.append("timed out" if self.code is None else f"exit {self.code}")
        if "Traceback" in self.stderr:
            found.append("traceback")
        lines = self.error_lines
        last = self.stderr.strip().splitlines()[-1:] or [""]
        if len(lines) != 1:
            found.append(f"{len(lines)} error lines")
        elif lines != last or not lines[0].startswith("dva "):
            found.append("the error is not the last line, as 'dva <command>: error: ...'")
        elif self.case.input_path.name not in lines[0]:
            found.append("error does not name the file")
        if self.left_behind:
            found.append(f"left {', '.join(self.left_behind)}")
        return found

    @property
    def passed(self) -> bool:
        return not self.problems()


def _left_behind(case: CliCase) -> tuple[str, ...]:
    left = []
    for path in case.outputs:
        if path.is_dir() and any(path.iterdir()) or path.is_file():
            left.append(path.name)
        elif path.is_dir():
            left.append(path.name + "/ (empty)")
    return tuple(left)


def run_case(case: CliCase, timeout: float = 300.0, env: dict | None = None) -> CliOutcome:
    """Run ``dva`` on the case in a process of its own (peak memory from its rusage)."""
    argv = [sys.executable, "-m", "dva_offline.cli", *case.argv]
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        started = time.monotonic()
        process = subprocess.Popen(argv, stdout=out, stderr=err, env=env,
                                   cwd=case.out_dir.parent)
        killed = False
        peak_kb = 0.0
        while True:
            peak_kb = max(peak_kb, _high_water_kb(process.pid))
            pid, status, _ = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            if not killed and time.monotonic() - started > timeout:
                process.kill()
                killed = True
            time.sleep(0.02)
        seconds = time.monotonic() - started
        process.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read().decode("utf-8", errors="replace")
    return CliOutcome(case, None if killed else process.returncode, stderr, seconds,
                      peak_kb / 1024.0, _left_behind(case))


def run_case_in_process(case: CliCase) -> CliOutcome:
    """:func:`run_case` with ``dva_offline.cli.main`` called in this process: no interpreter
    start, for fast tests. Warnings go to the captured stderr as the interpreter would print
    them, and an exception escaping ``main`` is printed there as a traceback. No memory figure.
    """
    from dva_offline import cli

    err = io.StringIO()
    started = time.monotonic()
    with warnings.catch_warnings(record=True) as caught, \
            contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        warnings.resetwarnings()  # the interpreter's defaults, not the test runner's
        for hidden in (DeprecationWarning, PendingDeprecationWarning, ImportWarning,
                       ResourceWarning):
            warnings.simplefilter("ignore", hidden)
        try:
            code = cli.main(case.argv)
        except SystemExit as exc:  # argparse's own errors
            code = exc.code if isinstance(exc.code, int) else 1
        except Exception:  # what would reach the user as a traceback
            traceback.print_exc(file=err)
            code = 1
    printed = "".join(warnings.formatwarning(w.message, w.category, w.filename, w.lineno)
                      for w in caught)
    return CliOutcome(case, code, printed + err.getvalue(), time.monotonic() - started, math.nan,
                      _left_behind(case))


def _high_water_kb(pid: int) -> float:
    """[kB] peak resident memory of a running process (VmHWM). Not ru_maxrss: Linux carries
    that over from the parent through fork and exec, so it would report the bench's size."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1])
    except (OSError, ValueError):
        pass  # gone already, or not Linux
    return 0.0


def clean(root: Path) -> None:
    shutil.rmtree(root, ignore_errors=True)
