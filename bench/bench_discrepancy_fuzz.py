"""Fuzz of ``dva discrepancy frf`` and ``modal`` with random tables at real scales.

Usage::

    PYTHONPATH=offline python bench/bench_discrepancy_fuzz.py [--files N] [--seed S]
        [--max-steps K] [--log FILE.jsonl]

N random tables (default 200, seed S = 2000: a seed the CI test does not use) from
:mod:`dva_offline.discrepancy.fuzz_tables` (moduli 1e4..1e10 Pa, receptances 1e-9..1e-2 m/N,
0.01 Hz..10 kHz), each through every command that reads its quantity
(:func:`~dva_offline.discrepancy.fuzz_run.commands`). Prints the count of each outcome
(verdict / input error / internal exception) and every internal exception; exit code 1 if
there was one. Not a timed test.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from dva_offline.discrepancy.fuzz_run import commands, run_table
from dva_offline.discrepancy.fuzz_tables import random_table


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--files", type=int, default=200)
    p.add_argument("--seed", type=int, default=2000)
    p.add_argument("--max-steps", type=int, default=2)
    p.add_argument("--log", type=Path)
    args = p.parse_args()
    rng = np.random.default_rng(args.seed)
    counts, verdicts, internal = Counter(), Counter(), []
    log = args.log.open("w") if args.log else None
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.files):
            table = random_table(rng)
            for command in commands(table):
                path = Path(tmp) / f"fuzz_{i}.csv"
                outcome, detail = run_table(table, path, command,
                                            ("--max-steps", str(args.max_steps)))
                counts[outcome] += 1
                if outcome == "verdict":
                    verdicts[f"{command} {detail.split(' ->')[0]}"] += 1
                if outcome == "internal":
                    internal.append((i, table.quantity, command, detail))
                    print(f"file {i} ({table.quantity}, {command}): {detail}", flush=True)
                if log:
                    log.write(json.dumps({"file": i, "quantity": table.quantity,
                                          "command": command, "outcome": outcome,
                                          "detail": detail}) + "\n")
                    log.flush()
    print(f"{args.files} files, {sum(counts.values())} runs: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    print("verdicts: " + ", ".join(f"{k} {v}" for k, v in sorted(verdicts.items())))
    return 1 if internal else 0


if __name__ == "__main__":
    sys.exit(main())
