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
import functools
import io
import json
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

import numpy as np
import yaml

HUGE_LINES = 10_000_000
ODD_DIR = "dir with spaces, ünïcødé ✈"
ODD_NAME = "mesure n°1 — données"

# Input formats: name -> file suffix.
SUFFIX = {"frf": ".csv", "series": ".csv", "stepped": ".csv", "static": ".csv", "uff": ".uff",
          "wing": ".yaml", "section": ".yaml", "scenario": ".yaml", "schedule": ".json",
          "network": ".npz", "bag": ".mcap", "plan": ".json"}
CSV_FORMATS = ("frf", "series", "stepped", "static")


# --------------------------------------------------------------------------------------------
# Input files
# --------------------------------------------------------------------------------------------

def _frf_rows(n: int = 200) -> tuple[list[str], np.ndarray]:
    """A Maxwell-Voigt receptance (Table 4.1 system F of the study) at ``n`` frequencies."""
    from dva_offline.isolator.maxwell_model import MaxwellModel, frf

    model = MaxwellModel(1.0, 12e3, 40.0, (12e3, 24e3), (80.0, 2000.0))
    f = np.linspace(0.5, 50.0, n)
    h = frf(model, 2 * np.pi * f, "receptance")
    return ["frequency_hz", "real", "imag"], np.column_stack([f, h.real, h.imag])


def _stepped_rows() -> tuple[list[str], np.ndarray]:
    """Steps through the resonance of a lightly damped Voigt system (17.4 Hz, 2 %)."""
    from dva_offline.isolator.maxwell_model import MaxwellModel, frf

    f = np.linspace(5.0, 30.0, 126)
    h = frf(MaxwellModel(1.0, 12e3, 8.8), 2 * np.pi * f, "receptance")
    return ["frequency_hz", "real", "imag"], np.column_stack([f, h.real, h.imag])


def _series_rows(n: int = 20_000) -> tuple[list[str], np.ndarray]:
    """White force through a lightly damped 25 Hz resonance, sampled at 1 kHz."""
    from scipy import signal

    rng = np.random.default_rng(0)
    fs = 1000.0
    force = rng.normal(0.0, 10.0, n)
    system = signal.cont2discrete(([1.0], [1.0, 2 * 0.05 * 157.0, 157.0**2]), 1 / fs)
    response = signal.lfilter(np.ravel(system[0]), system[1], force)
    return ["time_s", "force_n", "response_m"], np.column_stack([np.arange(n) / fs, force,
                                                                  response])


def _static_rows() -> tuple[list[str], np.ndarray]:
    x = np.concatenate([np.linspace(-2e-3, 2e-3, 50), np.linspace(2e-3, -2e-3, 50)])
    load = 1.2e4 * x + np.concatenate([np.full(50, -2.0), np.full(50, 2.0)])
    return ["deflection_m", "load_n"], np.column_stack([x, load])


def _csv_text(header: list[str], rows: np.ndarray) -> str:
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in row) for row in rows]
    return "\n".join(lines) + "\n"


def _binary(path: Path) -> None:
    # NULs and bytes that are not UTF-8, as a wrong file picked by accident would have.
    path.write_bytes(np.random.default_rng(1234).integers(0, 256, 4096, dtype=np.uint8)
                     .tobytes() + b"\x00\xff\xfe")


