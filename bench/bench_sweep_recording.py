"""Benchmark: the training sweep through the batch path (simulation + MCAP recording).

Flies the sweep ``dva train sweep`` flies by default (the shipped scenario_sweep.yaml adapted to
the stable airspeeds of the c2 list 200..770 N s/m, 4 s dwells: 122 x 20 x 4 s = 9760 s at
1 kHz) and times, in the same run:

1. ``stepped``: :meth:`FlightRuntime.step` (50-sample blocks, what the simulator node runs),
   nothing written, over the first ``--stepped-airspeeds`` airspeeds (the baseline; its rate
   is per sample, so it extrapolates);
2. ``parallel sim``: :mod:`aero_dva.flight.sweep_simulator` (the whole sweep parallel in time),
   nothing written: the simulation alone, all 7 output channels, and the 4 a measured-only
   recording needs (3 accelerations + the leading edge for the divergence test);
3. ``record``: :func:`~aero_dva.bag.sweep_recording_io.record_sweep` into a rosbag2 MCAP bag
   in ``--dir`` (chunk CRCs on, fsynced on close): as ``dva train sweep`` runs it (every
   topic, one process per core, each simulating and writing its span into its own file of a
   split bag), in one process (encoding, CRCs and writing on a second thread while the main
   thread simulates), as ``dva train sweep --no-displacement`` runs it (the measured topics
   only), and the old way (one process, simulation and writing in turn); the first three
   also into ``/dev/shm`` (RAM) when it exists, to separate the CPU from the disk;
4. ``dd``: the disk's write bandwidth, ``dd if=/dev/zero bs=16M conv=fdatasync`` of as many
   bytes as the default bag into the same directory, and what the bags would take at that
   rate (this virtual disk's rate varies from run to run, 280-690 MB/s seen).

Per path: wall and CPU time (CPU = user + system of this process, all threads, and of the
processes it forked: above the wall time when both cores work), "x real time" = sim seconds
per wall second, the ratio to the stepped baseline, the 1-minute load average when the path
started, and "others": the cores
other processes kept busy during the path (from /proc/stat; 1.0 = one of the two cores was
taken, and the second core this path could use was not there).
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

from aero_dva import data_files
from aero_dva.bag.sweep_recording_io import default_jobs, record_sweep
from aero_dva.flight import sweep_simulator
from aero_dva.flight.discrete_model import ACCELERATION_OUTPUTS, OUTPUT_NAMES
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, sweep_duration
from aero_dva.wing.flutter import growth_rate
from aero_dva.wing.model import AeroelasticModel
from dva_offline.training.rbf import adapt_sweep

TARGET = 1e4  # the issue: >= 10^4 x real time in aggregate


def sweep_config(as_is: bool, airspeeds: int | None):
    config = load_runtime_config({"scenario": str(data_files.data_file("scenario_sweep.yaml"))})
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


def busy_seconds() -> float:
    """CPU seconds all cores of the machine have been busy since boot (NaN without /proc)."""
    try:
        with open("/proc/stat") as stream:
            fields = [int(v) for v in stream.readline().split()[1:]]
    except (OSError, ValueError):
        return float("nan")
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


OTHERS: list[float] = []  # per timed() call: cores other processes kept busy meanwhile


def cpu_seconds() -> float:
    """User + system CPU of this process and of its finished (waited-for) children."""
    return sum(os.times()[:4])


def timed(fn):
    busy = busy_seconds()
    wall, cpu = time.perf_counter(), cpu_seconds()
    out = fn()
    wall, cpu = time.perf_counter() - wall, cpu_seconds() - cpu
    OTHERS.append(max(0.0, busy_seconds() - busy - cpu) / wall)
    return out, wall, cpu


def stepped(runtime) -> float:
    while not runtime.done:
        if runtime.step().diverged:
            break
    return runtime.time


def parallel_simulation(runtime, outputs=OUTPUT_NAMES) -> float:
    plan = sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    done = 0
    for chunk in sweep_simulator.simulate_sweep(runtime.config, plan, outputs=outputs):
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
                        help="no recordings into /dev/shm")
    args = parser.parse_args()
    config = sweep_config(args.as_is, args.airspeeds)
    s = config.scenario
    directory = Path(args.dir or tempfile.gettempdir())
    print(f"sweep: {len(s.airspeed.values)} airspeeds x {len(s.sweep_damping)} c2 x "
          f"{s.dwell:g} s = {s.duration:g} s of flight at {s.sample_rate:g} Hz "
          f"(blocks of {s.block_size}); bag in {directory}")

    # Start-up: what the first recording of a process costs more than the next (imports done
    # late, message definitions parsed, layouts built), on a one-airspeed flight.
    small = sweep_config(args.as_is, 1)
    first, again = (record(small, directory)[2] for _ in range(2))
    print(f"start-up cost: {first - again:.3f} s CPU (first recording in the process "
          f"{first:.3f} s, the same again {again:.3f} s)")

    rows = []

    def row(name, run):  # run() -> (sim seconds, wall, cpu, bytes or None)
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        rows.append((name, *run(), load, OTHERS[-1]))

    base_config = sweep_config(args.as_is, min(args.stepped_airspeeds,
                                               len(s.airspeed.values)))
    runtime = FlightRuntime(base_config)  # (its flutter analysis is not timed, in no path)
    row("stepped (FlightRuntime.step)", lambda: (*timed(lambda: stepped(runtime)), None))
    runtime = FlightRuntime(config)
    row("parallel sim, 7 channels", lambda: (*timed(lambda: parallel_simulation(runtime)),
                                             None))
    measured = ("leading_edge",) + ACCELERATION_OUTPUTS
    row("parallel sim, 4 channels", lambda: (
        *timed(lambda: parallel_simulation(runtime, measured)), None))
    results = {}

    def recorded(name, where, **options):
        def run():
            result, wall, cpu, size = record(config, where, **options)
            results[name] = (result, size)
            return result.sim_time, wall, cpu, size
        row(name, run)

    jobs = default_jobs(s.n_samples)
    recorded("record: dva train sweep", directory, jobs=jobs)
    recorded("record: one process", directory)
    recorded("record: --no-displacement", directory, displacement=False, jobs=jobs)
    recorded("record: old (all, no overlap)", directory, overlap=False)
    shm = Path("/dev/shm")
    if not args.no_variants and shm.is_dir() and os.access(shm, os.W_OK):
        recorded("/dev/shm: dva train sweep", shm, jobs=jobs)
        recorded("/dev/shm: one process", shm)
        recorded("/dev/shm: --no-displacement", shm, displacement=False, jobs=jobs)
    result, size = results["record: dva train sweep"]
    bandwidth = disk_bandwidth(directory, size)

    base = rows[0][1] / rows[0][2]
    print(f"{'path':<32}{'sim [s]':>8}{'wall [s]':>9}{'cpu [s]':>8}{'MB':>6}"
          f"{'x real time':>12}{'vs stepped':>11}{'load':>6}{'others':>7}")
    for name, sim, wall, cpu, nbytes, load, others in rows:
        mb = f"{nbytes / 1e6:.0f}" if nbytes else "-"
        print(f"{name:<32}{sim:>8.0f}{wall:>9.2f}{cpu:>8.2f}{mb:>6}{sim / wall:>12.0f}"
              f"{sim / wall / base:>11.1f}{load:>6.2f}{others:>7.2f}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"outcome {result.outcome} ({result.method}); {jobs} process(es) as dva train "
          f"sweep runs it; load average now {load:.2f} on {os.cpu_count()} CPUs")
    if bandwidth:
        for name in ("record: dva train sweep", "record: --no-displacement"):
            nbytes = results[name][1]
            floor = nbytes / bandwidth
            print(f"disk write bandwidth (dd, fdatasync, {directory}): "
                  f"{bandwidth / 1e6:.0f} MB/s: at that rate the {nbytes / 1e6:.0f} MB bag "
                  f"({name[8:]}) takes {floor:.2f} s: {result.sim_time / floor:.0f} x "
                  "real time")
    rate = {name: sim / wall for name, sim, wall, *_ in rows}
    print(f"issue target: >= {TARGET:.0f} x real time in aggregate for the batch path "
          "(simulating, encoding and writing the bag); where the disk does not bound it:")
    for name in ("parallel sim, 7 channels", "/dev/shm: dva train sweep",
                 "/dev/shm: one process", "/dev/shm: --no-displacement"):
        if name in rate:
            print(f"  {name:<30}{rate[name]:>7.0f} x "
                  f"({'met' if rate[name] >= TARGET else 'not met'})")
    print(f"to {directory} (fsynced), where the disk bounds it:")
    for name in ("record: dva train sweep", "record: --no-displacement"):
        disk = result.sim_time * bandwidth / results[name][1] if bandwidth else None
        floor = f"; the disk alone at dd's rate: {disk:.0f} x" if disk else ""
        print(f"  {name:<30}{rate[name]:>7.0f} x ({'met' if rate[name] >= TARGET else 'not met'}"
              f"{floor})")


if __name__ == "__main__":
    main()
