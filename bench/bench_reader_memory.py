"""Every bag reader on bags built to exhaust memory: outcome and peak resident memory.

Run: python bench/bench_reader_memory.py [--cap GIB] [--expanded GIB]

Builds (bench/faults/resource_bombs.py) a valid flight bag and hostile ones: a zstd chunk of
80 KB that expands to 2.5 GiB (declaring that size, declaring 1 MiB, with and without the
content size in its frame), an lz4 chunk of 1 GiB of zeros, 200 valid chunks of 1 MiB all
spanning the same log times, and a metadata.yaml listing its file 2000 times. Runs every reader
of resource_bombs.READERS on each, all in one child process under resource.setrlimit(RLIMIT_AS)
of --cap GiB (default 1; 0 for none), and prints one row per (bag, reader): the outcome
("read": it returned; "refused": one line, exit 2; "memory": the cap was reached; "crashed")
and the peak resident memory (VmHWM, reset before each reader: an upper bound, since Python
keeps what it freed).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.faults import resource_bombs as rb  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cap", type=float, default=1.0, help="GiB of address space (0: none)")
    parser.add_argument("--expanded", type=float, default=2.5,
                        help="GiB the zstd bomb expands to (default 2.5)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        started = time.monotonic()
        size = int(args.expanded * rb.GiB)
        bags = {"valid": rb.valid_bag(root / "valid"),
                "zstd bomb": rb.bomb_bag(root / "bomb", size),
                "zstd bomb, 1 MiB declared": rb.bomb_bag(root / "lie", size, declared=2**20),
                "zstd bomb, no content size": rb.bomb_bag(root / "nosize", size,
                                                          declared=2**20, content_size=False),
                "lz4 bomb": rb.lz4_bomb_bag(root / "lz4"),
                "overlapping chunks": rb.overlap_bag(root / "overlap"),
                "file listed 2000 times": rb.listed_bag(root / "listed")}
        made = time.monotonic() - started
        names = {str(b): n for n, b in bags.items()}
        runs = rb.run_capped([(r, b) for b in bags.values() for r in rb.READERS],
                             int(args.cap * rb.GiB))
        print(f"bags made in {made:.1f} s, read in {time.monotonic() - started - made:.1f} s; "
              f"cap {args.cap:g} GiB of address space")
        print("| bag | file bytes | reader | outcome | peak memory [MiB] | last line |")
        print("|---|---|---|---|---|---|")
        for r in runs:
            bag = Path(r.bag)
            nbytes = sum(f.stat().st_size for f in bag.iterdir())
            line = r.line.replace(str(root), "TMP").replace("|", "/")[:140]
            print(f"| {names[r.bag]} | {nbytes:,} | {r.reader} | {r.outcome} | "
                  f"{r.peak / 2**20:.0f} | {line} |")
        worst = max(r.peak for r in runs)
        bad = [r for r in runs if r.outcome in ("memory", "crashed")]
        print(f"largest peak {worst / 2**20:.0f} MiB; reached the cap or crashed: {len(bad)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