def _huge(path: Path, fmt: str) -> None:
    """Ten million lines: rows that would each be valid (increasing abscissa) where a CSV is
    expected, else a line of text repeated."""
    header, tail = {"frf": ("frequency_hz,real,imag", ",1e-06,-1e-07"),
                    "stepped": ("frequency_hz,real,imag", ",1e-06,-1e-07"),
                    "series": ("time_s,force_n,response_m", ",1.0,0.5"),
                    "static": ("deflection_m,load_n", ",1.0")}.get(fmt, (None, None))
    step = 100_000  # lines per write: the writer stays small
    with open(path, "w", encoding="ascii") as out:
        if header is None:
            line = "# padding\n"
            for _ in range(HUGE_LINES // step):
                out.write(line * step)
            return
        out.write(header + "\n")
        for first in range(1, HUGE_LINES, step):  # the header is line 1
            last = min(first + step, HUGE_LINES)
            out.write((tail + "\n").join(map(str, range(first, last))) + tail + "\n")


def _write_uff(path: Path) -> None:
    from dva_offline.isolator.isolator_io import write_uff58

    _, rows = _frf_rows()
    write_uff58(path, rows[:, 0], rows[:, 1] + 1j * rows[:, 2], "receptance")


def _wing_dict() -> dict:
    from aero_dva.wing.wing_io import reference_wing_path

    return yaml.safe_load(Path(reference_wing_path()).read_text(encoding="utf-8"))


SECTION = dict(semichord=1.0, mass_ratio=20.0, radius_of_gyration_sq=0.24, frequency_ratio=0.4,
               static_unbalance=0.1, elastic_axis=-0.2, pitch_frequency=1.0, air_density=1.0)


def _scenario_dict(name: str = "scenario_ramp.yaml") -> dict:
    from aero_dva import data_files

    return yaml.safe_load(Path(data_files.data_file(name)).read_text(encoding="utf-8"))


def _schedule_dict() -> dict:
    from aero_dva.control.airspeed_schedule import AirspeedSchedule
    from aero_dva.control.schedule_io import schedule_to_dict

    return schedule_to_dict(AirspeedSchedule(a0=-2000.0, a1=25.0, airspeed_range=(95.0, 120.0),
                                             damping_range=(0.0, 2500.0)))


@functools.lru_cache(maxsize=1)
def _plan_text() -> str:
    """A small valid training plan (2 airspeeds x 3 c2), made by ``dva train plan``."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "plan.json"
        subprocess.run([sys.executable, "-m", "dva_offline.cli", "train", "plan",
                        *_SMALL_PLAN, "--out", str(path)], check=True, capture_output=True,
                       timeout=300)
        return path.read_text(encoding="utf-8")


def _plan_dict() -> dict:
    return json.loads(_plan_text())


def _write_network(path: Path, *, nan: bool = False, header: bool = True) -> None:
    from aero_dva.control.rbf_io import save_rbf_network
    from aero_dva.control.rbf_network import InputScaling, RBFNetwork

    dim = 33
    centres = np.random.default_rng(2).uniform(0.0, 1.0, (4, dim))
    if nan:
        centres[1, 3] = np.nan
    network = RBFNetwork(centres=np.nan_to_num(centres), output_weights=np.ones(4),
                         output_bias=0.0, spread=1.0,
                         scaling=InputScaling(np.zeros(dim), np.ones(dim)),
                         input_names=tuple(f"x{i}" for i in range(dim)),
                         input_units=("1",) * dim, output_name="c2", output_unit="N s/m")
    tmp = path.with_name("valid_" + path.name)
    save_rbf_network(network, tmp)
    with np.load(tmp, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    tmp.unlink()
    if nan:
        arrays["centres"] = centres
    if not header:
        arrays.pop("header")
    with open(path, "wb") as stream:
        np.savez(stream, **arrays)


def _write_bag_without_topics(path: Path) -> None:
    """A complete, valid bag directory holding only damper commands."""
    from aero_dva.bag.bag_writer import BagWriter

    with BagWriter(path) as writer:
        writer.add_topic("/dva/damper_command", "dva_msgs/msg/DamperCommand")
        for i in range(10):
            writer.write("/dva/damper_command", {"header": {"stamp": {"sec": i, "nanosec": 0},
                                                            "frame_id": ""},
                                                 "damping": 500.0, "source": "fixed"},
                         log_time_ns=i * 10**9)


def _yaml(path: Path, data) -> None:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")


def _with(data: dict, *keys_value) -> dict:
    """A deep copy of ``data`` with one nested key set (or removed, value ``...``)."""
    out = json.loads(json.dumps(data))
    *keys, value = keys_value
    node = out
    for key in keys[:-1]:
        node = node[key]
    if value is ...:
        node.pop(keys[-1])
    else:
        node[keys[-1]] = value
    return out


def _json_nan(path: Path, data: dict, key: str) -> None:
    path.write_text(json.dumps(_with(data, key, float("nan"))), encoding="utf-8")


def _frf_variant(path: Path, change: Callable[[np.ndarray], np.ndarray],
                 header: list[str] | None = None) -> None:
    names, rows = _frf_rows()
    rows = change(rows.copy())
    names = header or names
    path.write_text(_csv_text(names, rows[:, :len(names)]), encoding="utf-8")


def _set(rows: np.ndarray, index, value) -> np.ndarray:
    rows[index] = value
    return rows


# format -> kind -> writer(path). "valid" is the content of the odd-path ok cases.
WRITERS: dict[str, dict[str, Callable[[Path], None]]] = {
    "frf": {
        "valid": lambda p: p.write_text(_csv_text(*_frf_rows()), encoding="utf-8"),
        "missing-columns": lambda p: _frf_variant(p, lambda r: r, ["frequency_hz", "real"]),
        "nan": lambda p: _frf_variant(p, lambda r: _set(r, (10, 1), np.nan)),
        "duplicate-frequency": lambda p: _frf_variant(p, lambda r: _set(r, (10, 0), r[9, 0])),
        "negative-frequency": lambda p: _frf_variant(p, lambda r: _set(r, (slice(None), 0),
                                                                       r[:, 0] - 10.0)),
    },
    "stepped": {
        "valid": lambda p: p.write_text(_csv_text(*_stepped_rows()), encoding="utf-8"),
        "missing-columns": lambda p: p.write_text(
            _csv_text(["frequency_hz", "force_amplitude_n"], _stepped_rows()[1][:, :2]),
            encoding="utf-8"),
        "nan": lambda p: p.write_text(
            _csv_text(_stepped_rows()[0], _set(_stepped_rows()[1], (7, 2), np.nan)),
            encoding="utf-8"),
        "duplicate-frequency": lambda p: p.write_text(
            _csv_text(_stepped_rows()[0], _set(_stepped_rows()[1], (7, 0), 5.8)),
            encoding="utf-8"),
        "negative-frequency": lambda p: p.write_text(
            _csv_text(_stepped_rows()[0], _set(_stepped_rows()[1], (0, 0), -5.0)),
            encoding="utf-8"),
    },
    "series": {
        "valid": lambda p: p.write_text(_csv_text(*_series_rows()), encoding="utf-8"),
        "missing-columns": lambda p: p.write_text(
            _csv_text(["time_s", "response_m"], _series_rows()[1][:, [0, 2]]), encoding="utf-8"),
        "nan": lambda p: p.write_text(
            _csv_text(_series_rows()[0], _set(_series_rows()[1], (100, 1), np.nan)),
            encoding="utf-8"),
        "duplicate-time": lambda p: p.write_text(
            _csv_text(_series_rows()[0], _set(_series_rows()[1], (100, 0), 0.099)),
            encoding="utf-8"),
    },
    "static": {
        "valid": lambda p: p.write_text(_csv_text(*_static_rows()), encoding="utf-8"),
        "missing-columns": lambda p: p.write_text(
            _csv_text(["deflection_m"], _static_rows()[1][:, :1]), encoding="utf-8"),
        "nan": lambda p: p.write_text(
            _csv_text(_static_rows()[0], _set(_static_rows()[1], (5, 1), np.nan)),
            encoding="utf-8"),
    },
    "uff": {
        "valid": lambda p: _write_uff(p),
    },
    "wing": {
        "valid": lambda p: _yaml(p, _wing_dict()),
        "syntax-error": lambda p: p.write_text("wing: {mass: [1000.0\n", encoding="utf-8"),
        "missing-keys": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", ...)),
        "nan": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", float("nan"))),
        "negative": lambda p: _yaml(p, _with(_wing_dict(), "wing", "mass", -1000.0)),
    },
    "section": {
        "valid": lambda p: _yaml(p, SECTION),
        "syntax-error": lambda p: p.write_text("semichord: 1.0\n  - mass_ratio\n",
                                               encoding="utf-8"),
        "missing-keys": lambda p: _yaml(p, _with(SECTION, "mass_ratio", ...)),
        "nan": lambda p: _yaml(p, _with(SECTION, "mass_ratio", float("nan"))),
        "negative-frequency": lambda p: _yaml(p, _with(SECTION, "pitch_frequency", -1.0)),
    },
    "scenario": {
        "syntax-error": lambda p: p.write_text("airspeed: {kind: ramp\n", encoding="utf-8"),
        "missing-keys": lambda p: _yaml(p, _with(_scenario_dict(), "airspeed", ...)),
        "nan": lambda p: _yaml(p, _with(_scenario_dict(), "duration", float("nan"))),
        "negative-frequency": lambda p: _yaml(p, _with(_scenario_dict(), "sample_rate",
                                                       -1000.0)),
    },
    "schedule": {
        "syntax-error": lambda p: p.write_text('{"a0": 1.0,', encoding="utf-8"),
        "missing-keys": lambda p: p.write_text(json.dumps(_with(_schedule_dict(), "a1", ...)),
                                               encoding="utf-8"),
        "nan": lambda p: _json_nan(p, _schedule_dict(), "a0"),
    },
    "plan": {
        "syntax-error": lambda p: p.write_text('{"format": ', encoding="utf-8"),
        "missing-keys": lambda p: p.write_text(json.dumps(_with(_plan_dict(), "dwells", ...)),
                                               encoding="utf-8"),
        "nan": lambda p: p.write_text(json.dumps(_with(_plan_dict(), "dwells", "airspeed",
                                                       [math.nan] * 6)), encoding="utf-8"),
    },
    "network": {
        "missing-keys": lambda p: _write_network(p, header=False),
        "nan": lambda p: _write_network(p, nan=True),
    },
    "bag": {
        "missing-topics": _write_bag_without_topics,
    },
}
COMMON_KINDS = ("empty", "binary", "ten-million-lines")


def kinds_of(fmt: str) -> list[str]:
    """The bad kinds that apply to a format, in table order."""
    return [*COMMON_KINDS[:2], *(k for k in WRITERS[fmt] if k != "valid"), COMMON_KINDS[2]]


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


_SMALL_PLAN = ["--ratios", "0.8:0.81:0.01", "--factors", "1.0", "--n-damping", "3"]
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
        "--c2-range", "0:2500:6", "--plot", str(o / "c2.png")], ("c2.png",)),
    Command("control schedule", "--wing", "wing", lambda f, o: [
        "control", "schedule", "--wing", f, "--airspeeds", "0.9:1.1:5", "--relative",
        "--c2-range", "0:2500:6", "--out", str(o / "schedule.json")], ("schedule.json",)),
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
        "train", "plan", "--wing", f, *_SMALL_PLAN, "--out", str(o / "plan.json")],
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
            path = self.root / "_huge" / f"{content}.lines"
            path.parent.mkdir(parents=True, exist_ok=True)
            _huge(path, content)
            self._huge_files[content] = path
        return self._huge_files[content]

    def write(self, fmt: str, kind: str, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        if kind == "empty":
            path.write_bytes(b"")
        elif kind == "binary":
            _binary(path)
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
