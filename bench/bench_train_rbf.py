"""`dva train rbf` on a recorded sweep: this revision against the previous route, same run.

Run:  .venv/bin/dva train sweep --out runs/train_final        # the default plan's bag, once
      .venv/bin/python bench/bench_train_rbf.py runs/train_final [--runs 1]

Each route runs in its own child process, alternately, and the child's own resource usage is
read back (``os.wait4``): CPU time (user + system; the figure a busy machine inflates least),
wall time and peak resident memory. This revision is the command itself (``dva train rbf BAG
--out F``: the bag read through its chunk indexes, batches of messages decoded at once, only
the rows the data set uses held in memory, the window spectra 256 windows per product). The
previous route is the same steps as the command ran them before (``--previous`` below: the
whole flight log decoded message by message, then the spectra one window at a time). Both
networks are compared (targets: at most 30 s and 1 GB, the same network to rounding).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def _previous(bag: Path, out: Path) -> None:
    """The steps of `dva train rbf` (default options) as the previous revision ran them."""
    import argparse as ap

    from aero_dva.bag.flight_log_io import load_flight_log
    from aero_dva.control.rbf_io import save_rbf_network
    from dva_offline.training.labels import label_exact
    from dva_offline.training.rbf import build_dataset, train_network
    from dva_offline.training.rbf_cli import _labelling_wing

    log = load_flight_log(bag, indexed=False)
    data = build_dataset(log, window=2.0, spectra_batch=1)
    model, _, _ = _labelling_wing(ap.Namespace(wing=None), bag, log)
    outcome = train_network(data, label_exact(data, model))
    save_rbf_network(outcome.network, out, description="bench_train_rbf previous route")


def _child(argv: list[str]) -> dict:
    started = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            cwd=REPO)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - started
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(argv)} failed:\n{err}")
    return {"cpu": usage.ru_utime + usage.ru_stime, "wall": wall,
            "rss_mb": usage.ru_maxrss / 1024.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path, help="a sweep recorded by `dva train sweep`")
    parser.add_argument("--runs", type=int, default=1, help="alternating runs of each route")
    parser.add_argument("--previous", metavar="OUT", help=argparse.SUPPRESS)  # child mode
    args = parser.parse_args()
    if args.previous:
        _previous(args.bag, Path(args.previous))
        return
    dva = shutil.which("dva", path=str(Path(sys.executable).parent)) or "dva"
    tmp = Path(tempfile.mkdtemp(prefix="bench_train_rbf_"))
    try:
        results = {"previous": [], "this revision": []}
        for _ in range(args.runs):
            results["previous"].append(_child([sys.executable, __file__, str(args.bag),
                                               "--previous", str(tmp / "previous.npz")]))
            results["this revision"].append(_child([dva, "train", "rbf", str(args.bag),
                                                    "--out", str(tmp / "new.npz")]))
        old, new = np.load(tmp / "previous.npz"), np.load(tmp / "new.npz")
        diffs = {k: float(np.max(np.abs(old[k] - new[k]))) if old[k].size else 0.0
                 for k in old.files if old[k].dtype.kind == "f"}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"dva train rbf {args.bag} ({args.runs} alternating run(s) per route; child "
          "processes' own usage)")
    for name, rows in results.items():
        for i, r in enumerate(rows):
            print(f"  {name:14s} run {i + 1}: CPU {r['cpu']:6.1f} s  wall {r['wall']:6.1f} s  "
                  f"peak memory {r['rss_mb']:6.0f} MB")
    cpu = [p["cpu"] / n["cpu"] for p, n in zip(results["previous"], results["this revision"])]
    rss = [p["rss_mb"] / n["rss_mb"]
           for p, n in zip(results["previous"], results["this revision"])]
    print("  ratio previous / this revision: CPU " + ", ".join(f"{c:.1f}x" for c in cpu)
          + "; peak memory " + ", ".join(f"{m:.1f}x" for m in rss))
    best = min(r["cpu"] for r in results["this revision"])
    peak = max(r["rss_mb"] for r in results["this revision"])
    print(f"  targets: <= 30 s ({best:.1f} s CPU, best run), <= 1 GB ({peak:.0f} MB peak)")
    print("  largest difference between the networks: "
          + ", ".join(f"{k} {v:.1e}" for k, v in diffs.items()))


if __name__ == "__main__":
    main()
