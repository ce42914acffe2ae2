"""Physically absurd numbers in every numeric field of every input file and node parameter.

Each trial takes a valid input, puts one value of one hostile class (:data:`CLASSES`: zero,
negative, small, tiny, subnormal, large, huge, NaN, infinite) into one numeric field, and
hands it to what uses it (not only the loader: the command or the node's own start-up path
and the first blocks of its flight), in this process:

- wing file: ``dva wing flutter --wing``, then the simulator's runtime for 3 blocks;
- section file: ``dva wing flutter --section``;
- scenario: the simulator's runtime (``load_runtime_config``, ``FlightRuntime``, 3 blocks);
- airspeed schedule: the airspeed controller's law over airspeeds 0..400 m/s;
- training plan: ``dva train sweep --plan``;
- switching gains: the simulator's runtime with the law armed, 3 blocks;
- RBF network header: the network loaded and its law asked for a command;
- bag metadata.yaml: ``dva bag info`` and the bag player's source;
- node parameters: the table's check (what the node does at start), then, for the
  simulator's flight parameters, its runtime for 3 blocks.

Outcomes: "accepted" (it ran), "refused" (an input error of the project, one line: what
``dva`` and the nodes report with exit code 2), "internal" (any other exception: exit 3 or a
traceback), "timeout" (more than :data:`TRIAL_SECONDS`), "memory" (MemoryError under the
bench's address-space cap). A refusal of more than one line counts as "internal".
Used by bench/bench_input_fuzz.py (``--numbers``) and tests/unit/dva_offline/test_number_fuzz.py.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import signal
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import yaml

from bench.faults import bad_inputs

CLASSES = {"zero": 0.0, "negative": -1.0, "small": 1e-4, "tiny": 1e-300, "subnormal": 5e-324,
           "large": 1e9, "huge": 1e300, "NaN": math.nan, "infinite": math.inf}
TRIAL_SECONDS = 120


@dataclass(frozen=True)
class Trial:
    kind: str
    field: str
    value_class: str
    outcome: str
    message: str


class _Timeout(Exception):
    pass


def _classify(run: Callable[[], None]) -> tuple[str, str]:
    """(outcome, message) of one consumer call (module docstring)."""
    from dva_offline.cli_failures import is_input_error

    def alarm(*_):
        raise _Timeout()

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(TRIAL_SECONDS)
    try:
        run()
        return "accepted", ""
    except _Timeout:
        return "timeout", f"more than {TRIAL_SECONDS} s"
    except MemoryError:
        return "memory", "MemoryError"
    except _Exit as exc:
        return exc.outcome, exc.message
    except Exception as exc:  # noqa: BLE001 - the point is to see what comes out
        text = f"{type(exc).__name__}: {exc}"
        if is_input_error(exc) and "\n" not in str(exc):
            return "refused", text
        return "internal", text
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


class _Exit(Exception):
    """A ``dva`` command's exit code turned into an outcome."""

    def __init__(self, outcome: str, message: str):
        super().__init__(message)
        self.outcome, self.message = outcome, message


def _dva(*argv: str) -> None:
    """Run ``dva argv`` in this process; raise :class:`_Exit` unless it exits 0."""
    from dva_offline.cli import main

    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(list(argv))
    lines = [line for line in err.getvalue().strip().splitlines() if line.strip()]
    last = lines[-1] if lines else ""
    if code == 0:
        return
    if code == 2 and "error:" in last and "Traceback" not in err.getvalue():
        raise _Exit("refused", last)
    raise _Exit("internal", f"exit {code}: {last}")


def _start(build: Callable[[], object]):
    """A node's start-up (its constructor under ``run_node``): a ValueError or OSError of one
    line is its refusal (exit 2); anything else, a traceback."""
    try:
        return build()
    except (ValueError, OSError) as exc:
        text = f"{type(exc).__name__}: {exc}"
        raise _Exit("refused" if "\n" not in str(exc) else "internal", text) from None


def _spin(run: Callable[[], None]) -> None:
    """A node at work (its callbacks while it spins): any exception is a traceback."""
    try:
        run()
    except _Exit:
        raise
    except Exception as exc:  # noqa: BLE001
        raise _Exit("internal", f"{type(exc).__name__} while running: {exc}") from None


