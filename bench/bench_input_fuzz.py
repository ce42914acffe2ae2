"""Generated bad files through every loader of the tools: how many are accepted, refused in one
line (exit 2), or fail otherwise (an internal error or a traceback; the target is 0).

Run: python bench/bench_input_fuzz.py [--examples 1000] [--loader NAME ...]
     source scripts/env.sh && python bench/bench_input_fuzz.py --numbers [--json FILE]

Hypothesis draws the files (random bytes, damaged valid files, numbers at the float limits,
nesting up to 5,000 levels, random .npz array shapes; bench/faults/input_fuzz.py) from a fixed
seed (derandomize), so two runs draw the same files. Prints one row per loader and the
failures found, with a sample message of each kind.

``--numbers``: physically absurd numbers instead (bench/faults/number_fuzz.py): every numeric
field of every input file and every numeric node parameter, each given a zero, a negative, a
small (1e-4), a tiny (1e-300), a subnormal, a large (1e9), a huge (1e300), a NaN and an
infinite value, through what uses it (the command, or the node's start and first blocks), and
the issue's node starts as processes; one row per input and value class, and every trial that
ended other than accepted or refused in one line. Runs under a 4 GiB address-space cap.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402

from bench.faults import input_fuzz  # noqa: E402


def run_loader(loader, examples: int, directory: Path) -> input_fuzz.Tally:
    tally = input_fuzz.Tally()

    @settings(max_examples=examples, derandomize=True, deadline=None, database=None,
              phases=(Phase.generate,), suppress_health_check=list(HealthCheck))
    @given(content=input_fuzz.inputs(loader))
    def one(content):
        outcome = input_fuzz.try_loader(loader, content, directory)
        if outcome is None:
            tally.accepted += 1
        elif outcome == "refused":
            tally.refused += 1
        else:
            kind = outcome.split(":")[0]
            tally.failures[kind] += 1
            tally.samples.setdefault(outcome[:90], len(tally.samples))

    one()
    return tally


def numbers(json_out: str | None) -> int:
    """The ``--numbers`` table (module docstring)."""
    import collections
    import json
    import resource
    import warnings

    from bench.faults import number_fuzz

    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    warnings.simplefilter("ignore")
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="number_fuzz_") as tmp:
        work = Path(tmp)
        trials = list(number_fuzz.file_trials(work)) + list(number_fuzz.parameter_trials(work))
        try:
            trials += list(number_fuzz.node_start_trials(work))
        except ImportError:
            print("(node starts left out: source scripts/env.sh for the ROS environment)")
    classes = list(number_fuzz.CLASSES) + ["start"]
    outcomes = ("accepted", "refused", "internal", "timeout", "memory")
    print(f"{len(trials)} trials in {time.monotonic() - started:.0f} s")
    print("| input | fields | trials | " + " | ".join(outcomes) + " |")
    print("|---|---|---|" + "---|" * len(outcomes))
    kinds = dict.fromkeys(t.kind for t in trials)
    for kind in kinds:
        rows = [t for t in trials if t.kind == kind]
        count = collections.Counter(t.outcome for t in rows)
        print(f"| {kind} | {len({t.field for t in rows})} | {len(rows)} | "
              + " | ".join(str(count[o]) for o in outcomes) + " |")
    print("\n| value class | trials | " + " | ".join(outcomes) + " |")
    print("|---|---|" + "---|" * len(outcomes))
    for label in classes:
        rows = [t for t in trials if t.value_class == label]
        if rows:
            count = collections.Counter(t.outcome for t in rows)
            print(f"| {label} | {len(rows)} | " + " | ".join(str(count[o]) for o in outcomes)
                  + " |")
    bad = [t for t in trials if t.outcome not in ("accepted", "refused")]
    for t in bad:
        print(f"  {t.outcome}: {t.kind} {t.field} = {t.value_class}: {t.message[:200]}")
    print(f"not accepted or refused in one line: {len(bad)} of {len(trials)}")
    if json_out:
        Path(json_out).write_text(json.dumps([t.__dict__ for t in trials], indent=1))
    return 1 if bad else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=1000, help="examples per loader")
    parser.add_argument("--loader", action="append", help="only these loaders (repeatable)")
    parser.add_argument("--numbers", action="store_true",
                        help="physically absurd numbers in every numeric field and parameter")
    parser.add_argument("--json", metavar="FILE", help="--numbers: every trial, as JSON")
    args = parser.parse_args(argv)
    if args.numbers:
        return numbers(args.json)
    chosen = {n: ld for n, ld in input_fuzz.loaders().items()
              if not args.loader or n in args.loader}
    print(f"{'loader':22s} {'examples':>8s} {'accepted':>8s} {'refused':>8s} {'failures':>8s} "
          f"{'seconds':>8s}")
    total_failures = 0
    samples = []
    with tempfile.TemporaryDirectory(prefix="input_fuzz_") as tmp:
        for name, loader in chosen.items():
            directory = Path(tmp) / name.replace(" ", "_")
            directory.mkdir()
            started = time.monotonic()
            tally = run_loader(loader, args.examples, directory)
            seconds = time.monotonic() - started
            failures = sum(tally.failures.values())
            total_failures += failures
            samples += [f"{name}: {s}" for s in tally.samples]
            print(f"{name:22s} {tally.examples:8d} {tally.accepted:8d} {tally.refused:8d} "
                  f"{failures:8d} {seconds:8.1f}", flush=True)
    for sample in samples[:40]:
        print("  failure:", sample)
    print(f"failures: {total_failures}")
    return 1 if total_failures else 0


if __name__ == "__main__":
    sys.exit(main())
