"""Benchmark: recording flight blocks to a rosbag2 MCAP bag through the batch path.

Writes the simulator's six messages per block (/clock, acceleration, displacement, excitation,
flight condition, damper state; 1 kHz, 50-sample blocks) in the same run through

1. ``dict``: :class:`~aero_dva.bag.mcap_io.BagWriter` with message dicts (mcap-ros2-support's
   pure-Python CDR encoder), the baseline;
2. ``bagwriter``: :mod:`aero_dva.bag.cdr_encoding` bytes, one ``BagWriter.write`` per message;
3. ``numpy``: :class:`~aero_dva.bag.batch_recording_io.BatchRecorder` (block runs encoded and
   chunked with numpy, the batch path's default),
4. ``samples``: :meth:`BatchRecorder.write_samples` with the same samples as whole arrays (no
   FlightBlock objects; what ``record_sweep`` writes), and ``samples-nocrc`` without chunk
   CRCs,

and prints, per path, wall and CPU time and throughput as "x real time" (sim seconds recorded
per wall second = samples per second / 1000), plus the ratios to the baseline. The blocks are
synthetic (random arrays from a pool larger than the CPU caches, made before timing), so only
the recording is timed; ``--simulation`` also times ``FlightRuntime.step`` on the sweep scenario
for comparison. ``--blocks 136800`` is the issue's full sweep data set (6840 s, about 520 MB).

Run: source scripts/env.sh; python bench/bench_batch_recording.py [--blocks 136800]
     [--dir /dev/shm] [--compression none|zstd|lz4] [--simulation]
"""
from __future__ import annotations

import argparse
import math
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from aero_dva.bag.batch_recording_io import BatchRecorder
from aero_dva.bag.mcap_io import BagWriter, qos_profile_yaml
from aero_dva.flight.damper import DamperSnapshot, DamperStatus
from aero_dva.flight.flight_runtime import FlightBlock

RATE = 1000.0
N = 50
POOL = 20_000  # distinct blocks of arrays: about 75 MB, beyond the caches


def make_blocks(count: int, seed: int) -> tuple[list, list]:
    rng = np.random.default_rng(seed)
    pool = min(POOL, count)
    acc = rng.standard_normal((pool, 3, N))
    disp = 1e-3 * rng.standard_normal((pool, 4, N))
    force = 1e3 * rng.standard_normal((pool, N))
    density = np.full(N, 1.2)
    damping = np.full(N, 300.0)
    blocks = [
        FlightBlock(first_index=N * k, t0=N * k / RATE, t_end=N * (k + 1) / RATE,
                    force=force[k % pool], airspeed=np.full(N, 80.0 + 1e-4 * k),
                    density=density, damping=damping, displacements=disp[k % pool],
                    accelerations=acc[k % pool], diverged=False)
        for k in range(count)]
    state = DamperSnapshot(time=0.0, commanded_damping=math.nan, applied_damping=500.0,
                           min_damping=0.0, max_damping=2500.0, command_age=math.inf,
                           status=DamperStatus.NO_COMMAND, source="initial", rejection=None)
    return blocks, [state] * count