def _fly(params: dict, blocks: int = 3, gains: str | None = None, source: str = "fixed"):
    """The simulator node: its start (config, runtime) and its first ``blocks`` blocks."""
    from aero_dva.control.switching_io import with_switching
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    def build():
        config = load_runtime_config(params)
        if gains is not None:
            config = with_switching(config, gains, params.get("wing"))
        return FlightRuntime(config)

    runtime = _start(build)

    def run():
        for _ in range(blocks):
            if runtime.done:
                break
            runtime.command(624.7, source)
            runtime.step()

    _spin(run)
    if gains is not None and runtime.law_problem() is not None:
        # the node says why on /diagnostics and holds the commands' c2: nothing applied
        raise _Exit("refused", runtime.law_problem())


# -- the inputs ----------------------------------------------------------------------------

#: Fields that only record how a file was made (read by no computation), and the format's
#: version (checked for equality).
INFORMATIONAL = ("selection", "description", "version")


def _numeric_leaves(node, trail=()) -> Iterator[tuple]:
    """Paths of the numbers in a YAML/JSON tree (the first element of a list of numbers)."""
    if isinstance(node, dict):
        for key, value in node.items():
            if not trail and key in INFORMATIONAL:
                continue
            yield from _numeric_leaves(value, (*trail, key))
    elif isinstance(node, list):
        if node and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in node):
            yield (*trail, 0)
        else:
            for index, value in enumerate(node):
                yield from _numeric_leaves(value, (*trail, index))
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield trail


def _set(node, trail, value):
    copy = json.loads(json.dumps(node))
    target = copy
    for key in trail[:-1]:
        target = target[key]
    target[trail[-1]] = value
    return copy


def _name(trail) -> str:
    return ".".join(str(k) for k in trail)


def _short_scenario(work: Path) -> str:
    path = work / "short.yaml"
    path.write_text("name: short\nduration: 0.5\nsample_rate: 1000.0\nblock_size: 50\n"
                    "airspeed: {kind: constant, value_ratio: 1.0}\n"
                    "excitation: {force_std: 1000.0, seed: 7}\n")
    return str(path)


def _file_kinds(work: Path) -> dict:
    """kind -> (valid tree, format, consumer(path)) of every input file with numbers."""
    from aero_dva import data_files
    from aero_dva.control.command_laws import RBFLaw, ScheduleLaw
    from aero_dva.control.rbf_io import load_rbf_network
    from aero_dva.control.schedule_io import load_schedule
    from aero_dva.flight.damper import DAMPER_RANGE
    from aero_dva.input_ranges import MAX_AIRSPEED

    short = _short_scenario(work)

    def wing(path):
        _dva("wing", "flutter", "--wing", str(path))
        _fly({"wing": str(path), "scenario": short})

    def schedule(path):
        law = _start(lambda: ScheduleLaw(load_schedule(path), DAMPER_RANGE, True,
                                         MAX_AIRSPEED))

        def run():
            for u in (0.0, 50.0, 100.0, 115.0, 200.0, MAX_AIRSPEED):
                c2 = law.command_for(u)
                if not DAMPER_RANGE[0] <= c2 <= DAMPER_RANGE[1]:
                    raise RuntimeError(f"the schedule commands {c2} N s/m")

        _spin(run)

    def plan(path):
        _dva("train", "sweep", "--plan", str(path), "--out", str(path.with_suffix(".bag")))

    def gains(path):
        _fly({"scenario": short, "damper_time_constant": 0.01}, gains=str(path),
             source="switching")

    bag = work / "metadata_bag"
    from bench.faults.resource_bombs import valid_bag

    valid_bag(bag, blocks=4)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())

    def metadata(path):
        import shutil

        from aero_dva_sim.bag_source import BagSource

        target = path.with_suffix(".bagdir")
        shutil.copytree(bag, target)
        shutil.copy(path, target / "metadata.yaml")
        _dva("bag", "info", str(target))
        source = _start(lambda: BagSource(target))
        _spin(lambda: [None for _ in source.messages(list(source.topics))])

    return {
        "wing file": (bad_inputs._wing_dict(), "yaml", wing),
        "section file": (dict(bad_inputs.SECTION), "yaml",
                         lambda p: _dva("wing", "flutter", "--section", str(p))),
        "scenario": (bad_inputs._scenario_dict(), "yaml",
                     lambda p: _fly({"scenario": str(p)})),
        "airspeed schedule": (bad_inputs._schedule_dict(), "json", schedule),
        "training plan": (bad_inputs._plan_dict(), "json", plan),
        "switching gains": (json.loads(data_files.data_file("switching_gains.json")
                                       .read_text()), "json", gains),
        "bag metadata.yaml": (meta, "yaml", metadata),
        "RBF network header": (None, "npz", lambda p: _spin(lambda: _start(lambda: RBFLaw(
            load_rbf_network(p), DAMPER_RANGE)).command(_spectrum(), 600.0))),
    }


