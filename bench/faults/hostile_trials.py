"""The hostile trials of issue 45, generated afresh: every input class as a process, as a user
would run it, with its exit code, its last line and its peak resident memory.

Classes (:data:`CLASSES`), each drawn from a seeded generator:

- ``c2``: a c2 outside the damper's range (1e12, 1e300, 2500.001, -1, -5e-324, inf, NaN, ...)
  in a switching gains file, a training plan (a dwell's c2, the plan's range), an airspeed
  schedule, and through the design and run options (``dva switching design --c-hi``, ``dva
  control schedule --damping-range``, ``dva evaluate --fixed-c2``);
- ``zip bomb``: a bag whose one chunk expands to 1-4 GiB (zstd, declaring its size or not,
  with and without the frame's content size; lz4), read by ``dva bag info``, ``dva bag
  recover`` and ``dva replay --offline``;
- ``listed``: a bag whose file ``metadata.yaml`` lists 2-2000 times, by the same readers;
- ``long``: scenarios of 2e4 s to 1e7 s (``dva evaluate --scenario``) and plans with windows
  of 100 s to 1e6 s (``dva train sweep --plan``);
- ``numbers``: one numeric field of a wing file (``dva wing flutter``) or a scenario (``dva
  evaluate``) set to a value of the number fuzz's classes (zero ... NaN);
- ``interrupt``: SIGTERM or SIGINT at a random moment to ``dva evaluate``, ``dva train
  sweep`` and ``dva bag recover``; what is left is checked: a complete result, or nothing
  that looks complete (no ``results.json``; a bag marked interrupted that ``dva train rbf``
  refuses; no ``.partial`` folder and no copy);
- ``names``: file names and scenario names with escape codes, newlines and up to 4000
  characters, in missing wing and bag paths, a scenario (its file and its ``name:``) with a
  field out of range, a plan whose wing path is hostile and missing;
- ``commander`` (ROS): ``run_flight`` with a second node on ``dva/damper_command`` (the
  controller's source or another, valid or absurd c2, strict or not), stamps a year ahead,
  sources of 1-10 MB with escape codes, a scenario named with escape codes and newlines; the
  applied c2 read back from the bag, the simulator's log size, control characters in the output.

A trial passes (:attr:`Trial.ok`) when it ends as documented: exit 2 with one line for bad
input (a reader that reports damage instead: exit 0 with the damage said, ``recover`` 1),
130 with "interrupted" for a signal, 1 for a flight with a second commander; no output keeps a
raw control character; and its own check holds (below). Peak memory is the process's
``ru_maxrss`` (os.wait4), under an address-space cap of :data:`CAP` (a reader that reached
it would fail its trial).
"""
from __future__ import annotations

import json
import math
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from aero_dva.flight.flight_limits import DAMPER_RANGE, MAX_WINDOW_SAMPLES
from bench.faults import bad_inputs
from bench.faults import resource_bombs as rb

CAP = 3 * 2**30  # [bytes] address space of each trial's process
GIB = 2**30
# control characters but tab, newline and the progress bars' carriage return
CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
HOSTILE_C2 = (1e12, 1e300, DAMPER_RANGE[1] + 0.001, DAMPER_RANGE[1] + 1.0, 1e4, -1.0, -5e-324,
              math.inf, -math.inf, math.nan)
CLASSES = ("c2", "zip bomb", "listed", "long", "numbers", "interrupt", "commander", "names")


@dataclass
class Trial:
    cls: str
    name: str
    code: int | None = None
    expected: tuple = (2,)
    last: str = ""
    lines: int = 0
    peak: int = 0  # [bytes] ru_maxrss of the process
    check: str = ""  # why the trial's own check failed ("" when it held)
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.code in self.expected and not self.check


def _limit():
    resource.setrlimit(resource.RLIMIT_AS, (CAP, CAP))


