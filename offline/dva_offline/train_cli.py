"""``dva train``: record the seed's training sweep and train the RBF controller from it (sec. 7.2).

Subcommands::

    dva train sweep   fly the stepped (U, c2) sweep and record it to a rosbag2 MCAP bag
                      (the batch path: same topics and schemas as the ROS graph)
    dva train rbf     read a recorded sweep (the bag alone), label each airspeed with the c2 of
                      the lowest measured RMS, train the RBF network by OLS, save it for the
                      rbf_controller node

The sweep is flown continuously, so the wing carries its state from one dwell into the next:
an unstable (U, c2) pair grows and spoils every later dwell, and a slowly decaying one leaks
into the next window. ``sweep`` therefore keeps the leading airspeeds of the scenario at which
every c2 of the list decays at ``--min-decay`` 1/s or faster (eigenvalues of the model) and
holds each pair for ``--settle`` + ``--window`` seconds; ``rbf`` analyses the last ``--window``
seconds of each dwell. ``--as-is`` flies the scenario unchanged.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from aero_dva.bag import channels as ch

__all__ = ["register"]

DEFAULT_C2 = "200:770:20"  # [N s/m] brackets the reference wing's optimum (350-420) by 150+
TOPICS = {
    ch.ACCELERATION.absolute(): "the spectra's accelerations",
    ch.DISPLACEMENT.absolute(): "the leading-edge RMS, the labels' objective; `dva train sweep "
                                "--no-displacement` leaves it out",
    ch.FLIGHT_CONDITION.absolute(): "the airspeed",
    ch.DAMPER_STATE.absolute(): "the applied c2",
}


def register(subparsers) -> None:
    """Add the ``train`` command and its subcommands."""
    p = subparsers.add_parser("train", help="record the training sweep, train the RBF network",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="train_command", metavar="<train-command>")
    p.set_defaults(func=lambda args: _help(p))

    s = sub.add_parser("sweep", help="fly and record the (U, c2) training sweep (MCAP)",
                       description="Fly the stepped sweep of Zhang (2006) sec. 7.2.1 with "
                                   "the flight runtime and record it through the batch path.")
    s.add_argument("--scenario", metavar="FILE",
                   help="sweep scenario YAML (default: the package's scenario_sweep.yaml)")
    s.add_argument("--out", metavar="BAG_DIR",
                   help="bag directory to create (default runs/train_sweep_<UTC time>)")
    s.add_argument("--c2", metavar="MIN:MAX:N", default=DEFAULT_C2,
                   help=f"c2 values at each airspeed [N s/m] (default {DEFAULT_C2}; "
                        "'scenario' keeps the file's list)")
    s.add_argument("--settle", type=float, default=2.0,
                   help="[s] settling time at the start of each dwell (default 2)")
    s.add_argument("--window", type=float, default=2.0,
                   help="[s] analysis window at the end of each dwell (default 2, the seed's)")
    s.add_argument("--min-decay", type=float, default=0.5,
                   help="[1/s] decay rate every (U, c2) pair must have (default 0.5)")
    s.add_argument("--as-is", action="store_true",
                   help="fly the scenario unchanged (no stability check, its own c2 and dwell)")
    s.add_argument("--no-displacement", dest="displacement", action="store_false",
                   help="record only what a wing test measures (no /wing/displacement: "
                        "faster, smaller; but `dva train rbf`, run reports and replays need "
                        "the displacement)")
    s.add_argument("--jobs", type=_jobs, default=0, metavar="N",
                   help="processes, each recording a part of the sweep into its own file "
                        "of a split bag (default 0: one per core, at most 4, fewer for a "
                        "short sweep; 1: one file)")
    s.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    s.set_defaults(func=_sweep)

    r = sub.add_parser("rbf", help="train the RBF network from a recorded sweep",
                       description="Build the 33-input data set from the bag, label by the "
                                   "lowest measured leading-edge RMS per airspeed, train by "
                                   "OLS with the spread chosen on held-out airspeeds.")
    r.add_argument("bag", metavar="BAG_DIR", help="recorded sweep (rosbag2 MCAP bag)")
    r.add_argument("--out", metavar="network.npz", required=True,
                   help="network file to write (the rbf_controller's network_file)")
    r.add_argument("--plot", metavar="FILE.png", help="write fig. 7.11 (optimal vs network c2)")
    r.add_argument("--window", type=float, default=2.0,
                   help="[s] window at the end of each dwell (default 2)")
    r.add_argument("--spreads", metavar="S1,S2,...",
                   help="candidate spreads in scaled input space (default "
                        "0.1,0.2,0.3,0.5,0.7,1,1.5,2,3)")
    r.add_argument("--validation-every", type=int, default=5,
                   help="hold out every k-th airspeed for validation (default 5)")
    r.add_argument("--max-neurons", type=int, default=100, help="most hidden neurons (100)")
    r.add_argument("--tolerance", type=float, default=1e-3,
                   help="OLS stops below this unexplained fraction (default 1e-3)")
    r.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    r.set_defaults(func=_rbf)


def _help(parser) -> int:
    parser.print_help()
    return 2


def _jobs(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expects an integer >= 0, got {text!r}")
    return value


def _range3(option: str, text: str):
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise ValueError(f"{option} expects MIN:MAX:N, got {text!r}") from None
    if not (math.isfinite(start) and math.isfinite(stop)) or start < 0 or n < 2 \
            or stop <= start:
        raise ValueError(f"{option} needs finite 0 <= MIN < MAX and N >= 2, got {text!r}")
    return np.linspace(start, stop, n)


# -- sweep ------------------------------------------------------------------------------------

def _sweep(args) -> int:
    from dataclasses import replace

    from tqdm import tqdm

    from aero_dva import data_files
    from aero_dva.bag.sweep_recording_io import default_jobs, record_sweep
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
    from aero_dva.wing.flutter import flutter_speed, growth_rate
    from aero_dva.wing.model import AeroelasticModel
    from dva_offline.training import adapt_sweep

    scenario_path = Path(args.scenario) if args.scenario else \
        data_files.data_file("scenario_sweep.yaml")
    config = load_runtime_config({"scenario": str(scenario_path)})
    if config.scenario.airspeed.kind != "steps":
        raise ValueError(f"--scenario {scenario_path}: not a sweep (airspeed kind "
                         f"{config.scenario.airspeed.kind!r}, expected 'steps')")
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    out = Path(args.out or f"runs/train_sweep_{stamp}").resolve()
    if out.exists():
        raise ValueError(f"--out {out} exists; choose a new bag directory")
    density = config.scenario.density
    u_cr = flutter_speed(AeroelasticModel(config.wing, None, config.aero),
                         density=density).critical_airspeed
    adaptation = None
    if not args.as_is:
        damping = None if args.c2 == "scenario" else _range3("--c2", args.c2)
        model = AeroelasticModel(config.wing, config.absorber, config.aero)
        adaptation = adapt_sweep(
            config.scenario, u_cr, lambda u, c: growth_rate(model, u, density, c),
            damping=damping, min_decay=args.min_decay, settle=args.settle, window=args.window)
        config = replace(config, scenario=adaptation.scenario)
        config = load_runtime_config_checked(config)
    runtime = FlightRuntime(config)
    scenario = runtime.scenario
    jobs = args.jobs or default_jobs(scenario.n_samples)
    # No tqdm monitor thread: the recording forks its processes from this one.
    tqdm.monitor_interval = 0
    bar = tqdm(total=scenario.n_samples, desc="sweep", unit="sample", unit_scale=True,
               file=sys.stderr, leave=False)

    def progress(done, total):
        bar.update(done - bar.n)

    try:
        # Parallel in time where it can; encoding and writing overlap the simulation.
        recorded = record_sweep(out, runtime, progress, displacement=args.displacement,
                                jobs=jobs)
    finally:
        bar.close()
    speeds = np.asarray(scenario.airspeed.values)
    bag_bytes = sum(f.stat().st_size for f in out.iterdir() if f.is_file())
    summary = {
        "bag": str(out),
        "scenario": str(scenario_path),
        "outcome": recorded.outcome,
        "sim_time_s": recorded.sim_time,
        "wall_time_s": recorded.wall_time,
        "real_time_factor": recorded.sim_time / recorded.wall_time,
        "samples": recorded.samples,
        "blocks": recorded.blocks,
        "method": recorded.method,
        "topics": [t.name for t in recorded.summary.topics],
        "bag_bytes": bag_bytes,
        "bag_files": len(list(out.glob("*.mcap"))),
        "critical_airspeed_no_dva": u_cr,
        "airspeeds": int(speeds.size),
        "airspeed_ratio_range": [float(speeds[0] / u_cr), float(speeds[-1] / u_cr)],
        "c2_values": [float(c) for c in scenario.sweep_damping],
        "dwell_s": scenario.dwell,
        "seed": scenario.seed,
        "adapted": adaptation is not None,
    }
    if adaptation is not None:
        dropped = adaptation.dropped_ratios
        summary.update({
            "settle_s": adaptation.settle, "window_s": adaptation.window,
            "min_decay_per_s": adaptation.min_decay,
            "dropped_airspeeds": int(dropped.size),
            "dropped_ratio_range": ([float(dropped[0]), float(dropped[-1])]
                                    if dropped.size else None),
        })
    if args.json:
        print(json.dumps(summary))
        return 0 if recorded.outcome == "completed" else 1
    print(f"bag                 {out}")
    print(f"outcome             {recorded.outcome}")
    print(f"flown               {recorded.sim_time:.0f} s of sim time in "
          f"{recorded.wall_time:.1f} s wall ({summary['real_time_factor']:.0f}x real time), "
          f"{bag_bytes / 1e6:.0f} MB in {summary['bag_files']} file(s)")
    if not args.displacement:
        print("topics              measured only (no /wing/displacement)")
    print(f"airspeeds           {speeds.size}: {speeds[0] / u_cr:.3f} .. "
          f"{speeds[-1] / u_cr:.3f} U_cr (U_cr = {u_cr:.2f} m/s without DVA)")
    c2 = scenario.sweep_damping
    print(f"c2 per airspeed     {len(c2)}: {c2[0]:g} .. {c2[-1]:g} N s/m, "
          f"dwell {scenario.dwell:g} s")
    if adaptation is not None:
        print(f"window              last {adaptation.window:g} s of each dwell, after "
              f"{adaptation.settle:g} s settling; every pair decays >= "
              f"{adaptation.min_decay:g} 1/s")
        if dropped.size:
            print(f"left out            {dropped.size} airspeeds {dropped[0]:.3f} .. "
                  f"{dropped[-1]:.3f} U_cr (some c2 of the list decays slower or grows)")
    return 0 if recorded.outcome == "completed" else 1


def load_runtime_config_checked(config):
    """Re-check an adapted sweep against the damper's range (as load_runtime_config does)."""
    low, high = config.damper.min_damping, config.damper.max_damping
    outside = [c for c in config.scenario.sweep_damping if not low <= c <= high]
    if outside:
        raise ValueError(f"--c2 values {outside} N s/m lie outside the damper's range "
                         f"[{low}, {high}]")
    return config