def _spectrum():
    import numpy as np

    return np.full((2, 16), 0.01)


def _network_header(work: Path) -> tuple[dict, Callable[[dict, Path], None]]:
    """The valid network's header and a writer of a network with another header."""
    import numpy as np

    from aero_dva.control.rbf_io import load_rbf_network, save_rbf_network

    path = work / "net.npz"
    bad_inputs._write_network(path)
    with np.load(path, allow_pickle=False) as data:
        header = json.loads(str(data["header"]))
    network = load_rbf_network(path)

    def write(new: dict, target: Path) -> None:
        import zipfile

        save_rbf_network(network, target)
        with zipfile.ZipFile(target) as archive:
            members = {i.filename: archive.read(i) for i in archive.infolist()}
        buffer = io.BytesIO()
        np.save(buffer, np.array(json.dumps(new, allow_nan=True)))
        members["header.npy"] = buffer.getvalue()
        with zipfile.ZipFile(target, "w") as archive:
            for name, data in members.items():
                archive.writestr(name, data)

    return header, write


def file_trials(work: Path, kinds: list[str] | None = None) -> Iterator[Trial]:
    """Every (file kind, numeric field, hostile class) trial (module docstring)."""
    for kind, (valid, fmt, consume) in _file_kinds(work).items():
        if kinds is not None and kind not in kinds:
            continue
        writer = None
        if fmt == "npz":
            valid, writer = _network_header(work)
        for trail in _numeric_leaves(valid):
            for label, value in CLASSES.items():
                tree = _set(valid, trail, value)
                path = Path(tempfile.mkdtemp(dir=work)) / f"input.{fmt}"
                if fmt == "npz":
                    writer(tree, path)
                elif fmt == "yaml":
                    path.write_text(yaml.safe_dump(tree, sort_keys=False))
                else:
                    path.write_text(json.dumps(tree, allow_nan=True))
                outcome, message = _classify(lambda c=consume, p=path: c(p))
                yield Trial(kind, _name(trail), label, outcome, message)


def _node_specs() -> dict:
    """node name -> parameter table of every node: the simulator, recorder, player, spectrum
    node and every controller of the controller table (block-rate laws in the generic
    controller node, per-sample laws' supervisors)."""
    import importlib

    specs = {}
    for node, module in {"simulator": "aero_dva_sim.simulator_node",
                         "mcap_recorder": "aero_dva_sim.mcap_recorder_node",
                         "bag_player": "aero_dva_sim.bag_player_node",
                         "spectrum": "dva_controller.spectrum_node"}.items():
        specs[node] = importlib.import_module(module).SPEC
    from aero_dva.control import controllers as table
    from dva_controller import controller_node, switching_controller_node

    for entry in table.controllers((table.BLOCK,)):
        specs[entry.node] = controller_node.node_spec(entry)
    for entry in table.controllers((table.SAMPLE,)):
        specs[entry.node] = switching_controller_node.node_spec(entry)
    return specs


#: The simulator's parameters that reach its flight (the others time the node itself).
_FLIGHT_PARAMS = ("absorber_mass", "absorber_stiffness", "absorber_series_stiffness",
                  "absorber_position", "damper_min", "damper_max", "damper_initial",
                  "damper_fallback", "damper_timeout", "damper_time_constant")