def run(argv: list, timeout: float = 600.0, cap: bool = True, env: dict | None = None,
        signal_after: tuple | None = None) -> tuple[int | None, str, str, int]:
    """(exit code, stdout, stderr, peak RSS bytes) of ``argv`` (exit code None: killed at
    ``timeout``); ``signal_after``: (signal, seconds, condition or None) sends the signal that
    many seconds after the condition first holds (after the start without one)."""
    env = dict(os.environ if env is None else env, OPENBLAS_NUM_THREADS="1",
               PYTHONUNBUFFERED="1")
    env.pop("DVA_DEBUG", None)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        process = subprocess.Popen([str(a) for a in argv], stdout=out, stderr=err, env=env,
                                   preexec_fn=_limit if cap else None)
        started = time.monotonic()
        armed = None if signal_after is None or signal_after[2] is not None else started
        sent, timed_out = False, False
        while True:
            pid, status, rusage = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            now = time.monotonic()
            if signal_after is not None and not sent:
                if armed is None and signal_after[2]():
                    armed = now
                if armed is not None and now - armed >= signal_after[1]:
                    process.send_signal(signal_after[0])
                    sent = True
            if now - started > timeout:
                process.kill()
                pid, status, rusage = os.wait4(process.pid, 0)
                timed_out = True
                break
            time.sleep(0.02)
        process.returncode = os.waitstatus_to_exitcode(status)  # reaped: Popen must know
        out.seek(0)
        err.seek(0)
        return (None if timed_out else process.returncode,
                out.read().decode(errors="replace"), err.read().decode(errors="replace"),
                rusage.ru_maxrss * 1024)


def dva(*args) -> list[str]:
    return [sys.executable, "-m", "dva_offline.cli", *map(str, args)]


def _finish(trial: Trial, result, extra_check: str = "") -> Trial:
    code, out, err, peak = result
    lines = err.strip().splitlines()
    trial.code, trial.peak = code, peak
    trial.last = lines[-1] if lines else ""
    trial.lines = len([line for line in lines if "error" in line])
    checks = [extra_check] if extra_check else []
    if CONTROL.search(out + err):
        bad = sorted({repr(c) for c in CONTROL.findall(out + err)})
        checks.append(f"raw control characters in the output ({', '.join(bad)})")
    said = [line for line in lines if line.strip() and "%|" not in line]  # no progress bars
    if code == 2 and (len(said) != 1 or "error" not in said[0]):
        checks.append(f"not one error line ({len(said)} lines)")
    trial.check = "; ".join(checks)
    return trial


# ------------------------------------------------------------------ c2 outside the range
def c2_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    from aero_dva import data_files

    gains = json.loads(Path(data_files.data_file("switching_gains.json")).read_text())
    plan = bad_inputs._plan_dict()
    schedule = bad_inputs._schedule_dict()
    routes = ("gains c_hi", "gains c_lo", "plan dwell c2", "plan range", "schedule max",
              "design --c-hi", "schedule --damping-range", "evaluate --fixed-c2",
              "replay schedule file")
    for i in range(n):
        route = routes[i % len(routes)]
        value = HOSTILE_C2[int(rng.integers(len(HOSTILE_C2)))]
        where = work / f"c2_{i}"
        where.mkdir()
        out = where / "out"
        trial = Trial("c2", f"{route} = {value!r}")
        if route.startswith("gains"):
            key = route.split()[1]
            (where / "gains.json").write_text(json.dumps({**gains, key: value}))
            argv = dva("evaluate", "--controllers", "switching", "--gains", where / "gains.json",
                       "--cases", "rho0", "--seeds", "1", "--no-boundaries", "--out", out)
        elif route.startswith("plan"):
            p = json.loads(json.dumps(plan))
            if route == "plan dwell c2":
                p["dwells"]["damping"][int(rng.integers(len(p["dwells"]["damping"])))] = value
            else:
                _set_key(p, "damping_range", [0.0, value])
            (where / "plan.json").write_text(json.dumps(p))
            argv = dva("train", "sweep", "--plan", where / "plan.json", "--out", out)
        elif route == "schedule max" or route == "replay schedule file":
            s = dict(schedule)
            _set_key(s, "damping_max", value)
            (where / "schedule.json").write_text(json.dumps(s))
            argv = dva("evaluate", "--controllers", "schedule", "--schedule",
                       where / "schedule.json", "--cases", "rho0", "--seeds", "1",
                       "--no-boundaries", "--out", out) if route == "schedule max" else dva(
                "replay", _valid_bag(work), "--offline", "--controller", "schedule",
                "--schedule", where / "schedule.json", "--out", out)
        elif route == "design --c-hi":
            argv = dva("switching", "design", f"--c-hi={value}", "--out", out)
        elif route == "schedule --damping-range":
            argv = dva("control", "schedule", "--damping-range", f"0:{value}", "--out", out)
        else:
            argv = dva("evaluate", "--controllers", "fixed", f"--fixed-c2={value}", "--cases",
                       "rho0", "--seeds", "1", "--no-boundaries", "--out", out)
        result = run(argv, timeout=300)
        yield _finish(trial, result, "an output was written" if out.exists() else "")


