"""``dva evaluate``: can the controllers be told apart? Paired flights, differences, boundaries.

Flies the study's ramp (0.8 -> 1.2 U_cr in 30 s, 1 kN white aileron force) for the controllers
of the controller table (aero_dva.control.controllers; by default the project's block-rate
laws and references: ``fixed``, the best constant c2; ``schedule``, eq. 7.1; ``rbf``, spectrum
+ network; ``oracle``, c2*(U, rho) at the true airspeed and density: the upper bound; a law
another package registers is flown when named) in six density cases
(constant rho0, x0.9, x1.1; mu = 0.1 with a 20 s period, at 1 Hz, and near twice the flutter
frequency), each with the same excitation seeds, so the controllers meet the same gusts. All
in one process (the simulator node's runtime with the nodes' arithmetic in the loop, command lag
one block; docs/evaluation.md). Reports per (controller, case) the mean divergence airspeed
U_div/U_cr and the leading-edge RMS below flutter (``--rms-range``) as a ratio to the best
fixed c2 on the same seed, with paired 95 % intervals, and the eigenvalue and Floquet
boundaries of each analysable control law beside them.

What it needs and is not given, it makes (into DIR/inputs, with the project's commands): the
schedule (dva control schedule), the best fixed c2, the network (dva train sweep + dva train
rbf, about two minutes). ``--graph`` flies the earlier evaluation through the ROS 2 graph
instead (run_flight per flight; mu cases, resumable; its own options below).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from aero_dva.flight.range_rms import RMS_RANGE

__all__ = ["register"]

DEFAULT_SEEDS = 30
RAMP_TO = 1.4  # [U_cr] the study's ramp (0.8 -> 1.2 in 30 s) carried on at its slope
DEFAULT_RMS_RANGE = f"{RMS_RANGE[0]:g}:{RMS_RANGE[1]:g}"  # the range run_flight's summary uses


def register(subparsers) -> None:
    """Add the ``evaluate`` command."""
    from aero_dva.control import controllers as table
    from aero_dva.control.controllers import BLOCK, NONE, REFERENCE, SAMPLE

    in_process = table.names((BLOCK, REFERENCE))
    default = table.names((BLOCK, REFERENCE), builtin_only=True)
    graph = (NONE, *table.names((BLOCK, SAMPLE)))
    p = subparsers.add_parser(
        "evaluate", help="paired evaluation flights: controllers x density cases x seeds; "
                         "differences to the best fixed c2 with 95 %% intervals",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", metavar="DIR",
                   help="evaluation directory (default runs/evaluation_<UTC time>)")
    p.add_argument("--seeds", type=int, default=None,
                   help=f"excitation seeds per case (default {DEFAULT_SEEDS}; --graph: 10)")
    p.add_argument("--first-seed", type=int, default=1, help="first excitation seed (1)")
    p.add_argument("--controllers", default=None,
                   help=f"subset of {','.join(in_process + table.names((SAMPLE,)))} (default "
                        f"{','.join(default)}; fixed is always flown, the reference); --graph: "
                        f"of {','.join(graph)}. A per-sample law "
                        f"({','.join(table.names((SAMPLE,)))}) flies the same flights, with "
                        "its damper lag and sensor noise, in the constant-density cases (the "
                        "others are marked in the table)")
    p.add_argument("--gains", metavar="FILE", default=None,
                   help="gains JSON of the one per-sample law flown (default: the package's "
                        "file of each)")
    p.add_argument("--ramp-to", type=float, default=None, metavar="RATIO",
                   help=f"carry the scenario's ramp on at its slope to RATIO U_cr, so that "
                        f"laws that hold past its end diverge on it too (default {RAMP_TO:g}; "
                        "the ramp's own end or below: as the scenario)")
    p.add_argument("--cases", default=None,
                   help="subset of rho0,x0.9,x1.1,slow,1Hz,2f (default all)")
    p.add_argument("--rms-range", metavar="LOW:HIGH", default=None,
                   help=f"airspeeds U/U_cr of the leading-edge RMS (default "
                        f"{DEFAULT_RMS_RANGE}; the first 2 s are left out)")
    p.add_argument("--scenario", metavar="FILE",
                   help="base ramp scenario YAML (default the package's scenario_ramp.yaml); "
                        "a flight holds its traces, about 160 bytes per sample: at most "
                        "6,710,886 samples (duration x sample rate, 1 GiB) per flight, and "
                        "the seeds of a batch together within 1 GiB")
    p.add_argument("--schedule", metavar="FILE", help="airspeed schedule JSON (default: made "
                   "by dva control schedule into DIR/inputs)")
    p.add_argument("--fixed-c2", type=float, default=None,
                   help="[N s/m] c2 of the fixed controller (default: the c2 with the highest "
                        "flutter airspeed)")
    p.add_argument("--network", metavar="FILE.npz", help="RBF network (default: trained)")
    p.add_argument("--sweep-bag", metavar="BAG",
                   help="recorded training sweep to train the network from (default: record "
                        "one with dva train sweep)")
    p.add_argument("--no-boundaries", action="store_true",
                   help="skip the eigenvalue and Floquet boundaries")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="flights in parallel: N local processes (default 1); with --graph, N "
                        "flights at a time, each in its own ROS domain")
    p.add_argument("--one-flight", action="store_true",
                   help="fly one flight at a time (the reference route) instead of each "
                        "case's seeds together (same records up to rounding)")
    p.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="hand the flights to a Ray cluster: its address, 'auto' (the cluster "
                        "this machine is part of) or 'local' (start one here with --workers "
                        "CPUs); needs the 'ray' extra")
    g = p.add_argument_group("--graph: the evaluation through the ROS 2 graph")
    g.add_argument("--graph", action="store_true",
                   help="fly every flight through run_flight (nodes over DDS) instead")
    g.add_argument("--mu", default=None,
                   help="density variations at 1 Hz, comma-separated (default 0,0.05,0.1)")
    g.add_argument("--timeout", type=float, default=None,
                   help="[s] wall time allowed per flight (default 300)")
    g.add_argument("--retries", type=int, default=None,
                   help="times a failed flight is flown again (default 1)")
    g.add_argument("--real-time-factor", type=float, default=None,
                   help="run_flight --real-time-factor (default 0: as fast as possible)")
    g.add_argument("--reports", choices=("first", "none"), default=None,
                   help="per-run report of the first seed of each case (default) or none")
    g.add_argument("--no-rrd", action="store_true", help="reports without the .rrd")
    p.set_defaults(func=_evaluate)


#: The options of --graph only, and their defaults.
GRAPH_DEFAULTS = {"mu": "0,0.05,0.1", "timeout": 300.0, "retries": 1, "real_time_factor": 0.0,
                  "reports": "first", "no_rrd": False}
#: The options of the in-process evaluation only (--graph has no use for them).
PAIRED_ONLY = ("--cases", "--rms-range", "--no-boundaries", "--one-flight", "--gains",
               "--ramp-to")


def _evaluate(args) -> int:
    from dva_offline.cli_tools import not_with

    if args.graph:
        from dva_offline.evaluation.graph import evaluate_graph
        from dva_offline.evaluation.graph_cases import DEFAULT_CONTROLLERS

        not_with(args, "is not an option of --graph (the in-process evaluation's only)",
                 *PAIRED_ONLY)
        args.seeds = 10 if args.seeds is None else args.seeds
        args.controllers = args.controllers or ",".join(DEFAULT_CONTROLLERS)
        for dest, value in GRAPH_DEFAULTS.items():
            if getattr(args, dest) is None:
                setattr(args, dest, value)
        return evaluate_graph(args)
    not_with(args, "is an option of --graph: it needs --graph",
             *("--" + d.replace("_", "-") for d in GRAPH_DEFAULTS))
    return _paired(args)


#: Options that give a controller's input, and the option of the controller table they fill.
INPUT_OPTIONS = {"--schedule": "schedule", "--network": "network", "--sweep-bag": "network",
                 "--gains": "gains"}


def check_inputs_used(args, controllers) -> None:
    """Refuse an input file or value for a controller that is not flown (one line, exit 2)."""
    from aero_dva.control import controllers as table
    from dva_offline.cli_tools import not_with
    from dva_offline.evaluation.paired import REFERENCE_CONTROLLER

    chosen = ",".join(controllers)
    users = {flag: [c.name for c in table.controllers() if c.option(option)]
             for flag, option in INPUT_OPTIONS.items()}
    users["--fixed-c2"] = [REFERENCE_CONTROLLER]
    for flag, names in users.items():
        if not set(names) & set(controllers):
            not_with(args, f"is for the {' or '.join(names)} controller, which is not flown "
                           f"(--controllers {chosen})", flag)
    if args.network:
        not_with(args, "trains a network, but --network gives one", "--sweep-bag")


def _choose(option: str, text: str | None, known: tuple[str, ...],
            default: tuple[str, ...] | None = None) -> tuple[str, ...]:
    if text is None:
        return known if default is None else default
    names = [v.strip() for v in text.split(",") if v.strip()]
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise ValueError(f"{option} must be a comma-separated subset of {','.join(known)}, "
                         f"got {text!r}")
    return tuple(n for n in known if n in names)


def _rms_range(text: str) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in text.split(":"))
    except ValueError:
        raise ValueError(f"--rms-range expects LOW:HIGH (U/U_cr), got {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low < high):
        raise ValueError(f"--rms-range needs 0 < LOW < HIGH, got {text!r}")
    return low, high


def _paired(args) -> int:
    from tqdm import tqdm

    from aero_dva import data_files
    from aero_dva.atomic_io import atomic_output
    from aero_dva.control import controllers as table
    from aero_dva.control.controllers import BLOCK, REFERENCE, SAMPLE
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
    from aero_dva.wing.model import AeroelasticModel
    from dva_offline.evaluation.flights import (
        EvaluationSetup,
        case_table,
        flight_memory_problem,
        fly_paired,
        oracle_table,
        peak_limit,
        refused,
        stability_boundaries,
    )
    from dva_offline.evaluation.inputs import evaluation_directory, log, resumable_or_removed
    from dva_offline.evaluation.paired import (
        CASE_NAMES,
        HOLD,
        REFERENCE_CONTROLLER,
        default_cases,
        law_pairs,
        summarise,
    )
    from dva_offline.evaluation.paired_io import plot_paired, write_paired_results

    seeds_n = DEFAULT_SEEDS if args.seeds is None else args.seeds
    if seeds_n < 1 or args.first_seed < 0:
        raise ValueError(f"--seeds must be >= 1 and --first-seed >= 0, got {seeds_n}, "
                         f"{args.first_seed}")
    known = table.names((BLOCK, REFERENCE, SAMPLE))
    controllers = _choose("--controllers", args.controllers, known,
                          table.names((BLOCK, REFERENCE), builtin_only=True))
    controllers = tuple(c for c in known if c in controllers or c == REFERENCE_CONTROLLER)
    per_sample = [c for c in controllers if table.controller(c).runs == SAMPLE]
    case_names = _choose("--cases", args.cases, CASE_NAMES)
    if args.gains and len(per_sample) > 1:
        raise ValueError(f"--gains is the file of one per-sample law; --controllers flies "
                         f"{' and '.join(per_sample)} (fly one, or both on their package "
                         "files)")
    args.ramp_to = RAMP_TO if args.ramp_to is None else args.ramp_to
    if not (math.isfinite(args.ramp_to) and 0.5 < args.ramp_to <= 2.0):
        raise ValueError(f"--ramp-to is a ratio of U_cr in (0.5, 2], got {args.ramp_to}")
    check_inputs_used(args, controllers)
    for name in per_sample:  # a bad file ends the run here, not in every flight
        _check_gains(table.controller(name), args.gains)
    rms_low, rms_high = _rms_range(args.rms_range or DEFAULT_RMS_RANGE)
    seeds = list(range(args.first_seed, args.first_seed + seeds_n))
    scenario_path = Path(args.scenario) if args.scenario else \
        data_files.data_file("scenario_ramp.yaml")
    config = load_runtime_config({"scenario": str(scenario_path)})
    if config.scenario.airspeed.kind != "ramp":
        raise ValueError(f"--scenario {scenario_path}: the evaluation flies a ramp, got "
                         f"airspeed kind {config.scenario.airspeed.kind!r}")
    problem = flight_memory_problem(config.scenario.n_samples)
    if problem is not None:
        raise ValueError(f"--scenario {scenario_path}: {problem}")
    started = time.monotonic()
    out, made, _, created = evaluation_directory(args, controllers)
    with resumable_or_removed(out, created):
        model = AeroelasticModel(config.wing, config.absorber, config.aero)
        u_cr = FlightRuntime(config).critical_airspeed
        fixed = made["fixed_c2"]
        flutter_frequency = fixed.get("flutter_frequency") or _flutter_frequency(model, config,
                                                                                 fixed["damping"])
        cases = {k: v for k, v in default_cases(flutter_frequency).items() if k in case_names}
        ramp = config.scenario.airspeed.values
        if not config.scenario.airspeed.relative:
            ramp = tuple(v / u_cr for v in ramp)
        ramp = (ramp[0], max(ramp[1], args.ramp_to))
        references = [c for c in controllers if table.controller(c).runs == REFERENCE]
        oracle = oracle_table(model, u_cr, config.scenario.density, list(cases.values()), ramp) \
            if references else None
        setup = EvaluationSetup(
            config=config, model=model, critical_airspeed=u_cr,
            laws=evaluation_laws(controllers, made, config.damper, oracle, args.gains),
            rms_range=(rms_low * u_cr, rms_high * u_cr), ramp_to=args.ramp_to,
            peak_limits={name: peak_limit(model, ramp[0] * u_cr, config.scenario.density
                                          * case.factor, fixed["damping"])
                         for name, case in cases.items()},
            safe_damping=fixed["damping"])
        not_flown = {(c, case.name): reason for c in controllers for case in cases.values()
                     if (reason := refused(c, case))}
        total = len(cases) * len(seeds) * len(controllers) - len(not_flown) * len(seeds)
        bar = tqdm(total=total, desc="flights", unit="flight", file=sys.stderr, leave=False)

        def progress(text):
            bar.set_postfix_str(text)
            bar.update(1)

        from dva_offline.evaluation.resume import FlightStore

        store = FlightStore(out / "flights", {
            "scenario": str(scenario_path), "controllers": list(controllers),
            "cases": case_table(cases), "rms_range_ratio": [rms_low, rms_high],
            "fixed_c2": fixed["damping"], "schedule": made.get("schedule"),
            "network": made.get("network"), "gains": args.gains, "ramp_to": args.ramp_to,
            "hold": list(HOLD), "records": "with practical boundary and hold"})
        done = store.load(seeds)
        if done:
            log(f"resuming: {len(done)} of {len(cases) * len(seeds)} (case, seed) jobs already "
                f"flown in {store.directory}")
            bar.update(sum(len(v) for k, v in done.items() if k[1] != seeds[0]))
        flights_started = time.monotonic()
        try:
            records, kept = fly_paired(setup, list(cases.values()), seeds, controllers, progress,
                                      keep_seed=seeds[0], workers=args.workers,
                                      ray_address=args.ray, done=done, finished=store.save,
                                      batch=not args.one_flight)
        finally:
            bar.close()
        flight_time = time.monotonic() - flights_started
        rows = summarise(records, controllers, list(cases), not_flown)
        boundaries = {} if args.no_boundaries else stability_boundaries(
            setup, list(cases.values()), controllers)
        payload = {
            "out": str(out), "scenario": str(scenario_path), "controllers": list(controllers),
            "cases": case_table(cases), "seeds": seeds, "inputs": made,
            "critical_airspeed_no_dva": u_cr, "fixed_c2": fixed["damping"],
            "rms_range_ratio": [rms_low, rms_high], "flights": len(records),
            "ramp_ratio": list(ramp), "hold": list(HOLD),
            "peak_limits": setup.peak_limits,
            "not_flown": [{"controller": c, "case": k, "reason": r}
                          for (c, k), r in not_flown.items()],
            "flight_wall_time_s": flight_time, "workers": args.workers, "ray": args.ray,
            "resumed_jobs": len(done),
            "results": [_row_json(r) for r in rows], "boundaries": boundaries,
            "law_pairs": law_pairs(records, per_sample, list(cases)),
        }
        # the plots first, then the tables: an interrupt among the plots leaves no results.md
        # that would pass for the run's (results.json, last, says the run is complete)
        plots = plot_paired(out, payload, kept, u_cr)
        payload["files"] = {**write_paired_results(out, payload, records), **plots}
        payload["wall_time_s"] = time.monotonic() - started
        with atomic_output(out / "results.json") as stream:  # last: the run is complete
            stream.write(json.dumps(payload, allow_nan=False))
        if args.json:
            print(json.dumps(payload, allow_nan=False))
        else:
            from dva_offline.evaluation.paired_io import markdown_results

            print(markdown_results(payload))
            print(f"results: {out / 'results.md'} ({len(records)} flights in {flight_time:.0f} s)")
        return 0


def _check_gains(entry, path: str | None) -> None:
    """A per-sample law's gains file (``path``, or its package file) must be its design and
    made for the evaluation's wing; ValueError naming the file otherwise."""
    from aero_dva.control.switching_io import gains_problem
    from aero_dva.data_files import data_file

    default = next(o.default_file for o in entry.options if o.default_file)
    problem = gains_problem(path or str(data_file(default)), None,
                            lambda p: entry.make_law({"gains_file": str(p)}))
    if problem is not None:
        raise ValueError(f"--controllers {entry.name}: {problem}")