def parameter_trials(work: Path) -> Iterator[Trial]:
    """Every (node, numeric parameter, hostile class) trial: the table's check, then for the
    simulator's flight parameters its runtime."""
    from dva_ros_common.node_params import check_value

    short = _short_scenario(work)
    for node, spec in _node_specs().items():
        for p in spec.params:
            if p.type_name not in ("int", "float", "double array"):
                continue
            for label, value in CLASSES.items():
                if p.type_name == "int":
                    if not math.isfinite(value) or value != int(value) or abs(value) >= 2**63:
                        continue  # rcl takes 64-bit integers only
                    value = int(value)
                given = [value] + list(p.default[1:]) if p.type_name == "double array" \
                    else value

                def consume(p=p, given=given, node=node):
                    _start(lambda: check_value(p, given))
                    if node == "simulator" and p.name in _FLIGHT_PARAMS:
                        _fly({"scenario": short, p.name: given})

                outcome, message = _classify(consume)
                yield Trial(f"node {node}", p.name, label, outcome, message)


#: Node starts of the issue's cases: (node, description, parameters, scenario YAML or None).
NODE_STARTS = [
    ("simulator", "0-sample scenario", {}, "duration: 0.0\n"),
    ("simulator", "1e-4 s scenario", {}, "duration: 1.0e-4\n"),
    ("simulator", "1 Hz scenario", {}, "sample_rate: 1.0\n"),
    ("simulator", "1e9 Hz scenario", {}, "sample_rate: 1.0e+9\n"),
    ("simulator", "force_std 0", {}, "excitation: {force_std: 0.0, seed: 1}\n"),
    ("simulator", "10-hour scenario", {}, "duration: 36000.0\n"),
    ("simulator", "absorber_position 1e300", {"absorber_position": "1.0e300"}, None),
    ("simulator", "absorber_mass 1e-300", {"absorber_mass": "1.0e-300"}, None),
    ("simulator", "damper_max 1e300", {"damper_max": "1.0e300"}, None),
    ("simulator", "damper_timeout 0", {"damper_timeout": "0.0"}, None),
    ("mcap_recorder", "topic with a space", {"topics": '["bad topic"]'}, None),
    ("mcap_recorder", "topic with escape codes", {"topics": '["a\x1b[31mred"]'}, None),
    ("mcap_recorder", "topic of 10,000 characters", {"topics": '["' + "x" * 10_000 + '"]'},
     None),
    ("mcap_recorder", "excluded topic starting with a digit", {"exclude": '["9lives"]'}, None),
]


def node_start_trials(work: Path, timeout: float = 60.0) -> Iterator[Trial]:
    """Each :data:`NODE_STARTS` case as ``ros2 run`` starts the node (a process; needs the
    ROS environment): refused = exit 2 with one ``<node>: error:`` line and no traceback."""
    import os
    import subprocess

    from aero_dva_sim.run_flight import executable

    package = {"simulator": "aero_dva_sim", "mcap_recorder": "aero_dva_sim"}
    for node, what, params, scenario in NODE_STARTS:
        args = [f"{k}:={v}" for k, v in params.items()]
        case = Path(tempfile.mkdtemp(dir=work))
        if node == "simulator":
            text = ("name: hostile\nduration: 1.0\nsample_rate: 1000.0\nblock_size: 50\n"
                    "airspeed: {kind: constant, value_ratio: 0.9}\n")
            if scenario is not None:
                key = scenario.split(":")[0]
                text = "\n".join(line for line in text.splitlines()
                                 if not line.startswith(key + ":")) + "\n" + scenario
            (case / "s.yaml").write_text(text)
            args += [f"scenario:={case / 's.yaml'}", "real_time_factor:=0.0"]
        else:
            args += [f"output:={case / 'bag'}"]
        argv = [executable(package[node], node), "--ros-args"]
        for arg in args:
            argv += ["-p", arg]
        env = dict(os.environ, ROS_DOMAIN_ID=os.environ.get("ROS_DOMAIN_ID", "0"))
        try:
            result = subprocess.run(argv, capture_output=True, text=True, timeout=timeout,
                                    env=env)
        except subprocess.TimeoutExpired:
            yield Trial(f"node {node} (process)", what, "start", "timeout", "")
            continue
        err = [line for line in result.stderr.strip().splitlines() if line.strip()]
        last = err[-1] if err else ""
        if result.returncode == 2 and last.startswith(f"{node}: error:") \
                and "Traceback" not in result.stderr:
            outcome = "refused"
        elif result.returncode == 0:
            outcome = "accepted"
        else:
            outcome = "internal"
        yield Trial(f"node {node} (process)", what, "start", outcome,
                    f"exit {result.returncode}: {last[:300]}")
