"""``dva replay``: re-run a controller on a recorded flight, open loop, and compare.

The recorded controller inputs (``wing/acceleration`` and ``dva/damper_state`` for the spectrum
node and a law of spectra such as the RBF network, ``flight/condition`` for a law of flight
conditions such as the airspeed schedule) go through the controller's law again (any block-rate
law of the controller table, aero_dva.control.controllers), and its spectra and commands are
recorded as a new bag and compared, stamp by stamp, with the ones the flight recorded. With the
network or schedule that flew, they are equal; with another one, the difference is what that
controller would have commanded on the same data (the wing does not respond: open loop).

Two paths, the same numbers:
  (default)   the ROS 2 graph: bag_player -> [spectrum ->] controller -> mcap_recorder, as
              separate processes on sim time (``ros2 run aero_dva_sim replay_flight``);
              needs the ROS environment (source scripts/env.sh)
  --offline   the nodes' own code without ROS (aero_dva.control.spectrum_stream, the
              law), much faster

The spectra and the law use the nodes' defaults (the spectra's shape, the damper's range).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from aero_dva import exits

__all__ = ["register"]

HOP = 0.1  # [s] the spectrum node's default hop


def _spectrum_shape() -> tuple:
    """(channels, frequencies, window duration, window) of the spectrum node's defaults."""
    from aero_dva.control.controllers import SPECTRUM_SHAPE

    shape = {p.name: p.default for p in SPECTRUM_SHAPE}
    return (tuple(shape["channels"]), np.asarray(shape["frequencies"], dtype=float),
            float(shape["window_duration"]), shape["window"])


