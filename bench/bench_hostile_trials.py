"""The hostile trials of issue 45 re-run from their descriptions: every class as processes,
with exit codes, last lines, peak memory and each class's own check.

Run: source scripts/env.sh && python bench/bench_hostile_trials.py [--trials N] [--seed S]
         [--only c2,zip bomb,...] [--json FILE]

Generators: bench/faults/hostile_trials.py (its docstring lists the classes and checks); the
in-process number fuzz over every field and parameter is bench/bench_input_fuzz.py --numbers,
the readers under a memory cap bench/bench_reader_memory.py. Prints one row per class
(trials, exit codes, trials that passed, largest peak resident memory) and every trial that
did not pass. ``--trials``: trials per class (default 40; the commander class, whose trials
are ROS flights, takes a quarter of it, at least 9).
"""
from __future__ import annotations

import argparse
import collections
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from bench.faults import hostile_trials as ht  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=40, help="trials per class")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", help="comma-separated classes of " + ", ".join(ht.CLASSES))
    parser.add_argument("--json", metavar="FILE", help="every trial, as JSON")
    args = parser.parse_args(argv)
    chosen = args.only.split(",") if args.only else list(ht.CLASSES)
    unknown = set(chosen) - set(ht.CLASSES)
    if unknown:
        parser.error(f"unknown classes {sorted(unknown)}")
    rng = np.random.default_rng(args.seed)
    trials, seconds = [], {}
    with tempfile.TemporaryDirectory(prefix="hostile_") as tmp:
        for cls in chosen:
            work = Path(tmp) / cls.replace(" ", "_")
            work.mkdir()
            n = max(9, args.trials // 4) if cls == "commander" else args.trials
            started = time.monotonic()
            for k, trial in enumerate(ht.GENERATORS[cls](work, rng, n)):
                trials.append(trial)
                print(f"  {cls} {k + 1}/{n}: {trial.name[:70]}: exit {trial.code}, "
                      f"{trial.peak / 2**20:.0f} MiB{'' if trial.ok else ' FAILED ' + trial.check}"
                      f" | {trial.last[:120]}", file=sys.stderr, flush=True)
            seconds[cls] = time.monotonic() - started
    print(f"{len(trials)} trials, seed {args.seed}, in {sum(seconds.values()):.0f} s")
    print("| class | trials | exit codes | passed | largest peak RSS [MiB] | seconds |")
    print("|---|---|---|---|---|---|")
    for cls in chosen:
        rows = [t for t in trials if t.cls == cls]
        codes = collections.Counter(t.code for t in rows)
        print(f"| {cls} | {len(rows)} | "
              + ", ".join(f"{c}: {n}" for c, n in sorted(codes.items(), key=str))
              + f" | {sum(t.ok for t in rows)} | {max(t.peak for t in rows) / 2**20:.0f} "
              f"| {seconds[cls]:.0f} |")
    failed = [t for t in trials if not t.ok]
    for t in failed:
        print(f"  failed: {t.cls}: {t.name}: exit {t.code} (expected {t.expected}); "
              f"{t.check}; last line: {t.last[:200]}")
    print(f"passed {len(trials) - len(failed)} of {len(trials)}; largest peak RSS "
          f"{max(t.peak for t in trials) / 2**20:.0f} MiB")
    if args.json:
        Path(args.json).write_text(json.dumps([{**t.__dict__, "ok": t.ok} for t in trials],
                                              indent=1, default=str))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