# -- rbf --------------------------------------------------------------------------------------

def _check_topics(bag) -> None:
    from aero_dva.bag.bag_reader import TopicNotFoundError, bag_topics

    present = bag_topics(bag)
    for topic, what in TOPICS.items():
        if topic not in present:
            raise TopicNotFoundError(
                f"bag {str(bag)!r} has no topic {topic} ({what}); topics there: "
                f"{sorted(present)}")
        if present[topic].message_count == 0:
            raise ValueError(f"bag {str(bag)!r}: topic {topic} ({what}) holds no messages")


def _critical_airspeed(log) -> float | None:
    for status in log.diagnostics:
        value = status["values"].get("critical_airspeed_no_dva")
        if value is not None:
            try:
                return float(value)
            except ValueError:
                return None
    return None


def _rbf(args) -> int:
    from aero_dva.bag.flight_log_io import load_flight_log
    from aero_dva.control.rbf_io import save_rbf_network
    from dva_offline.training import (
        DEFAULT_SPREADS,
        build_dataset,
        label_min_rms,
        network_c2_per_airspeed,
        train_network,
    )

    if args.spreads:
        try:
            spreads = tuple(float(s) for s in args.spreads.split(","))
        except ValueError:
            raise ValueError(f"--spreads expects numbers separated by commas, got "
                             f"{args.spreads!r}") from None
    else:
        spreads = DEFAULT_SPREADS
    started = time.monotonic()
    bag = Path(args.bag)
    _check_topics(bag)
    log = load_flight_log(bag)
    data = build_dataset(log, window=args.window)
    labels = label_min_rms(data)
    outcome = train_network(data, labels, spreads=spreads,
                            validation_every=args.validation_every,
                            tolerance=args.tolerance, max_neurons=args.max_neurons)
    network = outcome.network
    u_cr = _critical_airspeed(log)
    description = (
        f"trained by dva train rbf from {bag.resolve()}: {data.n_windows} windows "
        f"({data.window:g} s, last of each dwell), {labels.airspeed.size} airspeeds, label = "
        f"c2 of the lowest measured leading-edge RMS per airspeed; spread {outcome.spread:g} "
        f"chosen on {outcome.validation_airspeeds.size} held-out airspeeds; training RMS error "
        f"{outcome.training_error:.4g} N s/m, validation {outcome.validation_error:.4g} N s/m")
    out = save_rbf_network(network, args.out, description=description)
    per_airspeed = network_c2_per_airspeed(network, data, labels)
    held = np.isin(labels.airspeed, outcome.validation_airspeeds)
    if args.plot:
        from dva_offline.training_io import plot_network_c2

        scale = u_cr if u_cr else 1.0
        plot_network_c2(args.plot, labels.airspeed / scale, labels.damping, per_airspeed, held,
                        data.airspeed / scale, network.predict(data.inputs))
    label_spread = float(np.std(labels.damping))
    summary = {
        "bag": str(bag.resolve()),
        "network": str(out),
        "windows": data.n_windows,
        "window_s": data.window,
        "skipped_dwells": data.skipped,
        "airspeeds": int(labels.airspeed.size),
        "train_airspeeds": int(outcome.train_airspeeds.size),
        "validation_airspeeds": int(outcome.validation_airspeeds.size),
        "critical_airspeed_no_dva": u_cr,
        "spreads": outcome.spreads.tolist(),
        "training_rmse_per_spread": outcome.training_rmse.tolist(),
        "validation_rmse_per_spread": outcome.validation_rmse.tolist(),
        "spread": outcome.spread,
        "neurons": network.n_neurons,
        "stop_reason": outcome.result.stop_reason,
        "training_rmse": outcome.training_error,
        "validation_rmse": outcome.validation_error,
        "label_std": label_spread,
        "optimal_c2_range": [float(labels.damping.min()), float(labels.damping.max())],
        "optimal_c2": {"airspeed": labels.airspeed.tolist(), "c2": labels.damping.tolist(),
                       "network_c2": per_airspeed.tolist(),
                       "min_rms": labels.rms.tolist()},
        "plot": str(Path(args.plot).resolve()) if args.plot else None,
        "wall_time_s": time.monotonic() - started,
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"bag                 {summary['bag']}")
    print(f"data set            {data.n_windows} windows of {data.window:g} s x 33 inputs, "
          f"{labels.airspeed.size} airspeeds (skipped dwells: {data.skipped})")
    print(f"labels              optimal c2 {labels.damping.min():g} .. {labels.damping.max():g}"
          f" N s/m (std {label_spread:.1f})")
    for s, tr, va in zip(outcome.spreads, outcome.training_rmse, outcome.validation_rmse):
        mark = "  <- chosen" if s == outcome.spread else ""
        print(f"spread {s:<6g}       training {tr:8.2f}  validation {va:8.2f} N s/m{mark}")
    print(f"network             {network.n_neurons} neurons, spread {outcome.spread:g} "
          f"({outcome.result.stop_reason}), trained on {outcome.train_airspeeds.size} "
          f"airspeeds, validated on {outcome.validation_airspeeds.size}")
    print(f"RMS error           training {outcome.training_error:.2f} N s/m, validation "
          f"{outcome.validation_error:.2f} N s/m")
    print(f"saved               {out}")
    if args.plot:
        print(f"plot                {summary['plot']}")
    print(f"wall time           {summary['wall_time_s']:.1f} s")
    return 0
