"""Generated bad files through every loader of the tools: how many are accepted, refused in one
line (exit 2), or fail otherwise (an internal error or a traceback; the target is 0).

Run: python bench/bench_input_fuzz.py [--examples 1000] [--loader NAME ...]

Hypothesis draws the files (random bytes, damaged valid files, numbers at the float limits,
nesting up to 5,000 levels, random .npz array shapes; bench/faults/input_fuzz.py) from a fixed
seed (derandomize), so two runs draw the same files. Prints one row per loader and the
failures found, with a sample message of each kind.
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=1000, help="examples per loader")
    parser.add_argument("--loader", action="append", help="only these loaders (repeatable)")
    args = parser.parse_args(argv)
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