def _set_key(tree, key, value) -> bool:
    """Set ``key`` wherever it is in a nested dict (the first place found)."""
    if isinstance(tree, dict):
        if key in tree:
            tree[key] = value
            return True
        return any(_set_key(v, key, value) for v in tree.values())
    if isinstance(tree, list):
        return any(_set_key(v, key, value) for v in tree)
    return False


_VALID = {}


def _valid_bag(work: Path) -> Path:
    if "bag" not in _VALID:
        _VALID["bag"] = rb.valid_bag(work / "valid_bag")
    return _VALID["bag"]


# ------------------------------------------------------------------ bags
READERS = ("bag info", "bag recover", "replay --offline")


def _read(reader: str, bag: Path, out: Path) -> list[str]:
    if reader == "bag info":
        return dva("bag", "info", bag)
    if reader == "bag recover":
        return dva("bag", "recover", bag, "--out", out)
    return dva("replay", bag, "--offline", "--controller", "fixed", "--damping", "600",
               "--out", out)


def bomb_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    for i in range(n):
        reader = READERS[i % len(READERS)]
        kind = ("zstd", "zstd lie", "zstd no size", "lz4")[int(rng.integers(4))]
        expanded = int(rng.uniform(1.0, 4.0) * GIB) if kind != "lz4" else int(
            rng.uniform(0.25, 1.0) * GIB)
        bag = work / f"bomb_{i}"
        if kind == "lz4":
            rb.lz4_bomb_bag(bag, expanded)
        else:
            rb.bomb_bag(bag, expanded, declared=None if kind == "zstd" else 2**20,
                        content_size=kind != "zstd no size")
        trial = Trial("zip bomb", f"{kind} {expanded / GIB:.2f} GiB, {reader}",
                      # recover: 1, "copied, messages lost" (docs/bags.md)
                      expected={"bag info": (0,), "bag recover": (1,),
                                "replay --offline": (2,)}[reader])
        result = run(_read(reader, bag, work / f"bomb_{i}_out"), timeout=300)
        said = ("chunk" in result[1] + result[2]) or reader == "replay --offline"
        yield _finish(trial, result, "" if said else "the damaged chunk not said")
        shutil.rmtree(bag, ignore_errors=True)
        shutil.rmtree(work / f"bomb_{i}_out", ignore_errors=True)


