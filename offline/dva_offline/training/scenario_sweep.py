"""``dva train sweep --scenario FILE``: a stepped scenario sweep flown as one continuous flight.

The graph's path (``run_flight`` flies the same scenario through the nodes): the wing carries
its state from one dwell into the next, so an unstable (U, c2) pair grows and spoils every
later dwell. Unless ``--as-is``, :func:`dva_offline.training.rbf.adapt_sweep` keeps the leading
airspeeds at which every c2 of the list decays at ``--min-decay`` 1/s or faster and holds each
pair for ``--settle`` + ``--window`` seconds. Recorded parallel in time by
:func:`aero_dva.bag.sweep_recording_io.record_sweep` (one process per core). The default
training sweep is a plan instead (``dva train sweep`` without ``--scenario``).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

__all__ = ["scenario_sweep"]


def scenario_sweep(args, out: Path, range3) -> int:
    """``dva train sweep --scenario FILE``: see the module docstring."""
    from dataclasses import replace

    from tqdm import tqdm

    from aero_dva.bag.sweep_recording_io import default_jobs, record_sweep
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
    from aero_dva.wing.flutter import bare_critical_airspeed, growth_rate
    from aero_dva.wing.model import AeroelasticModel
    from dva_offline.training.rbf import adapt_sweep

    scenario_path = Path(args.scenario)
    config = load_runtime_config({"scenario": str(scenario_path)})
    if config.scenario.airspeed.kind != "steps":
        raise ValueError(f"--scenario {scenario_path}: not a sweep (airspeed kind "
                         f"{config.scenario.airspeed.kind!r}, expected 'steps')")
    density = config.scenario.density
    u_cr = bare_critical_airspeed(config.wing, density, config.aero)
    adaptation = None
    if not args.as_is:
        damping = None if args.c2 == "scenario" else range3("--c2", args.c2)
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
    problem = config.damper.range_problem(config.scenario.sweep_damping, "--c2 values")
    if problem is not None:
        raise ValueError(problem)
    return config


