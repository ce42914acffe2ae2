"""Benchmark of bit flips in a closed bag: what `dva bag info` says and `dva bag recover` keeps.

Run (after ./run.sh has written a main-job bag)::

    .venv/bin/python bench/bench_bag_damage.py [--bag runs/main_<time>] [--copies 20]
        [--max-flips 20] [--seed 1] [--json FILE]

Each copy of the bag gets 1..max-flips bits flipped at uniformly random byte offsets of the
MCAP file (whatever part they land in: header, chunks, message indexes, summary). For each
copy, both commands run as a user runs them (``python -m dva_offline.cli``); the recovered bag
is read back with ``mcap``'s reader (CRCs validated) and set against the oracle of
``bench.faults.bit_flips``: the intact bag's messages of every chunk that still passes its CRC
in the copy (found at the intact file's offsets). Prints one markdown row per copy and a total
(docs/reliability.md holds them).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.faults.bit_flips import (  # noqa: E402
    PARTS,
    expected_messages,
    flip_copy,
    layout,
    random_offsets,
    read_checked,
)


def _dva(*args: str) -> tuple[int, str, float]:
    t0 = time.perf_counter()
    result = subprocess.run([sys.executable, "-m", "dva_offline.cli", *args],
                            capture_output=True, text=True, timeout=600)
    return result.returncode, result.stdout, time.perf_counter() - t0


def _newest_main_bag() -> Path:
    found = sorted(Path("runs").glob("main_*/metadata.yaml"))
    if not found:
        raise SystemExit("bench_bag_damage: no runs/main_*/ bag: run ./run.sh first or pass --bag")
    return found[-1].parent


def trial(bag: Path, mcap: Path, lay, flips, work: Path) -> dict:
    copy = flip_copy(bag, flips, work / "flipped")
    expected, valid = expected_messages(mcap, copy / mcap.name, lay)
    code_info, out_info, wall_info = _dva("bag", "info", str(copy), "--json")
    info = json.loads(out_info) if code_info == 0 else {}
    code, out, wall = _dva("bag", "recover", str(copy), "--out", str(work / "new"), "--json")
    result = json.loads(out) if code in (0, 1) else {}  # 1: written, messages lost
    kept = read_checked(work / "new") if code in (0, 1) else []
    times = [m[1] for m in kept]
    kept_count = Counter(kept)
    intact = Counter(read_checked(bag))
    return {
        "flips": len(flips),
        "parts": dict(Counter(lay.part(o) for o, _ in flips)),
        "chunks": len(lay.chunks), "valid_chunks": valid,
        "expected": sum(expected.values()),
        "kept": len(kept),
        "expected_kept": sum((expected & kept_count).values()),
        "missing": sum((expected - kept_count).values()),
        "not_in_intact": sum((kept_count - intact).values()),
        "log_time_order": all(a <= b for a, b in zip(times, times[1:])),
        "recover_exit": code, "info_exit": code_info,
        "info_damaged": bool(info.get("damaged")), "ranges": len(info.get("damaged", [])),
        "reported_lost": result.get("lost"),
        "true_lost": sum(intact.values()) - len(kept),
        "wall_info_s": wall_info, "wall_recover_s": wall,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bag", type=Path, default=None)
    parser.add_argument("--copies", type=int, default=20)
    parser.add_argument("--max-flips", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    bag = args.bag or _newest_main_bag()
    (mcap,) = bag.glob("*.mcap")
    lay = layout(mcap)
    total = sum(Counter(read_checked(bag)).values())
    sizes = {p: sum(b - a for a, b in lay.ranges(p)) for p in PARTS}
    print(f"bag {bag}: {mcap.stat().st_size} bytes, {len(lay.chunks)} chunks, {total} "
          "messages; bytes per part: " + ", ".join(f"{p} {n}" for p, n in sizes.items()))
    rng = np.random.default_rng(args.seed)
    rows = []
    print("| copy | flips (header/chunk/index/summary) | CRC-valid chunks | messages in them | "
          "kept of those (byte-identical) | kept, not in the intact bag | log-time order | "
          "`info` says damaged (ranges) | `recover` exit | lost: reported / true |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for k in range(args.copies):
        n = int(rng.integers(1, args.max_flips + 1))
        flips = random_offsets(rng, [(0, lay.size)], n)
        with tempfile.TemporaryDirectory(prefix="bag_damage_") as tmp:
            row = trial(bag, mcap, lay, flips, Path(tmp))
        rows.append(row)
        parts = "/".join(str(row["parts"].get(p, 0)) for p in PARTS)
        print(f"| {k} | {row['flips']} ({parts}) | {row['valid_chunks']} of {row['chunks']} | "
              f"{row['expected']} | {row['expected_kept']} | {row['not_in_intact']} | "
              f"{'yes' if row['log_time_order'] else 'NO'} | "
              f"{'yes' if row['info_damaged'] else 'NO'} ({row['ranges']}) | "
              f"{row['recover_exit']} | {row['reported_lost']} / {row['true_lost']} |",
              flush=True)
    expected = sum(r["expected"] for r in rows)
    kept = sum(r["expected_kept"] for r in rows)
    print(f"\ntotal: {args.copies} copies, {sum(r['flips'] for r in rows)} flips; messages in "
          f"CRC-valid chunks {expected}, kept byte-identical {kept} ({kept / expected:.4f}); "
          f"missing {sum(r['missing'] for r in rows)}; kept but not in the intact bag "
          f"{sum(r['not_in_intact'] for r in rows)}; `dva bag info` flags "
          f"{sum(r['info_damaged'] for r in rows)} of {args.copies} as damaged; `dva bag "
          f"recover` exit codes {dict(Counter(r['recover_exit'] for r in rows))}; reported "
          f"lost = true lost in {sum(r['reported_lost'] == r['true_lost'] for r in rows)} of "
          f"{args.copies}; wall time per command (median): info "
          f"{np.median([r['wall_info_s'] for r in rows]):.2f} s, recover "
          f"{np.median([r['wall_recover_s'] for r in rows]):.2f} s")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
