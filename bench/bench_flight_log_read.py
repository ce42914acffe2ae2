"""Benchmark: reading a recorded flight back (``load_flight_log``) against rosbags' own reader.

Writes a bag of ``--blocks`` 50-sample blocks (1 kHz, the simulator's six topics; random
samples) with the batch recorder's ``write_samples`` (the same call in earlier revisions, so
``compare_recording_rows.py --same-script`` can run this file on them), then times, in the
same run and in CPU seconds (the figure a loaded machine does not inflate), best of
``--repeats``:

1. ``rosbags Reader``: ``rosbags.rosbag2.Reader`` over the bag, every message decoded with
   ``Typestore.deserialize_cdr`` (the library's own path, the baseline);
2. ``load_flight_log``: :func:`aero_dva.bag.flight_log_io.load_flight_log` (mcap's indexed
   reader with chunk CRCs checked, rosbags' decoder, the arrays assembled by sample index).

Run: source scripts/env.sh; python bench/bench_flight_log_read.py [--blocks 20000]
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.flight.damper import DAMPER_RANGE

try:  # the batch recorder's module before and after the bag layer was split
    from aero_dva.bag.batch_recorder import BatchRecorder
except ImportError:  # pragma: no cover - an earlier revision, for compare_recording_rows
    from aero_dva.bag.batch_recording_io import BatchRecorder


RATE, N = 1000.0, 50


def write_bag(path: Path, blocks: int) -> None:
    rng = np.random.default_rng(0)
    total = blocks * N
    ones = np.ones(blocks)
    damper = {"time": np.arange(blocks) * N / RATE, "commanded_damping": 300.0 * ones,
              "applied_damping": 300.0 * ones, "min_damping": DAMPER_RANGE[0] * ones,
              "max_damping": DAMPER_RANGE[1] * ones, "command_age": 0.0 * ones,
              "status": 0.0 * ones}
    with BatchRecorder(path, RATE) as recorder:
        recorder.write_samples(0, rng.standard_normal((3, total)),
                               1e-3 * rng.standard_normal((4, total)),
                               1e3 * rng.standard_normal(total), block_size=N,
                               airspeed=80.0 + 1e-3 * np.arange(blocks), density=1.2 * ones,
                               damper=damper, source="sweep")


def rosbags_read(path: Path) -> int:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    count = 0
    with Reader(path) as reader:
        for connection in reader.connections:
            if connection.msgtype not in store.fielddefs:
                store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        for connection, _, raw in reader.messages():
            store.deserialize_cdr(raw, connection.msgtype)
            count += 1
    return count


def cpu_best(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dir", default=None, help="where to write (default: a temp dir)")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench_read_", dir=args.dir))
    try:
        bag = root / "bag"
        write_bag(bag, args.blocks)
        messages = 6 * args.blocks
        load_flight_log(bag)  # imports and generated decoders, once
        rosbags_read(bag)
        rows = [("rosbags Reader", cpu_best(lambda: rosbags_read(bag), args.repeats)),
                ("load_flight_log", cpu_best(lambda: load_flight_log(bag), args.repeats))]
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"{args.blocks} blocks of {N} samples, {messages} messages; CPU seconds, "
          f"best of {args.repeats}")
    print(f"{'path':>16} {'blocks':>7} {'cpu [s]':>8} {'us/msg':>8} {'ratio':>7}")
    base = rows[0][1]
    for name, cpu in rows:
        print(f"{name:>16} {args.blocks:7d} {cpu:8.3f} {1e6 * cpu / messages:8.2f} "
              f"{cpu / base:7.2f}")


if __name__ == "__main__":
    main()