def _stamp(seconds: float) -> dict:
    ns = int(round(seconds * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def record_dicts(path: Path, blocks, states, compression: str) -> None:
    """The baseline: message dicts through BagWriter's mcap-ros2 encoder."""
    topics = {"/clock": "rosgraph_msgs/msg/Clock",
              "/wing/acceleration": "dva_msgs/msg/AccelerationBlock",
              "/wing/displacement": "dva_msgs/msg/DisplacementBlock",
              "/wing/excitation": "dva_msgs/msg/ForceBlock",
              "/flight/condition": "dva_msgs/msg/FlightCondition",
              "/dva/damper_state": "dva_msgs/msg/DamperState"}
    with BagWriter(path, compression=compression) as bag:
        for topic, type_name in topics.items():
            bag.add_topic(topic, type_name, qos_profile_yaml())
        for block, state in zip(blocks, states, strict=True):
            log = int(round(block.t_end * 1e9))
            head = {"stamp": _stamp(block.t0), "frame_id": "wing"}
            common = {"sample_rate": RATE, "first_sample_index": block.first_index}
            a, d = block.accelerations, block.displacements
            bag.write("/clock", {"clock": _stamp(block.t_end)}, log)
            bag.write("/wing/acceleration", {"header": head, **common, "plunge": a[0],
                                             "pitch": a[1], "leading_edge": a[2]}, log)
            bag.write("/wing/displacement", {"header": head, **common, "plunge": d[0],
                                             "pitch": d[1], "leading_edge": d[2],
                                             "absorber_stroke": d[3]}, log)
            bag.write("/wing/excitation", {"header": {"stamp": head["stamp"], "frame_id": ""},
                                           **common, "aileron_force": block.force}, log)
            bag.write("/flight/condition", {"header": {"stamp": head["stamp"]},
                                            "airspeed": block.airspeed[0],
                                            "air_density": block.density[0]}, log)
            bag.write("/dva/damper_state", {
                "header": {"stamp": _stamp(state.time)},
                "commanded_damping": state.commanded_damping,
                "applied_damping": state.applied_damping, "min_damping": state.min_damping,
                "max_damping": state.max_damping, "command_age": state.command_age,
                "status": int(state.status), "source": state.source}, log)


def record_batch(path: Path, blocks, states, compression: str, engine: str,
                 batch: int = 1000) -> None:
    with BatchRecorder(path, RATE, compression=compression, engine=engine) as recorder:
        for i in range(0, len(blocks), batch):
            recorder.write_blocks(blocks[i:i + batch], states[i:i + batch])


def sample_batches(blocks, states, batch: int = 5000) -> list[dict]:
    """The blocks as write_samples arguments, ``batch`` blocks per call (made before timing)."""
    out = []
    for i in range(0, len(blocks), batch):
        part, snaps = blocks[i:i + batch], states[i:i + batch]
        damper = {"time": np.array([b.t0 for b in part]),
                  **{k: np.array([float(getattr(s, k)) for s in snaps]) for k in (
                      "commanded_damping", "applied_damping", "min_damping", "max_damping",
                      "command_age", "status")}}
        out.append({"first_index": part[0].first_index,
                    "accelerations": np.concatenate([b.accelerations for b in part], axis=1),
                    "displacements": np.concatenate([b.displacements for b in part], axis=1),
                    "force": np.concatenate([b.force for b in part]),
                    "block_size": N, "airspeed": np.array([b.airspeed[0] for b in part]),
                    "density": np.array([b.density[0] for b in part]), "damper": damper,
                    "source": snaps[0].source})
    return out


def record_samples(path: Path, batches: list[dict], compression: str, chunk_crc: bool) -> None:
    with BatchRecorder(path, RATE, compression=compression, chunk_crc=chunk_crc) as recorder:
        for arguments in batches:
            recorder.write_samples(**arguments)


def timed(fn, *args) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    fn(*args)
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=20_000,
                        help="blocks for the batch path (default 20000 = 1000 s of flight)")
    parser.add_argument("--baseline-blocks", type=int, default=200,
                        help="blocks for the dict baseline (default 200 = 10 s)")
    parser.add_argument("--reference-blocks", type=int, default=2000,
                        help="blocks for the per-message BagWriter path (default 2000)")
    parser.add_argument("--compression", default="none", choices=("none", "zstd", "lz4"))
    parser.add_argument("--dir", default=None, help="where to write (default: a temp dir)")
    parser.add_argument("--simulation", action="store_true",
                        help="also time FlightRuntime.step on the sweep scenario")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    blocks, states = make_blocks(max(args.blocks, args.reference_blocks,
                                     args.baseline_blocks), args.seed)
    batches = sample_batches(blocks[:args.blocks], states[:args.blocks])
    root = Path(tempfile.mkdtemp(prefix="bench_batch_", dir=args.dir))
    rows = []
    try:
        for name, count, run in (
            ("dict", args.baseline_blocks,
             lambda p, b, s: record_dicts(p, b, s, args.compression)),
            ("bagwriter", args.reference_blocks,
             lambda p, b, s: record_batch(p, b, s, args.compression, "bagwriter")),
            ("numpy", args.blocks,
             lambda p, b, s: record_batch(p, b, s, args.compression, "numpy")),
            ("samples", args.blocks,
             lambda p, b, s: record_samples(p, batches, args.compression, True)),
            ("samples-nocrc", args.blocks,
             lambda p, b, s: record_samples(p, batches, args.compression, False)),
        ):
            path = root / name
            wall, cpu = timed(run, path, blocks[:count], states[:count])
            size = (path / f"{name}_0.mcap").stat().st_size
            rows.append((name, count, wall, cpu, size))
            shutil.rmtree(path)
    finally:
        shutil.rmtree(root, ignore_errors=True)

    print(f"{N}-sample blocks at {RATE:g} Hz, 6 messages per block, compression "
          f"{args.compression}, written under {args.dir or tempfile.gettempdir()}")
    print(f"{'path':>13} {'blocks':>7} {'sim [s]':>8} {'wall [s]':>9} {'cpu [s]':>8} "
          f"{'MB':>7} {'x real time':>12} {'ratio':>8}")
    base = None
    for name, count, wall, cpu, size in rows:
        sim = count * N / RATE
        speed = sim / wall  # = samples per second / 1000
        base = base or speed
        print(f"{name:>13} {count:7d} {sim:8.1f} {wall:9.3f} {cpu:8.3f} {size / 1e6:7.1f} "
              f"{speed:12.0f} {speed / base:8.1f}")
    sweep = 6840.0
    name, count, wall, _, _ = rows[2]
    print(f"full sweep data set ({sweep:g} s): recording through the batch path takes "
          f"{sweep / (count * N / RATE / wall):.2f} s at this rate "
          f"({'measured' if count >= sweep * RATE / N else 'extrapolated'})")

    if args.simulation:
        from aero_dva import data_files
        from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

        runtime = FlightRuntime(load_runtime_config(
            {"scenario": data_files.data_file("scenario_sweep.yaml")}))
        steps = 200
        t = time.perf_counter()
        for _ in range(steps):
            runtime.step()
        wall = time.perf_counter() - t
        print(f"simulation (FlightRuntime.step, sweep scenario): "
              f"{steps * runtime.block_duration / wall:.0f} x real time")


if __name__ == "__main__":
    main()
