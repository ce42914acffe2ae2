"""Benchmark of ``dva evaluate --workers N`` against one worker: the same campaign, timed whole.

Run (after ./test.sh or ./run.sh has set everything up)::

    source scripts/env.sh && python bench/bench_evaluate_workers.py [--runs 3] [--workers 2]
        [--seeds 10] [--cases rho0,x0.9,x1.1] [--controllers C1,C2,...]
        [--network FILE.npz] [--json FILE]

The default campaign is the one a user waits for: 4 controllers x 3 densities x 10 seeds = 120
flights. Its inputs (schedule, best fixed c2, network: trained unless ``--network`` is given)
are made once by an untimed ``dva evaluate`` and then given to every timed run, so the runs time
the evaluation itself: start-up, the oracle table, the flights, the summary and the plots.
Runs alternate one worker and ``--workers`` (the order flips each pair, so drift hurts both
alike); each pair gives a ratio of wall times. Prints each run, the median ratio with its
range, and checks that every run wrote the same records (``records.json``).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]



def _default_controllers() -> tuple[str, ...]:
    """What ``dva evaluate`` flies by default (the controller table's block-rate laws and
    references)."""
    from aero_dva.control.controllers import BLOCK, REFERENCE, names

    return names((BLOCK, REFERENCE), builtin_only=True)


def _dva(*args: str) -> list[str]:
    return [sys.executable, "-m", "dva_offline.cli", *args]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(argv: list[str]) -> tuple[dict, float, float]:
    """(the command's JSON, wall s, CPU s of it and its children)."""
    cpu0, t0 = _children_cpu(), time.perf_counter()
    result = subprocess.run(argv, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    if result.returncode != 0:
        tail = (result.stderr or result.stdout).strip().splitlines()[-3:]
        raise SystemExit(f"{' '.join(argv)} failed ({result.returncode}):\n" + "\n".join(tail))
    return json.loads(result.stdout), wall, cpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=3, help="pairs of runs (default 3)")
    parser.add_argument("--workers", type=int, default=2, help="workers of the parallel run")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--cases", default="rho0,x0.9,x1.1")
    parser.add_argument("--controllers", default=",".join(_default_controllers()))
    parser.add_argument("--network", help="RBF network (default: trained once, untimed)")
    parser.add_argument("--json", help="write every run here")
    args = parser.parse_args()
    if args.runs < 1 or args.workers < 2 or args.seeds < 1:
        parser.error("--runs >= 1, --workers >= 2 and --seeds >= 1")

    with tempfile.TemporaryDirectory(prefix="bench_evaluate_") as tmp:
        tmp = Path(tmp)
        common = ["--cases", args.cases, "--controllers", args.controllers,
                  "--no-boundaries", "--json"]
        prep = ["evaluate", "--out", str(tmp / "prep"), "--seeds", "1", *common]
        if args.network:
            prep += ["--network", args.network]
        print("making the inputs (untimed) ...", file=sys.stderr, flush=True)
        made, wall, _ = _run(_dva(*prep))
        print(f"inputs made in {wall:.0f} s: {made['inputs']}", file=sys.stderr)
        given = ["--fixed-c2", repr(made["fixed_c2"])]
        if "schedule" in made["inputs"]:
            given += ["--schedule", made["inputs"]["schedule"]]
        if "network" in made["inputs"]:
            given += ["--network", made["inputs"]["network"]]

        runs, records = [], {}
        for pair in range(args.runs):
            order = (1, args.workers) if pair % 2 == 0 else (args.workers, 1)
            for workers in order:
                out = tmp / f"run{pair}_w{workers}"
                payload, wall, cpu = _run(_dva(
                    "evaluate", "--out", str(out), "--seeds", str(args.seeds), *common, *given,
                    "--workers", str(workers)))
                records[(pair, workers)] = (out / "records.json").read_text()
                runs.append({"pair": pair, "workers": workers, "wall_s": wall, "cpu_s": cpu,
                             "flight_wall_s": payload["flight_wall_time_s"],
                             "flights": payload["flights"]})
                print(f"pair {pair} workers {workers}: {wall:.2f} s wall ({cpu:.2f} s CPU, "
                      f"flights {payload['flight_wall_time_s']:.2f} s, {payload['flights']} "
                      f"flights)", file=sys.stderr, flush=True)

    identical = len(set(records.values())) == 1
    spread = _largest_relative_difference([json.loads(r) for r in records.values()])
    agree = spread <= RECORD_RTOL
    by = {(r["pair"], r["workers"]): r for r in runs}
    ratios = [by[(p, 1)]["wall_s"] / by[(p, args.workers)]["wall_s"] for p in range(args.runs)]
    flight_ratios = [by[(p, 1)]["flight_wall_s"] / by[(p, args.workers)]["flight_wall_s"]
                     for p in range(args.runs)]

    def med(workers, key):
        return statistics.median(r[key] for r in runs if r["workers"] == workers)

    print(f"\ncampaign: {runs[0]['flights']} flights ({args.controllers} x {args.cases} x "
          f"{args.seeds} seeds), {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the end")
    print("| workers | wall s (median) | CPU s | flights wall s |")
    print("|---|---|---|---|")
    for w in (1, args.workers):
        print(f"| {w} | {med(w, 'wall_s'):.2f} | {med(w, 'cpu_s'):.2f} | "
              f"{med(w, 'flight_wall_s'):.2f} |")
    print(f"speed-up (one worker / {args.workers}, paired): median "
          f"{statistics.median(ratios):.2f}x (range {min(ratios):.2f}..{max(ratios):.2f}); "
          f"flights alone {statistics.median(flight_ratios):.2f}x")
    print(f"records identical in all {len(records)} runs: {identical}; largest relative "
          f"difference {spread:.1e} (agreement required: {RECORD_RTOL:.0e})")
    if args.json:
        Path(args.json).write_text(json.dumps({"runs": runs, "ratios": ratios,
                                               "flight_ratios": flight_ratios,
                                               "identical": identical,
                                               "largest_relative_difference": spread},
                                              indent=1))
    return 0 if agree else 1


# Flights on other processes can differ in the last bits (BLAS SIMD paths depend on memory
# alignment); tests/unit/dva_offline/test_evaluation_batch.py compares records to this tolerance.
RECORD_RTOL = 1e-9


def _largest_relative_difference(runs: list[list[dict]]) -> float:
    """Largest |a - b| / |b| over the float fields of every run's records against the first's
    (inf when the runs differ in anything else)."""
    first, largest = runs[0], 0.0
    for other in runs[1:]:
        if len(other) != len(first):
            return math.inf
        for a, b in zip(other, first, strict=True):
            for key, value in b.items():
                if isinstance(value, float) and isinstance(a.get(key), float):
                    if a[key] != value:
                        largest = max(largest, abs(a[key] - value) / abs(value))
                elif a.get(key) != value:
                    return math.inf
    return largest


if __name__ == "__main__":
    sys.exit(main())