def listed_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    counts = (2, 3, 7, 50, 500, 2000)
    for i in range(n):
        reader = READERS[i % len(READERS)]
        times = counts[int(rng.integers(len(counts)))]
        bag = rb.listed_bag(work / f"listed_{i}", times)
        out = work / f"listed_{i}_out"
        trial = Trial("listed", f"listed {times} times, {reader}")
        result = run(_read(reader, bag, out), timeout=300)
        yield _finish(trial, result, "" if "times" in result[2] and not out.exists() else
                      "not refused as listed twice, or an output written")
        shutil.rmtree(bag, ignore_errors=True)


# ------------------------------------------------------------------ long flights
def long_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    plan = bad_inputs._plan_dict()
    for i in range(n):
        where = work / f"long_{i}"
        where.mkdir()
        out = where / "out"
        if i % 2 == 0:
            duration = float(10 ** rng.uniform(math.log10(2.1e4), 7))
            rate = float(rng.choice([1000.0, 5000.0, 20000.0]))
            scenario = {**bad_inputs._scenario_dict(), "duration": duration,
                        "sample_rate": rate}
            (where / "s.yaml").write_text(yaml.safe_dump(scenario))
            trial = Trial("long", f"scenario {duration:.3g} s at {rate:g} Hz, dva evaluate")
            argv = dva("evaluate", "--controllers", "fixed", "--fixed-c2", "600", "--cases",
                       "rho0", "--seeds", "2", "--no-boundaries", "--scenario",
                       where / "s.yaml", "--out", out)
        else:
            window = float(10 ** rng.uniform(2, 6))  # [s]: 1e5 to 1e9 samples at 1 kHz
            p = json.loads(json.dumps(plan))
            p["settings"]["window"] = window
            (where / "plan.json").write_text(json.dumps(p))
            trial = Trial("long", f"plan window {window:.3g} s, dva train sweep")
            if window * p["settings"]["sample_rate"] <= MAX_WINDOW_SAMPLES:
                trial.expected = (0, 2)  # within the stated limit: a plan that may fly
            argv = dva("train", "sweep", "--plan", where / "plan.json", "--out", out)
        result = run(argv, timeout=300)
        left = out.exists() and result[0] != 0
        yield _finish(trial, result, "an output was written" if left else "")


# ------------------------------------------------------------------ absurd numbers
def number_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    from bench.faults import number_fuzz

    wing = bad_inputs._wing_dict()
    scenario = bad_inputs._scenario_dict()
    wing_leaves = list(number_fuzz._numeric_leaves(wing))
    scenario_leaves = list(number_fuzz._numeric_leaves(scenario))
    labels = list(number_fuzz.CLASSES)
    for i in range(n):
        label = labels[int(rng.integers(len(labels)))]
        value = number_fuzz.CLASSES[label]
        where = work / f"number_{i}"
        where.mkdir()
        if i % 2 == 0:
            trail = wing_leaves[int(rng.integers(len(wing_leaves)))]
            (where / "w.yaml").write_text(yaml.safe_dump(number_fuzz._set(wing, trail, value)))
            trial = Trial("numbers", f"wing {number_fuzz._name(trail)} = {label}",
                          expected=(0, 2))
            argv = dva("wing", "flutter", "--wing", where / "w.yaml")
        else:
            trail = scenario_leaves[int(rng.integers(len(scenario_leaves)))]
            (where / "s.yaml").write_text(yaml.safe_dump(number_fuzz._set(scenario, trail,
                                                                          value)))
            trial = Trial("numbers", f"scenario {number_fuzz._name(trail)} = {label}",
                          expected=(0, 1, 2))
            argv = dva("evaluate", "--controllers", "fixed", "--fixed-c2", "600", "--cases",
                       "rho0", "--seeds", "2", "--no-boundaries", "--scenario",
                       where / "s.yaml", "--out", where / "out")
        yield _finish(trial, run(argv, timeout=600))


# ------------------------------------------------------------------ interrupts
def _recover_source(work: Path) -> Path:
    if "big" not in _VALID:
        _VALID["big"] = rb.valid_bag(work / "big_bag", blocks=20000)
    return _VALID["big"]


