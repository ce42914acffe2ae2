"""Benchmark: the training sweep through the batch path (simulation + MCAP recording).

Flies the sweep ``dva train sweep`` flies by default (the shipped scenario_sweep.yaml adapted to
the stable airspeeds of the c2 list 200..770 N s/m, 4 s dwells: 122 x 20 x 4 s = 9760 s at
1 kHz) and times, in the same run:

1. ``stepped``: :meth:`FlightRuntime.step` (50-sample blocks, what the simulator node runs),
   nothing written, over the first ``--stepped-airspeeds`` airspeeds (the baseline; its rate
   is per sample, so it extrapolates);
2. ``parallel sim``: :mod:`aero_dva_sim.sweep_batch` (the whole sweep parallel in time),
   nothing written: the simulation alone;
3. ``record``: :func:`~aero_dva_sim.batch_recording_io.record_sweep`, simulation + every topic
   written to a rosbag2 MCAP bag in ``--dir`` (what ``dva train sweep`` runs), and variants:
   without chunk CRCs, with one message block per dwell (4000 samples), and into ``/dev/shm``
   (RAM) when it exists;
4. ``dd``: the disk's write bandwidth, ``dd if=/dev/zero bs=16M conv=fdatasync`` of as many
   bytes as the bag into the same directory: the bag cannot be written faster than this
   (the recorder fsyncs the bag when it closes it).

Per path: wall and CPU time (CPU = user + system of this process: on a shared machine the wall
time also holds other jobs' time), "x real time" = sim seconds per wall second, and the ratio
to the stepped baseline. The machine's load average is printed with the results.
``--airspeeds K`` flies only the first K airspeeds; ``--as-is`` the shipped sweep unchanged
(171 x 20 x 2 s = 6840 s; it diverges near the top, where both paths stop).

Run: source scripts/env.sh; python bench/bench_sweep_recording.py [--airspeeds K] [--as-is]
     [--dir DIR] [--stepped-airspeeds 3] [--no-variants]
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from aero_dva_sim import paths, sweep_batch
from aero_dva_sim.batch_recording_io import record_sweep
from aero_dva_sim.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva_sim.flutter import growth_rate
from aero_dva_sim.scenario import AirspeedProfile, sweep_duration
from aero_dva_sim.wing_model import AeroelasticModel
from dva_offline.training import adapt_sweep

TARGET = 1e4  # the issue: >= 10^4 x real time in aggregate


def sweep_config(as_is: bool, airspeeds: int | None):
    config = load_runtime_config({"scenario": str(paths.config_file("scenario_sweep.yaml"))})
    if not as_is:
        u_cr = FlightRuntime(config).critical_airspeed
        model = AeroelasticModel(config.wing, config.absorber, config.aero)
        adapted = adapt_sweep(config.scenario, u_cr,
                              lambda u, c: growth_rate(model, u, config.scenario.density, c),
                              damping=np.linspace(200.0, 770.0, 20))
        config = replace(config, scenario=adapted.scenario)
    s = config.scenario
    if airspeeds:
        values = s.airspeed.values[:airspeeds]
        s = replace(s, airspeed=AirspeedProfile("steps", values, s.airspeed.relative),
                    duration=sweep_duration(len(values), len(s.sweep_damping), s.dwell))
        config = replace(config, scenario=s)
    return config


def timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def stepped(runtime) -> float:
    while not runtime.done:
        if runtime.step().diverged:
            break
    return runtime.time


def parallel_simulation(runtime) -> float:
    plan = sweep_batch.plan_sweep(runtime.config, runtime.scenario)
    done = 0
    for chunk in sweep_batch.simulate_sweep(runtime.config, plan):
        done += chunk.force.size
    return done / plan.sample_rate


def record(config, directory: Path, **options):
    root = Path(tempfile.mkdtemp(prefix="bench_sweep_", dir=directory))
    try:
        runtime = FlightRuntime(config)
        result, wall, cpu = timed(lambda: record_sweep(root / "bag", runtime, **options))
        size = sum(f.stat().st_size for f in (root / "bag").iterdir())
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return result, wall, cpu, size


def disk_bandwidth(directory: Path, size: int) -> float | None:
    """[bytes/s] dd of ``size`` bytes (whole 16 MiB blocks) with fdatasync, or None."""
    dd = shutil.which("dd")
    if dd is None:
        return None
    count = max(1, -(-size // (16 << 20)))
    target = Path(tempfile.mkdtemp(prefix="bench_dd_", dir=directory)) / "dd.bin"
    try:
        start = time.perf_counter()
        subprocess.run([dd, "if=/dev/zero", f"of={target}", "bs=16M", f"count={count}",
                        "conv=fdatasync"], check=True, capture_output=True)
        return count * (16 << 20) / (time.perf_counter() - start)
    finally:
        shutil.rmtree(target.parent, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--airspeeds", type=int, default=None,
                        help="fly only the first K airspeeds (default all)")
    parser.add_argument("--as-is", action="store_true", help="the shipped sweep unchanged")
    parser.add_argument("--dir", default=None,
                        help="directory for the bag (default the system's temp dir)")
    parser.add_argument("--stepped-airspeeds", type=int, default=3,
                        help="airspeeds flown by the stepped baseline (default 3)")
    parser.add_argument("--no-variants", action="store_true",
                        help="only the default recording (no CRC-less, big-block, RAM runs)")
    args = parser.parse_args()
    config = sweep_config(args.as_is, args.airspeeds)
    s = config.scenario
    directory = Path(args.dir or tempfile.gettempdir())
    dwell = int(round(s.dwell * s.sample_rate))
    print(f"sweep: {len(s.airspeed.values)} airspeeds x {len(s.sweep_damping)} c2 x "
          f"{s.dwell:g} s = {s.duration:g} s of flight at {s.sample_rate:g} Hz "
          f"(blocks of {s.block_size}); bag in {directory}")

    rows = []
    base_config = sweep_config(args.as_is, min(args.stepped_airspeeds,
                                               len(s.airspeed.values)))
    runtime = FlightRuntime(base_config)  # (its flutter analysis is not timed, in no path)
    sim, wall, cpu = timed(lambda: stepped(runtime))
    rows.append(("stepped (FlightRuntime.step)", sim, wall, cpu, None))
    runtime = FlightRuntime(config)
    sim, wall, cpu = timed(lambda: parallel_simulation(runtime))
    rows.append(("parallel sim (no writing)", sim, wall, cpu, None))
    result, wall, cpu, size = record(config, directory)
    rows.append((f"record, blocks of {s.block_size}", result.sim_time, wall, cpu, size))
    if not args.no_variants:
        r, w, c, b = record(config, directory, chunk_crc=False)
        rows.append((f"record, blocks of {s.block_size}, no CRC", r.sim_time, w, c, b))
        r, w, c, b = record(config, directory, chunk_crc=False, block_size=dwell)
        rows.append((f"record, blocks of {dwell}, no CRC", r.sim_time, w, c, b))
        shm = Path("/dev/shm")
        if shm.is_dir() and os.access(shm, os.W_OK):
            r, w, c, b = record(config, shm)
            rows.append((f"record to /dev/shm, blocks of {s.block_size}", r.sim_time, w, c, b))
            r, w, c, b = record(config, shm, chunk_crc=False, block_size=dwell)
            rows.append((f"record to /dev/shm, {dwell}, no CRC", r.sim_time, w, c, b))
    bandwidth = disk_bandwidth(directory, size)

    base = rows[0][1] / rows[0][2]
    print(f"{'path':<38}{'sim [s]':>9}{'wall [s]':>10}{'cpu [s]':>9}{'MB':>7}"
          f"{'x real time':>13}{'vs stepped':>12}")
    for name, sim, wall, cpu, nbytes in rows:
        mb = f"{nbytes / 1e6:.0f}" if nbytes else "-"
        print(f"{name:<38}{sim:>9.0f}{wall:>10.2f}{cpu:>9.2f}{mb:>7}{sim / wall:>13.0f}"
              f"{sim / wall / base:>12.1f}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"outcome {result.outcome} ({result.method}); load average {load:.1f} on "
          f"{os.cpu_count()} CPUs")
    if bandwidth:
        floor = size / bandwidth
        print(f"disk write bandwidth (dd, fdatasync, {directory}): {bandwidth / 1e6:.0f} MB/s:\n"
              f"  writing the {size / 1e6:.0f} MB bag takes >= {floor:.2f} s, so recording to "
              f"this disk cannot exceed {result.sim_time / floor:.0f} x real time")
    sim_rate = rows[1][1] / rows[1][2]
    print(f"issue target: >= {TARGET:.0f} x real time in aggregate;\n  simulation alone "
          f"{sim_rate:.0f} x ({'met' if sim_rate >= TARGET else 'not met'}), simulation + "
          f"recording {rows[2][1] / rows[2][2]:.0f} x "
          f"({'met' if rows[2][1] / rows[2][2] >= TARGET else 'not met'})")


if __name__ == "__main__":
    main()
