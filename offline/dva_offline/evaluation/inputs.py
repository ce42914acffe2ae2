"""What an evaluation needs and was not given: the schedule, the best fixed c2, the network.

  schedule   ``dva control schedule`` (exact stationary RMS, eq. 7.1 fit)
  fixed c2   the constant c2 with the highest flutter airspeed (eigenvalues, base density)
  network    ``dva train rbf`` on --sweep-bag, or on the default training sweep recorded
             first by ``dva train sweep``

Made by the project's own commands (as a user would run them) into ``DIR/inputs`` and reused
by a later run with the same ``--out``.
"""
from __future__ import annotations

import contextlib
import json
import math
import shutil
import subprocess
import sys
import time
from pathlib import Path

from aero_dva.atomic_io import unique_directory

__all__ = ["best_fixed_damping_of", "check_given_inputs", "evaluation_directory", "inputs",
           "log", "resumable_or_removed", "saved_flights"]


def _run(argv: list[str], what: str, timeout: float = 3600.0) -> str:
    """Run a helper command; its stdout, or ValueError with its last error line."""
    result = subprocess.run(argv, capture_output=True, text=True, timeout=timeout)
    if result.returncode != 0:
        lines = (result.stderr or result.stdout).strip().splitlines()
        raise ValueError(f"{what} failed ({result.returncode}): "
                         f"{lines[-1] if lines else 'no output'}")
    return result.stdout


def _dva(*args: str) -> list[str]:
    return [sys.executable, "-m", "dva_offline.cli", *args]


def log(text: str) -> None:
    """A line of ``dva evaluate`` on stderr that keeps its progress bar intact."""
    from tqdm import tqdm

    tqdm.write(f"dva evaluate: {text}", file=sys.stderr)


def evaluation_directory(args, controllers) -> tuple[Path, dict, dict, bool]:
    """The evaluation's directory (``--out``, default ``runs/evaluation_<UTC time>``), the
    inputs given or made into its ``inputs/`` (paths), the given ones as read at the door
    (``{"schedule": ..., "network": ...}``, so nobody reads them again), and whether this run
    created the directory; a directory created here is removed again when making the inputs
    fails, so nothing is left that looks like an evaluation."""
    given = check_given_inputs(args, controllers)
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    if args.out:  # a given directory resumes (held by this run alone: cli_tools.outputs_held)
        out = Path(args.out).resolve()
        created = not out.exists()
        out.mkdir(parents=True, exist_ok=True)
    else:  # a default name another run took in the same second moves on to <name>_2, ...
        out = unique_directory(Path(f"runs/evaluation_{stamp}").resolve(), "evaluation")
        created = True
    try:
        return out, inputs(args, controllers, out / "inputs", log), given, created
    except BaseException:
        if created:
            shutil.rmtree(out, ignore_errors=True)
        raise


def saved_flights(out: Path) -> int:
    """Flight records an evaluation has saved in ``out/flights`` (what a resume starts from)."""
    folder = out / "flights"
    return sum(1 for p in folder.glob("*.json") if p.name != "settings.json") \
        if folder.is_dir() else 0


@contextlib.contextmanager
def resumable_or_removed(out: Path, created: bool):
    """Around an evaluation's flights and results: when they fail or are interrupted, the
    directory this run created is removed if it saved no flight (its ``inputs/`` alone is
    not a result); otherwise it is kept, holding flight records and no results, and the
    line before the error says how to resume. Nothing left looks like a finished
    evaluation: results.json is written last."""
    try:
        yield
    except BaseException:
        saved = saved_flights(out)
        if created and saved == 0:
            shutil.rmtree(out, ignore_errors=True)
        elif saved:
            log(f"{saved} flight record(s) kept in {out / 'flights'} (no results written); "
                f"the same command with --out {out} resumes")
        raise


def needed_options(controllers) -> set[str]:
    """The options of the chosen controllers' table entries (what their laws are made from:
    ``schedule``, ``network``, ``damping``, ...)."""
    from aero_dva.control.controllers import NONE, controller

    return {o.name for name in controllers if name != NONE for o in controller(name).options}


