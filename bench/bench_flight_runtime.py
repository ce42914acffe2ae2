"""Benchmark: the flight runtime's step per block (the simulator node's NumPy stepping), this
tree against an earlier revision in the same run, with their records compared bit for bit.

Run::

    source scripts/env.sh && python bench/bench_flight_runtime.py [--base REV] [--repeats 5]

Each revision flies in a child process of its own (REV checked out into a temporary git
worktree, its packages first on PYTHONPATH), the two in turns, ``--repeats`` times each:

- **schedule:** the 30 s ramp with a linear c2(U) schedule commanded every block, as the
  schedule law does in the node graph's lockstep flight: the c2 changes every block, so every
  block has a new held condition and its maps are built anew;
- **held:** the same flight uncommanded (the start-up c2 held: a new condition only when the
  airspeed has moved by the flight quantum).

Each process flies the flight twice: the first flight is the simulator node's case (a new
process), the second shows what is left once everything is loaded. Prints the best wall time
per block of each on each side and their ratios (this tree / base), and whether every block's
arrays (displacements, accelerations, airspeed, density, c2, force, divergence and the damper
state flown) are bit-identical on the two sides and in every flight (a SHA-256 over their
bytes). Without ``--base`` this tree alone (as ``bench/compare_revisions.py`` runs it). Exit 1
when the records differ.
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from compare_revisions import REPO, base_worktree, python_path  # noqa: E402

FLIGHTS = ("schedule", "held")


def schedule_c2(airspeed: float) -> float:
    """[N s/m] the c2 commanded at ``airspeed`` [m/s]: a linear schedule clipped to the
    damper's range, of the size the fitted schedule gives the reference wing."""
    return min(2500.0, max(0.0, -1059.7 + 14.6343 * airspeed))


def fly(kind: str) -> tuple[float, int, str]:
    """(wall s, blocks, SHA-256 of every block's arrays) of one flight from a new runtime."""
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    runtime = FlightRuntime(load_runtime_config({}))
    u0, u1 = runtime.scenario.airspeed.values
    duration = runtime.scenario.duration
    blocks, record = [], hashlib.sha256()
    started = time.perf_counter()
    while not runtime.done:
        if kind == "schedule":
            runtime.command(schedule_c2(u0 + (u1 - u0) * runtime.time / duration), "schedule")
        block = runtime.step()
        blocks.append((block, runtime.flown_damper))
        if block.diverged:
            break
    wall = time.perf_counter() - started
    for block, flown in blocks:  # hashed after the clock: the record, not its cost
        for name in ("displacements", "accelerations", "airspeed", "density", "damping",
                     "force"):
            record.update(getattr(block, name).tobytes())
        record.update(repr((block.first_index, bool(block.diverged), flown)).encode())
    return wall, len(blocks), record.hexdigest()


def child(kind: str) -> None:
    """Fly ``kind`` twice in this process; print JSON: the wall per block of the first flight
    (a new process, as the simulator node's) and of the second, the blocks and the record."""
    import aero_dva

    runs = [fly(kind) for _ in range(2)]
    print(json.dumps({"first": runs[0][0] / runs[0][1], "again": runs[1][0] / runs[1][1],
                      "blocks": runs[0][1],
                      "record": runs[0][2] if runs[0][2] == runs[1][2] else "unrepeatable",
                      "package": aero_dva.__file__}))


def run_child(tree: Path, kind: str) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = ":".join(python_path(tree) + [env.get("PYTHONPATH", "")]).rstrip(":")
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", kind],
                         env=env, cwd=tree, check=True, capture_output=True, text=True).stdout
    got = json.loads(out.strip().splitlines()[-1])
    if not Path(got["package"]).is_relative_to(tree):  # the revision's own code, or nothing
        raise RuntimeError(f"{tree} flew {got['package']}")
    return got


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", help="the earlier revision (commit, tag) to compare with")
    parser.add_argument("--repeats", type=int, default=5,
                        help="flights per side and kind, in turns (best taken; default 5)")
    parser.add_argument("--child", choices=FLIGHTS, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    if args.child:
        child(args.child)
        return 0
    print(f"load average {os.getloadavg()[0]:.2f} (the wall clock measures any sharing too)")
    sides = {"now": REPO}
    with contextlib.ExitStack() as stack:
        if args.base is not None:
            sides = {"base": stack.enter_context(base_worktree(args.base)), "now": REPO}
        runs: dict = {(side, kind): [] for side in sides for kind in FLIGHTS}
        for _ in range(args.repeats):  # one process per side and kind, the sides in turns
            for kind in FLIGHTS:
                for side, tree in sides.items():
                    runs[side, kind].append(run_child(tree, kind))
    names = {"base": args.base, "now": "this tree"}
    print(f"{' vs '.join(names[side] for side in sides)}: best of {args.repeats} processes, "
          "each flying the flight twice (first, again) [ms per block]")
    columns = [(side, which) for side in sides for which in ("first", "again")]
    head = "".join(f" {side + ' ' + which:>12s}" for side, which in columns)
    if "base" in sides:
        head += f" {'now/base':>8s} {'again':>6s}"
    print(f"{'flight':9s}{head} {'blocks':>7s}  records")
    same = True
    for kind in FLIGHTS:
        best = {(side, which): min(r[which] for r in runs[side, kind]) for side, which in columns}
        records = {(r["record"], r["blocks"]) for side in sides for r in runs[side, kind]}
        equal = len(records) == 1 and "unrepeatable" not in next(iter(records))
        same &= equal
        row = "".join(f" {best[column] * 1e3:12.4f}" for column in columns)
        if "base" in sides:
            row += (f" {best['now', 'first'] / best['base', 'first']:8.3f}"
                    f" {best['now', 'again'] / best['base', 'again']:6.3f}")
        label = ("bit-identical" if "base" in sides else "repeatable") if equal else "DIFFER"
        print(f"{kind:9s}{row} {runs['now', kind][0]['blocks']:7d}  {label}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
