"""``dva replay``: re-run a controller on a recorded flight, open loop, and compare.

The recorded controller inputs (``wing/acceleration`` and ``dva/damper_state`` for the spectrum
and RBF network, ``flight/condition`` for the airspeed schedule) go through the controller
again, and its spectra and commands are recorded as a new bag and compared, stamp by stamp,
with the ones the flight recorded. With the network or schedule that flew, they are equal;
with another one, the difference is what that controller would have commanded on the same data
(the wing does not respond: open loop).

Two paths, the same numbers:
  (default)   the ROS 2 graph: bag_player -> [spectrum ->] controller -> mcap_recorder, as
              separate processes on sim time (``ros2 run aero_dva_sim replay_flight``);
              needs the ROS environment (source scripts/env.sh)
  --offline   the nodes' own code without ROS (aero_dva.control.spectrum_stream,
              command_laws), much faster

The spectra use the nodes' defaults: channels plunge and pitch, 5..20 Hz in 1 Hz steps, a 2 s
rectangular window every 0.1 s; commands are clamped to 0..2500 N s/m.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from aero_dva.flight.damper import DAMPER_RANGE

__all__ = ["register"]

CHANNELS = ("plunge", "pitch")  # the spectrum and rbf_controller nodes' defaults
FREQUENCIES = np.arange(5.0, 21.0, 1.0)
WINDOW_DURATION, HOP, WINDOW = 2.0, 0.1, "rectangular"
MAX_AIRSPEED = 400.0  # [m/s] the airspeed controller's default
FIXED_DAMPING = 1500.0  # [N s/m] the fixed controller's default


def register(subparsers) -> None:
    """Add the ``replay`` command."""
    p = subparsers.add_parser(
        "replay", help="re-run a controller on a recorded flight (open loop, through the ROS "
                       "graph or --offline) and compare with the recorded commands",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", metavar="BAG", help="recorded flight (bag directory or .mcap file)")
    p.add_argument("--controller", choices=("rbf", "schedule", "fixed"), required=True)
    p.add_argument("--network", metavar="FILE.npz", help="RBF network (rbf)")
    p.add_argument("--schedule", metavar="FILE.json", help="airspeed schedule (schedule)")
    p.add_argument("--damping", type=float, default=None,
                   help=f"[N s/m] c2 of the fixed controller (default {FIXED_DAMPING:g})")
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
    from dva_offline.cli_tools import CliError, not_with

    for option, needed in (("network", "rbf"), ("schedule", "schedule")):
        if args.controller == needed and not getattr(args, option):
            raise CliError(f"--controller {needed} needs --{option} FILE")
    for option, needed in (("--network", "rbf"), ("--schedule", "schedule"),
                           ("--damping", "fixed")):
        if args.controller != needed:
            not_with(args, f"is for --controller {needed}, not {args.controller}", option)
    if args.offline:
        not_with(args, "is an option of the ROS path: drop it or --offline", "--rate",
                 "--retries")
    if args.retries is None:
        args.retries = 1
    if args.controller == "fixed":
        from aero_dva.flight.damper import check_damping

        check_damping(FIXED_DAMPING if args.damping is None else args.damping, "--damping",
                      error=CliError)
    if Path(args.out).exists():
        raise CliError(f"--out {args.out} exists; choose another directory")
    if args.retries < 0:
        raise CliError(f"--retries must be >= 0, got {args.retries}")
    if args.rate is not None and not args.rate > 0:
        raise CliError(f"--rate must be > 0, got {args.rate:g}")


def _offline(args, recording):
    from aero_dva.control.command_laws import RBFLaw, ScheduleLaw
    from aero_dva.control.rbf_io import load_rbf_network
    from aero_dva.control.rbf_network import spectrum_input_names
    from aero_dva.control.schedule_io import load_schedule
    from dva_offline.replay.rerun import (
        CommandRecord,
        rbf_commands,
        schedule_commands,
        spectra_from_inputs,
    )

    if args.controller == "rbf":
        dim = len(CHANNELS) * FREQUENCIES.size + 1
        network = load_rbf_network(args.network, expected_input_dim=dim)
        names, units = spectrum_input_names(CHANNELS, FREQUENCIES)
        if network.input_names != names or network.input_units != units:
            raise ValueError(f"RBF network {args.network!r}: its inputs are not the spectra of "
                             f"{list(CHANNELS)} at 5..20 Hz and c2")
        spectra = spectra_from_inputs(recording.inputs, CHANNELS, WINDOW_DURATION, HOP,
                                      FREQUENCIES, WINDOW)
        return spectra, rbf_commands(spectra, RBFLaw(network, DAMPER_RANGE))
    if args.controller == "schedule":
        schedule = load_schedule(args.schedule)
        low = max(DAMPER_RANGE[0], schedule.damping_range[0])
        high = min(DAMPER_RANGE[1], schedule.damping_range[1])
        law = ScheduleLaw(schedule, (low, high), True, MAX_AIRSPEED)
        return [], schedule_commands(recording.conditions, law)
    damping = FIXED_DAMPING if args.damping is None else args.damping
    return [], [CommandRecord(stamp, damping, "fixed") for stamp, _ in recording.conditions]


def _ros(args, expected: list[int]) -> dict:
    try:
        from aero_dva_sim.run_flight import executable
    except ImportError:
        raise ValueError("the ROS path needs the ROS environment: source scripts/env.sh "
                         "(or use --offline)") from None
    try:
        exe = executable("aero_dva_sim", "replay_flight")
    except SystemExit as exc:
        raise ValueError(str(exc).replace("run_flight: error: ", "")) from None
    argv = [exe, str(args.bag), "--controller", args.controller, "--out", str(args.out),
            "--json"]
    for option in ("network", "schedule", "damping", "rate"):
        value = getattr(args, option)
        if value is not None:
            argv += [f"--{option}", str(value)]
    if args.controller != "fixed":  # the graph must give what the nodes' code says
        argv += ["--expect-spectra", str(expected[0]), "--expect-commands", str(expected[1])]
    result = subprocess.run(argv, capture_output=True, text=True)
    if result.returncode != 0:
        lines = (result.stderr or result.stdout).strip().splitlines()
        raise ValueError(lines[-1] if lines else f"replay_flight exited {result.returncode}")
    return json.loads(result.stdout)


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
    recording = read_recording(args.bag)
    if args.offline:
        spectra, commands = _offline(args, recording)
        write_outputs(args.out, spectra, commands, CHANNELS, FREQUENCIES, WINDOW_DURATION, HOP,
                      WINDOW)
        path = "offline (the nodes' code without ROS)"
    else:
        # What the graph must give: the nodes' code says how many, so a message lost between
        # two nodes (DDS discovery under load) is caught, and the replay flown again.
        expected = [len(x) for x in _offline(args, recording)]
        for attempt in range(1 + args.retries):
            summary = _ros(args, expected)
            spectra, commands = read_outputs(args.out)
            if [len(spectra), len(commands)] == expected or args.controller == "fixed":
                break
            lost = (f"the graph delivered {len(spectra)} spectra and {len(commands)} commands "
                    f"of {expected[0]} and {expected[1]} to the recorder")
            if attempt == args.retries:
                raise ValueError(f"{lost}; node logs in {summary['node_logs']}")
            print(f"dva replay: warning: {lost}; replaying again", file=sys.stderr)
            _discard(Path(args.out))
        path = f"ROS 2 graph, played at {summary['rate']:g}x recorded speed"
    wall = time.monotonic() - started
    result = {
        "bag": str(args.bag), "controller": args.controller, "path": path, "out": str(args.out),
        "recorded": {"spectra": len(recording.spectra), "commands": len(recording.commands),
                     "duration_s": recording.duration},
        "spectra": compare(recording.spectra, spectra).to_dict() if args.controller == "rbf"
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