def register(subparsers) -> None:
    """Add the ``replay`` command."""
    p = subparsers.add_parser(
        "replay", help="re-run a controller on a recorded flight (open loop, through the ROS "
                       "graph or --offline) and compare with the recorded commands",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", metavar="BAG", help="recorded flight (bag directory or .mcap file)")
    from aero_dva.control import controllers as table

    laws = table.controllers((table.BLOCK,))
    per_sample = table.controllers((table.SAMPLE,))
    p.add_argument("--controller", choices=[c.name for c in (*laws, *per_sample)],
                   required=True,
                   help="the block-rate law to re-run: "
                        + "; ".join(f"{c.name}: {c.label}" for c in laws)
                        + "; or a per-sample law whose flight to fly again with the c2 it "
                          "recorded (--offline): "
                        + ", ".join(c.name for c in per_sample))
    table.add_options(p, laws)
    p.add_argument("--scenario", metavar="FILE",
                   help="a per-sample law's flight: the scenario it flew (default the "
                        "package's scenario_ramp.yaml)")
    p.add_argument("--wing", metavar="FILE",
                   help="a per-sample law's flight: the wing it flew (default the package's "
                        "chapter-6 wing)")
    p.add_argument("--out", metavar="DIR", required=True, help="new bag directory to create")
    p.add_argument("--offline", action="store_true", help="without ROS (the nodes' code)")
    p.add_argument("--rate", type=float, default=None,
                   help="ROS path: playing speed, x recorded (default: replay_flight's, 10)")
    p.add_argument("--retries", type=int, default=None,
                   help="ROS path: times a replay whose graph lost messages is run again "
                        "before it is an error (default 1)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=_replay)


def _check_args(args) -> None:
    from aero_dva.control.controllers import BLOCK, controller, controllers
    from aero_dva.flight.damper import check_damping
    from dva_offline.cli_tools import CliError, not_with

    entry = controller(args.controller)
    if entry.runs != BLOCK:  # a per-sample law's flight is flown again, offline
        if not args.offline:
            raise CliError(f"--controller {entry.name} is a per-sample law: its flight is "
                           "flown again with the c2 it recorded, offline only (add --offline)")
        for other in controllers((BLOCK,)):
            for option in other.options:
                not_with(args, f"is for --controller {other.name}, not {entry.name}",
                         f"--{option.name}")
        not_with(args, "is an option of the ROS path: drop it or --offline", "--rate",
                 "--retries")
        if Path(args.out).exists():
            raise CliError(f"--out {args.out} exists; choose another directory")
        return
    not_with(args, f"is for a per-sample law's flight, not --controller {entry.name}",
             "--scenario", "--wing")
    for option in entry.options:
        if option.required and not getattr(args, option.name, None):
            raise CliError(f"--controller {entry.name} needs --{option.name} FILE")
    for other in controllers((BLOCK,)):
        for option in other.options:
            if entry.option(option.name) is None:
                not_with(args, f"is for --controller {other.name}, not {entry.name}",
                         f"--{option.name}")
    if args.offline:
        not_with(args, "is an option of the ROS path: drop it or --offline", "--rate",
                 "--retries")
    if args.retries is None:
        args.retries = 1
    defaults = entry.defaults()
    for option in entry.options:  # a c2 the damper would clip or reject, refused at the door
        if option.kind == "number":
            value = getattr(args, option.name)
            check_damping(defaults[option.param] if value is None else value,
                          f"--{option.name}", error=CliError)
    args.law = _law(args)  # a bad value or file ends the run here, naming it
    if Path(args.out).exists():
        raise CliError(f"--out {args.out} exists; choose another directory")
    if args.retries < 0:
        raise CliError(f"--retries must be >= 0, got {args.retries}")
    if args.rate is not None and not args.rate > 0:
        raise CliError(f"--rate must be > 0, got {args.rate:g}")


def _law(args):
    """The law of ``--controller`` with its options' values over its node's defaults."""
    from aero_dva.control.controllers import controller

    entry = controller(args.controller)
    return entry.make_law({o.param: getattr(args, o.name) for o in entry.options
                           if getattr(args, o.name, None) is not None})


def _offline(args, recording):
    import copy

    from aero_dva.control.controllers import SPECTRUM, controller
    from dva_offline.replay.rerun import law_commands, spectra_from_inputs

    entry = controller(args.controller)
    shape = _spectrum_shape()
    channels, frequencies, duration, window = shape
    spectra = spectra_from_inputs(recording.inputs, channels, duration, HOP, frequencies,
                                  window) if SPECTRUM in entry.inputs else []
    law = copy.deepcopy(args.law)  # a fresh law for each re-run
    return spectra, law_commands(entry, law, recording.conditions, spectra, shape)


def _ros(args, expected: list[int]) -> dict:
    try:
        from aero_dva_sim.run_flight import executable
    except ImportError:
        raise ValueError("the ROS path needs the ROS environment: source scripts/env.sh "
                         "(or use --offline)") from None
    exe = executable("aero_dva_sim", "replay_flight")  # not sourced: exits.Failure says how
    argv = [exe, str(args.bag), "--controller", args.controller, "--out", str(args.out),
            "--json"]
    from aero_dva.control.controllers import controller

    for option in (*(o.name for o in controller(args.controller).options), "rate"):
        value = getattr(args, option)
        if value is not None:
            argv += [f"--{option}", str(value)]
    if not _timed(args):  # the graph must give what the nodes' code says
        argv += ["--expect-spectra", str(expected[0]), "--expect-commands", str(expected[1])]
    result = subprocess.run(argv, capture_output=True, text=True)
    if result.returncode not in (exits.DONE, exits.PARTIAL):  # PARTIAL: counted below
        lines = result.stderr.strip().splitlines()
        line = (lines[-1] if lines else f"replay_flight exited {result.returncode}")
        line = line.removeprefix("replay_flight: ").removeprefix("error: ")
        if result.returncode == exits.BAD_INPUT:
            raise ValueError(line)
        code = result.returncode if result.returncode in exits.TABLE else exits.FAILED
        raise exits.Failure(f"replay_flight: {line}", code)
    return json.loads(result.stdout)


def _per_sample(args) -> bool:
    from aero_dva.control.controllers import SAMPLE, controller

    return controller(args.controller).runs == SAMPLE


def _fly_again(args, started: float) -> int:
    """A per-sample law's flight flown again with its recorded c2 (:mod:`.refly`)."""
    from dva_offline.replay.refly import refly

    check = refly(args)
    wall = time.monotonic() - started
    result = {"bag": str(args.bag), "controller": args.controller,
              "path": "offline: the wing flown again with the c2 the bag recorded",
              "out": str(args.out), **check, "wall_time_s": wall}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"bag          {args.bag}: {check['samples']} samples, {check['law_blocks']} "
              f"blocks flown by the law, {check['held_blocks']} on a held c2")
        print(f"controller   {args.controller}; {result['path']}")
        for name, c in check["accelerations"].items():
            print(f"{name:12s} max |difference| {c['max_abs_difference']:.3g} of a peak "
                  f"{c['peak']:.4g} ({c['relative_to_peak']:.2g} of it)")
        print(f"new bag      {args.out}")
        print(f"wall time    {wall:.1f} s")
    if not check["agrees"]:
        print(f"dva replay: error: the accelerations flown again differ from the recorded by "
              f"{check['relative_to_peak']:.3g} of their peak (more than {check['rtol']:g}): "
              "another scenario or wing than the flight's, or a bag that lost blocks",
              file=sys.stderr)
        return 1
    return 0


def _timed(args) -> bool:
    """The law answers its node's own timer, not the played inputs (its commands in the graph
    come at other times: nothing to count)."""
    from aero_dva.control.controllers import TICK, controller

    return controller(args.controller).inputs[0] == TICK


def _reads_spectra(args) -> bool:
    from aero_dva.control.controllers import SPECTRUM, controller

    return SPECTRUM in controller(args.controller).inputs


def _discard(out: Path) -> None:
    """Remove a replay's bag and node logs (before flying it again)."""
    import shutil

    shutil.rmtree(out, ignore_errors=True)
    shutil.rmtree(out.with_name(out.name + "_logs"), ignore_errors=True)


def _replay(args) -> int:
    from dva_offline.replay.bag_io import read_outputs, read_recording, write_outputs
    from dva_offline.replay.rerun import compare

    _check_args(args)
    started = time.monotonic()
    if _per_sample(args):
        return _fly_again(args, started)
    recording = read_recording(args.bag)
    if args.offline:
        spectra, commands = _offline(args, recording)
        channels, frequencies, duration, window = _spectrum_shape()
        write_outputs(args.out, spectra, commands, channels, frequencies, duration, HOP, window)
        path = "offline (the nodes' code without ROS)"
    else:
        # What the graph must give: the nodes' code says how many, so a message lost between
        # two nodes (DDS discovery under load) is caught, and the replay flown again.
        expected = [len(x) for x in _offline(args, recording)]
        for attempt in range(1 + args.retries):
            summary = _ros(args, expected)
            spectra, commands = read_outputs(args.out)
            if [len(spectra), len(commands)] == expected or _timed(args):
                break
            lost = (f"the graph delivered {len(spectra)} spectra and {len(commands)} commands "
                    f"of {expected[0]} and {expected[1]} to the recorder")
            if attempt == args.retries:  # the graph failed, not the input
                raise exits.Failure(f"{lost}; node logs in {summary['node_logs']}")
            print(f"dva replay: warning: {lost}; replaying again", file=sys.stderr)
            _discard(Path(args.out))
        path = f"ROS 2 graph, played at {summary['rate']:g}x recorded speed"
    wall = time.monotonic() - started
    result = {
        "bag": str(args.bag), "controller": args.controller, "path": path, "out": str(args.out),
        "recorded": {"spectra": len(recording.spectra), "commands": len(recording.commands),
                     "duration_s": recording.duration},
        "spectra": compare(recording.spectra, spectra).to_dict() if spectra or _reads_spectra(args)
        else None,
        "commands": compare(recording.commands, commands).to_dict(),
        "wall_time_s": wall,
    }
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"bag          {args.bag}: {len(recording.spectra)} spectra, "
          f"{len(recording.commands)} commands over {recording.duration:.2f} s")
    print(f"controller   {args.controller}, open loop; {path}")
    for key in ("spectra", "commands"):
        c = result[key]
        if c is None:
            continue
        if c["identical"]:
            verdict = "identical to the recorded"
        elif c["matched"] == 0:
            verdict = "nothing to compare stamp by stamp"
        else:
            verdict = (f"max |difference| {c['max_abs_difference']:.6g}, RMS "
                       f"{c['rms_difference']:.6g}" + (" N s/m" if key == "commands" else ""))
        print(f"{key:12s} {c['other']} re-run, {c['reference']} recorded, {c['matched']} "
              f"at the same stamps: {verdict}")
        held = c.get("held")
        if held and held["compared"] and not c["identical"]:
            print(f"{'':12s} against the recorded c2 in force at each re-run command "
                  f"({held['compared']}): mean {held['mean_difference']:+.6g}, max |difference| "
                  f"{held['max_abs_difference']:.6g}, RMS {held['rms_difference']:.6g} N s/m")
    print(f"new bag      {args.out}")
    print(f"wall time    {wall:.1f} s")
    return 0