def interrupt_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    commands = ("evaluate", "train sweep", "bag recover")
    for i in range(n):
        command = commands[i % 3]
        sig = (signal.SIGTERM, signal.SIGINT)[(i // 3) % 2]
        where = work / f"int_{i}"
        where.mkdir()
        out = where / "out"
        # evaluate: after its inputs are made (before, during or after its first flights);
        # sweep: after its recording has begun (the plan is in the bag); recover: from the
        # start, the first tenth of a second included
        delay = float(rng.uniform(0.0, {"evaluate": 20.0, "train sweep": 8.0,
                                        "bag recover": 1.5}[command]))
        if command == "evaluate":
            argv = dva("evaluate", "--controllers", "fixed,schedule", "--cases", "rho0",
                       "--seeds", "2", "--out", out)
            ready = (out / "inputs").is_dir
        elif command == "train sweep":
            argv = dva("train", "sweep", "--out", out)  # the default plan: minutes
            ready = (out / "training_plan.json").is_file
        else:
            argv = dva("bag", "recover", _recover_source(work), "--out", out)
            ready = None
        trial = Trial("interrupt", f"{sig.name} {delay:.2f} s into dva {command}",
                      expected=(130, 0))
        result = run(argv, timeout=900, signal_after=(sig, delay, ready))
        trial = _finish(trial, result, _left(command, out, where, result[0]))
        if result[0] == 130 and "interrupted" not in trial.last:
            trial.check = (trial.check + "; " if trial.check else "") + "no 'interrupted'"
        trial.extra["left"] = _describe_left(out)
        yield trial
        shutil.rmtree(where, ignore_errors=True)


def _describe_left(out: Path) -> str:
    if not out.exists():
        return "nothing"
    names = sorted(p.name for p in out.iterdir())
    return ", ".join(names[:4]) + (" ..." if len(names) > 4 else "")


def _left(command: str, out: Path, where: Path, code: int | None) -> str:
    """"" when what the command left is a complete result or nothing that looks complete."""
    hidden = [p.name for p in where.iterdir() if p.name.startswith(".")]
    if hidden:
        return f"hidden folders left: {hidden}"
    if not out.exists():
        return ""
    if command == "evaluate":
        if (out / "results.json").exists() and code != 0:
            return "results.json after an interrupt"
        return ""
    if command == "train sweep":
        info = run(dva("bag", "info", "--json", out), timeout=300)
        if code == 0:
            return "" if info[0] == 0 else "a finished sweep that bag info cannot read"
        if "interrupted" not in info[1]:
            return "a cut sweep not marked interrupted"
        rbf = run(dva("train", "rbf", out, "--out", out.parent / "net.npz"), timeout=300)
        if rbf[0] != 2 or (out.parent / "net.npz").exists():
            return f"dva train rbf on the cut sweep: exit {rbf[0]}"
        return ""
    # bag recover: a copy exists only when complete
    if code != 0:
        return f"a copy left after exit {code}"
    return ""


# ------------------------------------------------------------------ commanders (ROS)
INTRUDER = """\
import sys, rclpy
from rclpy.node import Node
from builtin_interfaces.msg import Time
from dva_msgs.msg import DamperCommand
name, source_kind, damping, ahead = sys.argv[1], sys.argv[2], float(sys.argv[3]), \
    float(sys.argv[4])
source = {"huge": "\\x1b[31m\\n" + "x" * 10_000_000, "fixed": "fixed",
          "other": "intruder"}[source_kind]
rclpy.init()
node = Node(name)
pub = node.create_publisher(DamperCommand, "dva/damper_command", 10)
def send():
    msg = DamperCommand(damping=damping, source=source)
    t = ahead
    msg.header.stamp = Time(sec=int(t), nanosec=0)
    pub.publish(msg)
node.create_timer(0.05, send)
print("ready", flush=True)
try:
    rclpy.spin(node)
except BaseException:
    pass
"""

#: (name, intruder source, its c2, stamp [s], strict, expected exit codes)
COMMANDER_CASES = (
    ("second commander, controller's source, valid c2", "fixed", 2499.0, 0.0, True, (1, 3)),
    ("second commander, controller's source, c2 0", "fixed", 0.0, 0.0, True, (1, 3)),
    ("second commander, other source", "other", 2499.0, 0.0, True, (1, 3)),
    ("second commander, c2 1e12", "fixed", 1e12, 0.0, True, (1, 3)),
    ("second commander, not strict", "fixed", 2499.0, 0.0, False, (1,)),
    ("stamps a year ahead, not strict", "fixed", 2499.0, 3.2e7, False, (1,)),
    ("source of 10 MB with escape codes, not strict", "huge", 2499.0, 0.0, False, (1,)),
    ("source of 10 MB with escape codes", "huge", 2499.0, 0.0, True, (1, 3)),
)


def commander_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    from aero_dva.bag.reader import bag_topics, read_messages

    scenario = {**bad_inputs._scenario_dict("scenario_constant.yaml"), "duration": 6.0}
    cases = list(COMMANDER_CASES) + [("scenario named with escape codes", None, 0, 0, True,
                                      (0,))]
    for i in range(n):
        name, source, damping, ahead, strict, expected = cases[i % len(cases)]
        where = work / f"cmd_{i}"
        where.mkdir()
        s = dict(scenario)
        if source is None:
            s["name"] = "\x1b[31mred\x1b[0m\nINJECTED LINE\r" + "y" * 5000
        (where / "s.yaml").write_text(yaml.safe_dump(s))
        domain = 100 + int(rng.integers(0, 100))
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
        intruder = None
        if source is not None:
            intruder = subprocess.Popen(
                [sys.executable, "-c", INTRUDER, f"intruder_{i}", source, str(damping),
                 str(ahead)], env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                text=True)
            # publishing before the flight starts: a loaded machine takes seconds to start it
            if intruder.stdout.readline().strip() != "ready":
                raise RuntimeError(f"the intruder did not start ({intruder.wait()})")
        bag = where / "bag"
        argv = [sys.executable, "-m", "aero_dva_sim.run_flight", "--scenario",
                where / "s.yaml", "--controller", "fixed", "--real-time-factor", "2",
                "--domain-id", str(domain), "--output", bag, "--json",
                *([] if strict else ["--no-strict-commands"])]
        trial = Trial("commander", name, expected=expected)
        try:
            result = run([str(a) for a in argv], timeout=600, cap=False)
        finally:
            if intruder is not None:
                intruder.send_signal(signal.SIGINT)
                try:
                    intruder.wait(20)
                except subprocess.TimeoutExpired:
                    intruder.kill()
                    intruder.wait()
        checks = []
        try:
            recorded = bag.exists() and "/dva/damper_state" in bag_topics(bag)
            # none when the flight stopped before the recorder kept a state
            applied = [m.message.applied_damping for m in read_messages(
                bag, ["/dva/damper_state"], allow_truncated=True)] if recorded else []
        except Exception as exc:  # noqa: BLE001 - said in the trial's check
            applied = []
            checks.append(f"bag unreadable: {str(exc)[:160]}")
        bag_bytes = sum(p.stat().st_size for p in bag.iterdir()) if bag.exists() else 0
        logs = bag.with_name("bag_logs")
        log_bytes = sum(p.stat().st_size for p in logs.glob("*.log")) if logs.exists() else 0
        log_text = "".join(p.read_text(errors="replace") for p in logs.glob("*.log")) \
            if logs.exists() else ""
        if any(not (DAMPER_RANGE[0] <= c <= DAMPER_RANGE[1]) for c in applied):
            checks.append(f"c2 outside the range applied ({max(applied):.3g})")
        if strict and damping in applied and source is not None and damping != 0.0:
            checks.append("the intruder's c2 applied under strict commands")
        if log_bytes > 2**20:
            checks.append(f"node logs of {log_bytes:,} bytes")
        if "\x1b" in log_text or "INJECTED LINE" in log_text.replace("\\nINJECTED", ""):
            checks.append("raw control characters in the node logs")
        summary = _json(result[1])
        if summary is not None and (summary.get("command_latency_median") or 0) < 0:
            checks.append(f"latency {summary['command_latency_median']}")
        if result[0] in (1, 3) and "commander" not in result[2].strip().splitlines()[-1]:
            checks.append("the last line does not say the commander")
        trial = _finish(trial, result, "; ".join(checks))
        trial.extra.update(c2_min=min(applied, default=None), c2_max=max(applied, default=None),
                           states=len(applied), log_bytes=log_bytes, bag_bytes=bag_bytes,
                           latency=None if summary is None else
                           summary.get("command_latency_median"),
                           foreign=None if summary is None else summary.get("commands_foreign"))
        yield trial
        shutil.rmtree(where, ignore_errors=True)


def _json(text: str):
    try:
        return json.loads(text)
    except ValueError:
        return None


# ------------------------------------------------------------------ outside text in names
def _hostile_name(rng: np.random.Generator) -> str:
    parts = ["\x1b[31m", "\x1b[2J", "\n", "\r", "\x07", "\t", "INJECTED ", "é✈", "x" * 40]
    name = "".join(parts[int(k)] for k in rng.integers(len(parts), size=int(rng.integers(2, 8))))
    return name + "y" * int(10 ** rng.uniform(0, 3.6)) + ".yaml"


def name_trials(work: Path, rng: np.random.Generator, n: int) -> Iterator[Trial]:
    """File and scenario names with escape codes, newlines and thousands of characters: the
    file missing, a directory, or a scenario file (its name and ``name:`` field hostile) with
    one field out of range; every error one line, escaped and cut."""
    scenario = bad_inputs._scenario_dict()
    for i in range(n):
        name = _hostile_name(rng)
        where = work / f"name_{i}"
        where.mkdir()
        how = ("missing wing", "missing bag", "scenario", "plan")[i % 4]
        if how == "missing wing":
            argv = dva("wing", "flutter", "--wing", where / name)
        elif how == "missing bag":
            argv = dva("bag", "info", where / name)
        else:
            # a real file: its name within the file system's 255 bytes
            short = name.encode()[:200].decode(errors="ignore").replace("/", "_") or "s"
            path = where / short
            try:
                if how == "scenario":
                    path.write_text(yaml.safe_dump({**scenario, "name": name,
                                                    "duration": -1.0}))
                    argv = dva("evaluate", "--controllers", "fixed", "--fixed-c2", "600",
                               "--cases", "rho0", "--seeds", "1", "--no-boundaries",
                               "--scenario", path, "--out", where / "out")
                else:
                    plan = bad_inputs._plan_dict()
                    plan["wing"] = str(where / name)  # missing: refused, never a default
                    path.write_text(json.dumps(plan))
                    argv = dva("train", "sweep", "--plan", path, "--out", where / "out")
            except OSError:  # a name the file system refuses: the trial is a missing file
                argv = dva("wing", "flutter", "--wing", where / name)
        trial = Trial("names", f"{how}: {len(name)} characters, {name[:20]!r}")
        result = run(argv, timeout=300)
        long_line = len(result[2].strip().splitlines()[-1]) > 1200 if result[2].strip() else 0
        yield _finish(trial, result, "an error line over 1200 characters" if long_line else "")


GENERATORS = {"c2": c2_trials, "zip bomb": bomb_trials, "listed": listed_trials,
              "long": long_trials, "numbers": number_trials, "interrupt": interrupt_trials,
              "commander": commander_trials, "names": name_trials}
