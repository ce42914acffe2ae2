"""Does a graph flight give the same record idle and loaded? The README's schedule flight, N times.

Run: ``source scripts/env.sh && python bench/bench_flight_determinism.py [--idle 10]
[--loaded 20] [--at-once 2] [--busy 2] [--json FILE] [--keep DIR]``

Fits the airspeed schedule as ``./run.sh`` does (``dva control schedule``), flies the study's
ramp through ``run_flight --controller schedule`` ``--idle`` times one after the other, then
``--loaded`` times, ``--at-once`` flights at a time beside ``--busy`` CPU-bound processes, and
compares each flight's record (divergence, leading-edge RMS, mean applied c2, commands recorded)
with the first idle one, digit for digit. A flight either gives that record or fails (exit code
non-zero, with its reason); the table counts both.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

RECORD = ("divergence_ratio", "leading_edge_rms", "mean_damping", "commands_recorded")
APPLIED = ("blocks", "blocks_startup", "blocks_fallback", "commands_received",
           "commands_expected", "controller_wait_timeouts")
BUSY_LOOP = "while True:\n    pass\n"


def run_flight_path() -> str:
    from aero_dva_sim.run_flight import executable

    return executable("aero_dva_sim", "run_flight")


def fly(run_flight: str, schedule: Path, out: Path, extra: list[str]) -> dict:
    """One run_flight; its exit code, record, applied-control counts and wall time."""
    started = time.monotonic()
    result = subprocess.run([run_flight, "--controller", "schedule", "--schedule", str(schedule),
                             "--output", str(out), "--json", *extra],
                            capture_output=True, text=True, timeout=1800)
    flight = {"code": result.returncode, "wall_s": time.monotonic() - started,
              "error": (result.stderr.strip().splitlines() or [""])[-1]}
    try:
        summary = json.loads(result.stdout)
    except json.JSONDecodeError:
        return flight
    flight.update({k: summary.get(k) for k in RECORD + APPLIED})
    flight["flight_wall_s"] = summary.get("flight_wall_time")
    return flight


def record(flight: dict) -> tuple | None:
    """The flight's record, exact (None: the flight failed or printed no summary)."""
    if flight["code"] != 0 or "mean_damping" not in flight:
        return None
    return tuple(repr(flight[k]) for k in RECORD)


def fly_many(run_flight, schedule, root: Path, name: str, count: int, at_once: int,
             extra: list[str]) -> list[dict]:
    with ThreadPoolExecutor(max_workers=at_once) as pool:
        futures = [pool.submit(fly, run_flight, schedule, root / f"{name}_{i:02d}", extra)
                   for i in range(count)]
        flights = []
        for i, future in enumerate(futures):
            flights.append(future.result())
            f = flights[-1]
            print(f"  {name} {i + 1:2d}/{count}: exit {f['code']}, record {record(f)}, "
                  f"start-up {f.get('blocks_startup')}, fallback {f.get('blocks_fallback')}, "
                  f"{f['wall_s']:.1f} s wall" + (f"  [{f['error']}]" if f["code"] else ""),
                  flush=True)
    return flights


def load_average() -> float:
    return os.getloadavg()[0]


def table(phases: dict, reference: tuple | None) -> str:
    rows = ["| flights | at once | busy loops | exit 0 | failed (reason) | identical to the "
            "idle record | other records | blocks on start-up c2 | blocks on fallback | "
            "wall per flight [s]: median | load average |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for phase in phases.values():
        flights = phase["flights"]
        ok = [f for f in flights if f["code"] == 0]
        failed = [f for f in flights if f["code"] != 0]
        same = sum(record(f) == reference for f in ok)
        others = sorted({record(f) for f in ok if record(f) != reference})
        reasons = sorted({f["error"] for f in failed})
        walls = sorted(f["wall_s"] for f in flights)
        startup = sorted({f.get("blocks_startup") for f in ok})
        fallback = sorted({f.get("blocks_fallback") for f in ok})
        rows.append(
            f"| {len(flights)} | {phase['at_once']} | {phase['busy']} | {len(ok)} | "
            f"{len(failed)}{' (' + '; '.join(reasons) + ')' if reasons else ''} | "
            f"{same} | {len(others)}{' ' + str(others) if others else ''} | "
            f"{', '.join(map(str, startup))} | {', '.join(map(str, fallback))} | "
            f"{walls[len(walls) // 2]:.1f} | {phase['load'][0]:.1f}-{phase['load'][1]:.1f} |")
    return "\n".join(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--idle", type=int, default=10, help="flights one after the other")
    parser.add_argument("--loaded", type=int, default=20, help="flights beside the busy loops")
    parser.add_argument("--at-once", type=int, default=2, help="loaded flights at a time")
    parser.add_argument("--busy", type=int, default=2, help="CPU-bound processes beside them")
    parser.add_argument("--extra", default="", help="more run_flight arguments (one string)")
    parser.add_argument("--json", default=None, help="write every flight's numbers here")
    parser.add_argument("--keep", default=None, help="keep the bags in this directory")
    args = parser.parse_args(argv)

    run_flight = run_flight_path()
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="determinism_"))
    root.mkdir(parents=True, exist_ok=True)
    schedule = root / "schedule.json"
    subprocess.run(["dva", "control", "schedule", "--out", str(schedule)], check=True,
                   capture_output=True)
    extra = args.extra.split()
    phases = {}
    try:
        print(f"idle: {args.idle} flights one after the other", flush=True)
        load0 = load_average()
        flights = fly_many(run_flight, schedule, root, "idle", args.idle, 1, extra)
        phases["idle"] = {"flights": flights, "at_once": 1, "busy": 0,
                          "load": (load0, load_average())}
        busy = [subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) for _ in range(args.busy)]
        try:
            print(f"loaded: {args.loaded} flights, {args.at_once} at once, beside {args.busy} "
                  "busy loops", flush=True)
            load0 = load_average()
            flights = fly_many(run_flight, schedule, root, "loaded", args.loaded, args.at_once,
                               extra)
            phases["loaded"] = {"flights": flights, "at_once": args.at_once, "busy": args.busy,
                                "load": (load0, load_average())}
        finally:
            for process in busy:
                process.kill()
                process.wait()
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    reference = next((record(f) for f in phases["idle"]["flights"] if record(f)), None)
    print(f"\nreference (first idle flight that succeeded): {dict(zip(RECORD, reference or ()))}")
    print(table(phases, reference))
    if args.json:
        Path(args.json).write_text(json.dumps({"reference": reference, "phases": phases},
                                              indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