def evaluation_laws(controllers, made: dict, damper, oracle_table, gains=None) -> dict:
    """Each controller's law, made from its table entry with the evaluation's inputs: its
    options' values from ``made`` (the best fixed c2 for ``--damping``, the schedule and network
    files), the damper's range for a law that clamps to it, a reference's table."""
    from aero_dva.control import controllers as table

    given = {"damping": made.get("fixed_c2", {}).get("damping"), **made}
    if gains:
        given["gains"] = gains
    laws = {}
    for name in controllers:
        entry = table.controller(name)
        values = {o.param: given[o.name] for o in entry.options if given.get(o.name) is not None}
        params = {p.name for p in entry.params}
        if {"damping_min", "damping_max"} <= params:
            values.update(damping_min=damper.min_damping, damping_max=damper.max_damping)
        if entry.runs == table.REFERENCE:
            values["table"] = oracle_table
        laws[name] = entry.make_law(values)
    return laws


def _flutter_frequency(model, config, damping: float) -> float:
    from aero_dva.wing.flutter import flutter_speed

    return flutter_speed(model, config.scenario.density, damping=damping).flutter_frequency


def _row_json(row: dict) -> dict:
    def clean(v):
        return None if isinstance(v, float) and not math.isfinite(v) else v

    from dva_offline.evaluation.paired import ROW_STATS

    out = {k: clean(v) for k, v in row.items() if k not in ROW_STATS}
    out.update({k: row[k].to_dict() for k in ROW_STATS})
    return out