def inputs(args, controllers, inputs: Path, log) -> dict:
    """Schedule, fixed c2 and network for the chosen controllers' options (given or made)."""
    made: dict = {}
    inputs.mkdir(parents=True, exist_ok=True)
    needed = needed_options(controllers)
    if "schedule" in needed:
        if args.schedule:
            made["schedule"] = str(Path(args.schedule).resolve())
        else:
            path = inputs / "schedule.json"
            if not path.is_file():
                log("making the airspeed schedule (dva control schedule)")
                _run(_dva("control", "schedule", "--out", str(path), "--plot",
                          str(inputs / "schedule.png"), "--json"), "dva control schedule")
            made["schedule"] = str(path)
        if not Path(made["schedule"]).is_file():
            raise FileNotFoundError(f"--schedule: no file {made['schedule']}")
    if "damping" in needed:
        if args.fixed_c2 is not None:
            from aero_dva.flight.damper import check_damping

            check_damping(args.fixed_c2, "--fixed-c2")
            made["fixed_c2"] = {"damping": args.fixed_c2, "source": "--fixed-c2"}
        else:
            path = inputs / "fixed_c2.json"
            if not path.is_file():
                log("choosing the fixed c2 (highest flutter airspeed)")
                _save(path, best_fixed_damping_of(None))
            made["fixed_c2"] = json.loads(path.read_text())
    if "network" in needed:
        if args.network:
            made["network"] = str(Path(args.network).resolve())
            if not Path(made["network"]).is_file():
                raise FileNotFoundError(f"--network: no file {made['network']}")
        else:
            path = inputs / "rbf.npz"
            if not path.is_file():
                bag = Path(args.sweep_bag) if args.sweep_bag else inputs / "train_sweep"
                if not args.sweep_bag and not (bag / "metadata.yaml").is_file():
                    shutil.rmtree(bag, ignore_errors=True)  # an interrupted recording
                    log("recording the training sweep (dva train sweep, several minutes)")
                    _run(_dva("train", "sweep", "--out", str(bag), "--json"), "dva train sweep")
                log(f"training the RBF network from {bag} (dva train rbf)")
                _run(_dva("train", "rbf", str(bag), "--out", str(path), "--plot",
                          str(inputs / "rbf_fig7_11.png"), "--json"), "dva train rbf")
            made["network"] = str(path)
    return made


def _save(path, payload):
    from dva_offline.evaluation.graph_io import save_json

    return save_json(path, payload)


def check_given_inputs(args, controllers) -> dict:
    """Read the input files the user gave, once, before anything is made or flown: a bad one
    ends the run here with the file named, instead of failing (or, for a controller that
    cannot start, flying on the damper's fallback) in every flight. Returns what was read."""
    from aero_dva.bag.reader import bag_topics
    from aero_dva.control.rbf_io import load_rbf_network
    from aero_dva.control.rbf_network import SPECTRUM_INPUT_DIM
    from aero_dva.control.schedule_io import load_schedule

    given = {}
    needed = needed_options(controllers)
    if "schedule" in needed and args.schedule:
        given["schedule"] = load_schedule(args.schedule)
    if "network" in needed and args.network:
        given["network"] = load_rbf_network(args.network, expected_input_dim=SPECTRUM_INPUT_DIM)
    elif "network" in needed and args.sweep_bag:
        bag_topics(args.sweep_bag)
    return given


def best_fixed_damping_of(wing) -> dict:
    """The best constant c2 (:func:`aero_dva.control.dva_design.best_fixed_damping`: the c2 in
    the damper's range with the highest flutter airspeed) of ``wing`` (a file; None: the
    default wing) with its Maxwell DVA, at the file's density. A c2 with no flutter found up to
    1e5 m/s has no flutter airspeed or frequency to write (null)."""

    from aero_dva.control.dva_design import best_fixed_damping
    from aero_dva.flight.damper import DAMPER_RANGE
    from aero_dva.wing.flutter import bare_critical_airspeed, flutter_speed
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import load_wing

    cfg = load_wing(wing)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    rho = cfg.air_density
    choice = best_fixed_damping(model, rho)
    u_cr = bare_critical_airspeed(cfg.wing, rho, cfg.aero)
    finite = math.isfinite(choice.critical_airspeed)
    return {"damping": choice.damping,
            "critical_airspeed": choice.critical_airspeed if finite else None,
            "critical_ratio": choice.critical_airspeed / u_cr if finite else None,
            "density": rho,
            "flutter_frequency": flutter_speed(model, rho, damping=choice.damping)
            .flutter_frequency if finite else None,
            "source": "c2 in {:g}..{:g} N s/m maximising the flutter airspeed of the wing with "
                      "its Maxwell DVA and c2 held fixed (eigenvalues, base density)"
                      .format(*DAMPER_RANGE)}
