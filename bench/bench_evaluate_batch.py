"""Benchmark of ``dva evaluate``'s flights: each case's seeds flown together against one flight
at a time (the reference route), CPU seconds in this process.

Run (after ./test.sh or ./run.sh has set everything up)::

    source scripts/env.sh && python bench/bench_evaluate_batch.py [--seeds 30]
        [--reference-seeds 5] [--cases rho0,x0.9,x1.1,slow,1Hz,2f]
        [--controllers C1,C2,...] [--network F.npz --schedule F.json
        --fixed-c2 C] [--json FILE]

The default is the default evaluation: 6 cases x 4 controllers x 30 seeds = 720 flights, flown
batched (one batch per case and controller). The reference route flies ``--reference-seeds``
of those seeds (default 5: 120 flights, the first seeds) one at a time; its CPU per flight is
scaled to the batched run's flights (a flight's cost there does not depend on how many are
flown). The inputs (schedule, best fixed c2, network) are made once by an untimed ``dva
evaluate`` unless given; the oracle's table is built once, untimed, for both routes. Prints
the CPU of each controller's flights on both routes, the ratio, and the largest relative
difference between the two routes' records of the same flights (required: at most
RECORD_RTOL).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RECORD_RTOL = 1e-9  # as tests/unit/dva_offline/evaluation/test_paired.py (why there)



def _default_controllers() -> tuple[str, ...]:
    """What ``dva evaluate`` flies by default (the controller table's block-rate laws and
    references)."""
    from aero_dva.control.controllers import BLOCK, REFERENCE, names

    return names((BLOCK, REFERENCE), builtin_only=True)


def _made_inputs(tmp: Path, cases: str, controllers: str) -> dict:
    argv = [sys.executable, "-m", "dva_offline.cli", "evaluate", "--out", str(tmp / "prep"),
            "--seeds", "1", "--cases", cases.split(",")[0], "--controllers", controllers,
            "--no-boundaries", "--json"]
    print("making the inputs (untimed) ...", file=sys.stderr, flush=True)
    result = subprocess.run(argv, capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed:\n{result.stderr[-2000:]}")
    made = json.loads(result.stdout)
    return {"fixed_c2": made["fixed_c2"], **made["inputs"]}


def _setup(args, inputs: dict):
    from aero_dva import data_files
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
    from aero_dva.wing.flutter import flutter_speed
    from aero_dva.wing.model import AeroelasticModel
    from dva_offline.evaluation.cli import evaluation_laws
    from dva_offline.evaluation.flights import EvaluationSetup, oracle_table
    from dva_offline.evaluation.paired import default_cases

    config = load_runtime_config({"scenario": str(data_files.data_file("scenario_ramp.yaml"))})
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    u_cr = FlightRuntime(config).critical_airspeed
    fixed = float(inputs["fixed_c2"])
    frequency = flutter_speed(model, config.scenario.density, damping=fixed).flutter_frequency
    names = args.cases.split(",")
    cases = [c for c in default_cases(frequency).values() if c.name in names]
    ramp = tuple(v / (1.0 if config.scenario.airspeed.relative else u_cr)
                 for v in config.scenario.airspeed.values)
    controllers = args.controllers.split(",")
    table = oracle_table(model, u_cr, config.scenario.density, cases, ramp) \
        if "oracle" in controllers else None
    made = {"fixed_c2": {"damping": fixed}, **{k: inputs[k] for k in ("schedule", "network")
                                               if inputs.get(k)}}
    setup = EvaluationSetup(
        config=config, model=model, critical_airspeed=u_cr,
        laws=evaluation_laws(controllers, made, config.damper, table),
        rms_range=(0.8 * u_cr, 1.05 * u_cr))
    return setup, cases


def _fly(setup, cases, seeds, controller: str, batch: bool):
    from dva_offline.evaluation.flights import fly_paired

    cpu = time.process_time()
    records, _ = fly_paired(setup, cases, seeds, (controller,), batch=batch)
    return records, time.process_time() - cpu


def _largest_difference(batched: dict, reference: dict) -> float:
    """Largest |a - b| / |b| over the float fields of the same flights (inf when anything
    else differs: a diverged flag, a NaN on one side only)."""
    largest = 0.0
    for key, ref in reference.items():
        got = batched[key]
        for name, value in ref.to_dict().items():
            other = got.to_dict()[name]
            if isinstance(value, float) and isinstance(other, float):
                if other != value:
                    largest = max(largest, abs(other - value) / abs(value))
            elif other != value:
                return math.inf
    return largest


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--reference-seeds", type=int, default=5)
    parser.add_argument("--cases", default="rho0,x0.9,x1.1,slow,1Hz,2f")
    parser.add_argument("--controllers", default=",".join(_default_controllers()))
    parser.add_argument("--network")
    parser.add_argument("--schedule")
    parser.add_argument("--fixed-c2", type=float)
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    if args.seeds < 1 or not 1 <= args.reference_seeds <= args.seeds:
        parser.error("--seeds >= 1 and 1 <= --reference-seeds <= --seeds")
    controllers = args.controllers.split(",")
    with tempfile.TemporaryDirectory(prefix="bench_evaluate_batch_") as tmp:
        inputs = {"fixed_c2": args.fixed_c2, "network": args.network,
                  "schedule": args.schedule}
        if args.fixed_c2 is None or ("rbf" in controllers and not args.network) or \
                ("schedule" in controllers and not args.schedule):
            made = _made_inputs(Path(tmp), args.cases, args.controllers)
            inputs = {"fixed_c2": args.fixed_c2 or made["fixed_c2"]["damping"],
                      "network": args.network or made.get("network"),
                      "schedule": args.schedule or made.get("schedule")}
        setup, cases = _setup(args, inputs)
        seeds = list(range(1, args.seeds + 1))
        rows, batched, reference = [], {}, {}
        for name in controllers:
            recs, cpu_batch = _fly(setup, cases, seeds, name, batch=True)
            batched.update({(r.controller, r.case, r.seed): r for r in recs})
            recs, cpu_ref = _fly(setup, cases, seeds[:args.reference_seeds], name, batch=False)
            reference.update({(r.controller, r.case, r.seed): r for r in recs})
            flights = len(cases) * len(seeds)
            scaled = cpu_ref * len(seeds) / args.reference_seeds
            rows.append({"controller": name, "flights": flights, "batched_cpu_s": cpu_batch,
                         "reference_cpu_s": cpu_ref,
                         "reference_flights": len(cases) * args.reference_seeds,
                         "reference_cpu_scaled_s": scaled})
            print(f"{name}: batched {cpu_batch:.2f} s CPU for {flights} flights; one at a time "
                  f"{cpu_ref:.2f} s for {len(recs)} (x{len(seeds) / args.reference_seeds:g}: "
                  f"{scaled:.1f} s)", file=sys.stderr, flush=True)
    spread = _largest_difference(batched, reference)
    total_b = sum(r["batched_cpu_s"] for r in rows)
    total_r = sum(r["reference_cpu_scaled_s"] for r in rows)
    flights = sum(r["flights"] for r in rows)
    print(f"\n`dva evaluate` flights: {len(cases)} cases x {len(controllers)} controllers x "
          f"{len(seeds)} seeds = {flights} flights; the one-flight route timed on "
          f"{args.reference_seeds} seeds and scaled; {os.cpu_count()} CPUs, load "
          f"{os.getloadavg()[0]:.1f} at the end")
    print("| controller | batched CPU s | one flight at a time CPU s (scaled) | ratio |")
    print("|---|---|---|---|")
    for r in rows:
        print(f"| {r['controller']} | {r['batched_cpu_s']:.2f} | "
              f"{r['reference_cpu_scaled_s']:.1f} | "
              f"{r['reference_cpu_scaled_s'] / r['batched_cpu_s']:.1f}x |")
    print(f"| all | {total_b:.2f} | {total_r:.1f} | {total_r / total_b:.1f}x |")
    print(f"target: the {flights} flights in at most 30 s of CPU: "
          f"{'met' if total_b <= 30.0 else 'not met'} ({total_b:.1f} s)")
    print(f"records of the {len(reference)} flights on both routes: largest relative "
          f"difference {spread:.1e} (required at most {RECORD_RTOL:.0e})")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "largest_relative_difference":
                                               spread, "load": os.getloadavg()[0]}, indent=1))
    return 0 if spread <= RECORD_RTOL else 1


if __name__ == "__main__":
    sys.exit(main())
