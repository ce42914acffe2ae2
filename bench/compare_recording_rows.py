"""Recording rows of bench_batch_recording / bench_sweep_recording: earlier revision vs now.

    source scripts/env.sh && python bench/compare_recording_rows.py --base REV \
        [--runs 5] BENCH [BENCH ARGS...]

compare_revisions.py times whole benchmark processes; this compares what the two recording
benchmarks print per path (their wall and CPU columns), so that work a newer benchmark adds
(more rows, a warm-up) does not count. Checks out REV into a temporary git worktree, runs BENCH
alternately on REV and on this tree ``--runs`` times each with the same arguments (the earlier
revision's aero_dva/ and offline/ first on PYTHONPATH), and prints per row the medians and
their ratio (this tree / base): below 1 is faster. CPU time is the figure to trust on a loaded
machine. Example: ``compare_recording_rows.py --base main bench_sweep_recording --airspeeds 40
--stepped-airspeeds 1``.
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

from compare_revisions import base_worktree, python_path  # a script beside this one

REPO = Path(__file__).resolve().parents[1]
# Row label, then: bench_batch_recording "blocks sim wall cpu ...", bench_sweep_recording
# "sim wall cpu ...".
ROW = re.compile(r"^\s*(record: [^\d]+?|/dev/shm: [^\d]+?|dict|rosbags|bagwriter|numpy|samples"
                 r"|samples-nocrc|rosbags Reader|load_flight_log)\s+(\d+)\s+([\d.]+)"
                 r"(?:\s+([\d.]+))?(?:\s+([\d.]+))?")
# Columns (wall, cpu) of a row; bench_flight_log_read times CPU only.
COLUMNS = {"bench_batch_recording": (4, 5), "bench_sweep_recording": (3, 4),
           "bench_flight_log_read": (None, 3)}
START_UP = re.compile(r"^start-up cost: (-?[\d.]+) s CPU")


def rows(output: str, bench: str) -> dict[str, tuple[float, float]]:
    wall, cpu = COLUMNS[bench]
    found = {}
    for line in output.splitlines():
        match = ROW.match(line)
        if match:
            found[match.group(1).strip()] = (
                float(match.group(wall)) if wall else float("nan"), float(match.group(cpu)))
        match = START_UP.match(line)
        if match:  # CPU only
            found["start-up (first recording)"] = (float("nan"), float(match.group(1)))
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="the earlier revision (commit, tag)")
    parser.add_argument("--runs", type=int, default=5, help="runs per side (default 5)")
    parser.add_argument("--same-script", action="store_true",
                        help="run this tree's benchmark script on both sides (for a script "
                             "that uses only APIs both revisions have)")
    parser.add_argument("bench", choices=sorted(COLUMNS))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="arguments of the benchmark")
    args = parser.parse_args(argv)
    with base_worktree(args.base) as base_dir:
        found: dict[str, dict[str, list]] = {}
        for _ in range(args.runs):
            for side, tree in (("base", base_dir), ("now", REPO)):
                env = dict(os.environ)
                paths = python_path(tree) if side == "base" else []
                env["PYTHONPATH"] = ":".join([*paths, env.get("PYTHONPATH", "")])
                script = (REPO if args.same_script else tree) / "bench" / f"{args.bench}.py"
                env["PYTHONPATH"] = ":".join([str(script.parent), env["PYTHONPATH"]])
                out = subprocess.run([sys.executable, str(script), *args.args], cwd=tree,
                                     env=env, capture_output=True, text=True,
                                     check=True).stdout
                for name, value in rows(out, args.bench).items():
                    found.setdefault(name, {"base": [], "now": []})[side].append(value)
        print(f"{args.bench} {' '.join(args.args)}: base {args.base} vs this tree, "
              f"{args.runs} alternating runs each, medians")
        print(f"{'row':<32}{'wall base':>10}{'wall now':>10}{'ratio':>7}"
              f"{'cpu base':>10}{'cpu now':>10}{'ratio':>7}")
        for name, sides in found.items():
            if not (sides["base"] and sides["now"]):
                continue
            (wb, cb), (wn, cn) = [[statistics.median(v[i] for v in sides[s]) for i in (0, 1)]
                                  for s in ("base", "now")]
            walls = f"{wb:10.3f}{wn:10.3f}{wn / wb:7.3f}" if wb == wb else f"{'':27}"
            ratio = f"{cn / cb:7.3f}" if cb > 0 else f"{'-':>7}"
            print(f"{name:<32}{walls}{cb:10.3f}{cn:10.3f}{ratio}")
        return 0


if __name__ == "__main__":
    sys.exit(main())
