"""Benchmark: the training sweep through the batch path (simulation + MCAP recording).

Flies the sweep ``dva train sweep`` flies by default (the shipped scenario_sweep.yaml adapted to
the stable airspeeds of the c2 list 200..770 N s/m, 4 s dwells), in the same run

1. ``simulation``: :meth:`FlightRuntime.step` to the end, nothing written (the baseline);
2. ``batch``: :func:`~aero_dva_sim.batch_recording_io.record_runtime`, stepping and recording
   every topic to a rosbag2 MCAP bag (what ``dva train sweep`` runs),

and prints per path the wall time, CPU time and aggregate "x real time" (sim seconds per wall
second), and the recording's share of the batch path. ``--airspeeds K`` flies only the first K
airspeeds (the rate is per sample, so it extrapolates); ``--as-is`` the shipped sweep unchanged
(171 x 20 x 2 s = 6840 s; it diverges near the top).

Run: source scripts/env.sh; python bench/bench_sweep_recording.py [--airspeeds K] [--as-is]
     [--dir /dev/shm]
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from aero_dva_sim import paths
from aero_dva_sim.batch_recording_io import record_runtime
from aero_dva_sim.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva_sim.flutter import growth_rate
from aero_dva_sim.scenario import AirspeedProfile, sweep_duration
from aero_dva_sim.wing_model import AeroelasticModel
from dva_offline.training import adapt_sweep


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--airspeeds", type=int, default=None,
                        help="fly only the first K airspeeds (default all)")
    parser.add_argument("--as-is", action="store_true", help="the shipped sweep unchanged")
    parser.add_argument("--dir", default=None, help="directory for the bag (default a temp dir)")
    args = parser.parse_args()
    config = sweep_config(args.as_is, args.airspeeds)
    s = config.scenario
    print(f"sweep: {len(s.airspeed.values)} airspeeds x {len(s.sweep_damping)} c2 x "
          f"{s.dwell:g} s = {s.duration:g} s of flight at {s.sample_rate:g} Hz "
          f"(blocks of {s.block_size})")

    def simulate():
        runtime = FlightRuntime(config)
        while not runtime.done:
            block = runtime.step()
            if block.diverged:
                break
        return runtime.time

    sim_time, sim_wall, sim_cpu = timed(simulate)
    root = Path(tempfile.mkdtemp(prefix="bench_sweep_", dir=args.dir))
    try:
        recorded, rec_wall, rec_cpu = timed(
            lambda: record_runtime(root / "bag", FlightRuntime(config)))
        size = sum(f.stat().st_size for f in (root / "bag").iterdir())
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"{'path':<12}{'sim [s]':>10}{'wall [s]':>10}{'cpu [s]':>10}{'x real time':>14}")
    print(f"{'simulation':<12}{sim_time:>10.0f}{sim_wall:>10.2f}{sim_cpu:>10.2f}"
          f"{sim_time / sim_wall:>14.0f}")
    print(f"{'batch':<12}{recorded.sim_time:>10.0f}{rec_wall:>10.2f}{rec_cpu:>10.2f}"
          f"{recorded.sim_time / rec_wall:>14.0f}")
    sim_share = sim_wall * recorded.sim_time / sim_time  # simulation time of what was recorded
    print(f"outcome {recorded.outcome}; bag {size / 1e6:.0f} MB; recording share of the batch "
          f"path {max(rec_wall - sim_share, 0) / rec_wall:.0%}; "
          f"batch / simulation wall time {rec_wall / sim_share:.2f}")
    print("issue target: >= 10000 x real time in aggregate; measured "
          f"{recorded.sim_time / rec_wall:.0f} x")


if __name__ == "__main__":
    main()
