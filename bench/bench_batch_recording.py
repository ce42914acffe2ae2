"""Benchmark: the batch CDR encoder against rosbags' per-message serializer, and recording
flight blocks to a rosbag2 MCAP bag through each path.

Why the hand-written batch path exists: the sweep recording writes about 10^6 blocks of six
messages, and one Python call per message is too slow for its target. This prints, in one run:

Encoding only (no file), messages per second and the ratio:
  ``rosbags``: ``Typestore.serialize_cdr`` of each message (objects built before timing, so the
  serializer alone; the library path);
  ``batch``: :func:`aero_dva.bag.batch_cdr.cdr_layout` structured arrays filled with numpy, a
  run of blocks at a time (layouts generated from the .msg files), then ``tobytes``.

Recording the simulator's six messages per block (/clock, acceleration, displacement,
excitation, flight condition, damper state; 1 kHz, 50-sample blocks) into a bag:
  1. ``dict``: :class:`~aero_dva.bag.writer.BagWriter` with message dicts (generic dict ->
     rosbags message -> CDR), the baseline;
  2. ``rosbags``: rosbags messages built per block and serialized by rosbags, one
     ``BagWriter.write`` of CDR bytes per message (what a per-message recorder does);
  3. ``numpy``: :class:`~aero_dva.bag.batch_recorder.BatchRecorder` (block runs encoded and
     chunked with numpy);
  4. ``samples``: :meth:`BatchRecorder.write_samples` with the same samples as whole arrays (no
     FlightSamples objects; what ``record_sweep`` writes), and ``samples-nocrc`` without chunk
     CRCs,

with wall and CPU time, throughput as "x real time" (sim seconds recorded per wall second =
samples per second / 1000), messages per second, and the ratios to the baseline. The blocks are
synthetic (random arrays from a pool larger than the CPU caches, made before timing), so only
encoding and recording are timed; ``--simulation`` also times ``FlightRuntime.step`` on the
sweep scenario for comparison. ``--blocks 136800`` is the full sweep data set (6840 s, about
520 MB).

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

from aero_dva.bag import channels as ch
from aero_dva.bag.batch_cdr import cdr_layout, sample_fields, split_stamps, stamps_from_seconds
from aero_dva.bag.batch_recorder import BatchRecorder
from aero_dva.bag.schemas import typestore
from aero_dva.bag.writer import BagWriter, qos_profile_yaml
from aero_dva.flight.damper import DAMPER_RANGE, DamperSnapshot, DamperStatus
from aero_dva.flight.samples import FlightSamples

RATE = 1000.0
N = 50
POOL = 20_000  # distinct blocks of arrays: about 75 MB, beyond the caches
STORE = typestore()
T = STORE.types


def make_blocks(count: int, seed: int) -> tuple[list, list]:
    rng = np.random.default_rng(seed)
    pool = min(POOL, count)
    acc = rng.standard_normal((pool, 3, N))
    disp = 1e-3 * rng.standard_normal((pool, 4, N))
    force = 1e3 * rng.standard_normal((pool, N))
    density = np.full(N, 1.2)
    damping = np.full(N, 300.0)
    blocks = [
        FlightSamples(first_index=N * k, sample_rate=RATE,
                      force=force[k % pool], airspeed=np.full(N, 80.0 + 1e-4 * k),
                      density=density, damping=damping, displacements=disp[k % pool],
                      accelerations=acc[k % pool], diverged=False)
        for k in range(count)]
    state = DamperSnapshot(time=0.0, commanded_damping=math.nan, applied_damping=500.0,
                           min_damping=DAMPER_RANGE[0], max_damping=DAMPER_RANGE[1],
                           command_age=math.inf,
                           status=DamperStatus.NO_COMMAND, source="initial", rejection=None)
    return blocks, [state] * count


def _stamp(seconds: float) -> dict:
    ns = int(round(seconds * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def block_bag(path: Path, compression: str) -> BagWriter:
    """A BagWriter with the simulator's block topics registered."""
    bag = BagWriter(path, compression=compression)
    for channel in ch.SIMULATOR_BLOCK:
        bag.add_topic(channel.name, channel.type_name, qos_profile_yaml())
    return bag


def record_dicts(path: Path, blocks, states, compression: str) -> None:
    """The baseline: message dicts through BagWriter (generic dict -> rosbags -> CDR)."""
    with block_bag(path, compression) as bag:
        for block, state in zip(blocks, states, strict=True):
            log = int(round(block.t_end * 1e9))
            head = {"stamp": _stamp(block.t0), "frame_id": "wing"}
            common = {"sample_rate": RATE, "first_sample_index": block.first_index}
            a, d = block.accelerations, block.displacements
            bag.write(ch.CLOCK.name, {"clock": _stamp(block.t_end)}, log)
            bag.write(ch.ACCELERATION.name, {"header": head, **common, "plunge": a[0],
                                             "pitch": a[1], "leading_edge": a[2]}, log)
            bag.write(ch.DISPLACEMENT.name, {"header": head, **common, "plunge": d[0],
                                             "pitch": d[1], "leading_edge": d[2],
                                             "absorber_stroke": d[3]}, log)
            bag.write(ch.EXCITATION.name, {"header": {"stamp": head["stamp"], "frame_id": ""},
                                           **common, "aileron_force": block.force}, log)
            bag.write(ch.FLIGHT_CONDITION.name, {"header": {"stamp": head["stamp"]},
                                                 "airspeed": block.airspeed[0],
                                                 "air_density": block.density[0]}, log)
            bag.write(ch.DAMPER_STATE.name, {
                "header": {"stamp": _stamp(state.time)},
                "commanded_damping": state.commanded_damping,
                "applied_damping": state.applied_damping, "min_damping": state.min_damping,
                "max_damping": state.max_damping, "command_age": state.command_age,
                "status": int(state.status), "source": state.source}, log)


def _time(seconds: float):
    sec, nanosec = divmod(int(round(seconds * 1e9)), 1_000_000_000)
    return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def rosbags_messages(block, state) -> list[tuple]:
    """The six messages of a block as rosbags objects: (channel, message)."""
    head = T["std_msgs/msg/Header"](stamp=_time(block.t0), frame_id="wing")
    bare = T["std_msgs/msg/Header"](stamp=head.stamp, frame_id="")
    common = {"sample_rate": RATE, "first_sample_index": block.first_index}
    a, d = block.accelerations, block.displacements
    return [
        (ch.CLOCK, T[ch.CLOCK.type_name](clock=_time(block.t_end))),
        (ch.ACCELERATION, T[ch.ACCELERATION.type_name](
            header=head, **common, plunge=a[0], pitch=a[1], leading_edge=a[2])),
        (ch.DISPLACEMENT, T[ch.DISPLACEMENT.type_name](
            header=head, **common, plunge=d[0], pitch=d[1], leading_edge=d[2],
            absorber_stroke=d[3])),
        (ch.EXCITATION, T[ch.EXCITATION.type_name](header=bare, **common,
                                                    aileron_force=block.force)),
        (ch.FLIGHT_CONDITION, T[ch.FLIGHT_CONDITION.type_name](
            header=bare, airspeed=float(block.airspeed[0]),
            air_density=float(block.density[0]))),
        (ch.DAMPER_STATE, T[ch.DAMPER_STATE.type_name](
            header=T["std_msgs/msg/Header"](stamp=_time(state.time), frame_id=""),
            commanded_damping=state.commanded_damping, applied_damping=state.applied_damping,
            min_damping=state.min_damping, max_damping=state.max_damping,
            command_age=state.command_age, status=int(state.status), source=state.source)),
    ]


def record_rosbags(path: Path, blocks, states, compression: str) -> None:
    """The per-message library path: rosbags messages, serialize_cdr, one write each."""
    with block_bag(path, compression) as bag:
        for block, state in zip(blocks, states, strict=True):
            log = int(round(block.t_end * 1e9))
            for channel, msg in rosbags_messages(block, state):
                bag.write(channel.name, STORE.serialize_cdr(msg, channel.type_name), log)


def encode_rosbags(messages: list[tuple]) -> int:
    """Serialize prebuilt rosbags messages one by one; returns the bytes made."""
    total = 0
    for channel, msg in messages:
        total += len(STORE.serialize_cdr(msg, channel.type_name))
    return total


def batch_inputs(blocks, states, batch: int = 1000) -> list[dict]:
    """The blocks as the arrays the batch encoder takes, ``batch`` blocks per run (made before
    timing, as write_samples gets them from the simulation)."""
    runs = []
    for i in range(0, len(blocks), batch):
        part, snaps = blocks[i:i + batch], states[i:i + batch]
        runs.append({
            "stamps": split_stamps(stamps_from_seconds([b.t0 for b in part])),
            "ends": split_stamps(stamps_from_seconds([b.t_end for b in part])),
            "index": np.array([b.first_index for b in part]),
            ch.ACCELERATION: np.stack([b.accelerations for b in part]),
            ch.DISPLACEMENT: np.stack([b.displacements for b in part]),
            ch.EXCITATION: np.stack([b.force for b in part])[:, None, :],
            "airspeed": np.array([b.airspeed[0] for b in part]),
            "density": np.array([b.density[0] for b in part]),
            "damper_stamps": split_stamps(stamps_from_seconds([s.time for s in snaps])),
            "damper": {name: np.array([float(getattr(s, name)) for s in snaps]) for name in (
                "commanded_damping", "applied_damping", "min_damping", "max_damping",
                "command_age", "status")},
            "source": snaps[0].source})
    return runs


def encode_batch(runs: list[dict]) -> int:
    """Fill the generated layouts a run of blocks at a time; returns the bytes made."""
    layouts = {c: cdr_layout(c.type_name, dict.fromkeys(sample_fields(c.type_name), N),
                             {"header.frame_id": "wing" if c != ch.EXCITATION else ""})
               for c in (ch.ACCELERATION, ch.DISPLACEMENT, ch.EXCITATION)}
    layouts[ch.CLOCK] = cdr_layout(ch.CLOCK.type_name)
    layouts[ch.FLIGHT_CONDITION] = cdr_layout(ch.FLIGHT_CONDITION.type_name)
    total = 0
    for run in runs:
        k = len(run["index"])
        layouts[ch.DAMPER_STATE] = cdr_layout(ch.DAMPER_STATE.type_name,
                                              strings={"source": run["source"]})
        rows = {c: layout.batch(k) for c, layout in layouts.items()}
        rows[ch.CLOCK]["clock.sec"], rows[ch.CLOCK]["clock.nanosec"] = run["ends"]
        for c in (ch.ACCELERATION, ch.DISPLACEMENT, ch.EXCITATION):
            r = rows[c]
            r["header.stamp.sec"], r["header.stamp.nanosec"] = run["stamps"]
            r["sample_rate"], r["first_sample_index"] = RATE, run["index"]
            for j, field in enumerate(sample_fields(c.type_name)):
                r[field] = run[c][:, j]
        r = rows[ch.FLIGHT_CONDITION]
        r["header.stamp.sec"], r["header.stamp.nanosec"] = run["stamps"]
        r["airspeed"], r["air_density"] = run["airspeed"], run["density"]
        r = rows[ch.DAMPER_STATE]
        r["header.stamp.sec"], r["header.stamp.nanosec"] = run["damper_stamps"]
        for name, column in run["damper"].items():
            r[name] = column
        total += sum(len(r.tobytes()) for r in rows.values())
    return total


def record_batch(path: Path, blocks, states, compression: str, batch: int = 1000) -> None:
    with BatchRecorder(path, RATE, compression=compression) as recorder:
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
    _, wall, cpu = timed_value(fn, *args)
    return wall, cpu


def timed_value(fn, *args) -> tuple[object, float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn(*args)
    return value, time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=20_000,
                        help="blocks for the batch path (default 20000 = 1000 s of flight)")
    parser.add_argument("--baseline-blocks", type=int, default=200,
                        help="blocks for the dict baseline (default 200 = 10 s)")
    parser.add_argument("--reference-blocks", type=int, default=2000,
                        help="blocks for the per-message rosbags path (default 2000)")
    parser.add_argument("--compression", default="none", choices=("none", "zstd", "lz4"))
    parser.add_argument("--dir", default=None, help="where to write (default: a temp dir)")
    parser.add_argument("--simulation", action="store_true",
                        help="also time FlightRuntime.step on the sweep scenario")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    blocks, states = make_blocks(max(args.blocks, args.reference_blocks,
                                     args.baseline_blocks), args.seed)
    batches = sample_batches(blocks[:args.blocks], states[:args.blocks])

    # Encoding only: the same messages through each encoder, equal bytes out. Both are run
    # once first: rosbags generates each type's serializer, the batch path its layouts.
    prebuilt = [m for b, s in zip(blocks[:args.reference_blocks],
                                  states[:args.reference_blocks]) for m in rosbags_messages(b, s)]
    runs = batch_inputs(blocks[:args.blocks], states[:args.blocks])
    encode_rosbags(prebuilt[:6])
    encode_batch(batch_inputs(blocks[:2], states[:2]))
    # CPU time: both are single-threaded pure computation, and CPU time is what a loaded
    # machine does not inflate.
    rosbags_bytes, _, cpu_rosbags = timed_value(encode_rosbags, prebuilt)
    batch_bytes, _, cpu_batch = timed_value(encode_batch, runs)
    per_block = rosbags_bytes / args.reference_blocks
    assert abs(batch_bytes / args.blocks - per_block) < 1.0, "the encoders made other sizes"
    rate_rosbags = len(prebuilt) / cpu_rosbags
    rate_batch = 6 * args.blocks / cpu_batch
    print(f"encoding only (no file), {per_block:.0f} bytes per block of 6 messages, per CPU "
          "second:")
    print(f"  rosbags serialize_cdr, per message : {rate_rosbags:12.0f} msg/s "
          f"({1e6 / rate_rosbags:.2f} us/msg, {len(prebuilt)} messages)")
    print(f"  batch_cdr layouts, 1000 blocks/run : {rate_batch:12.0f} msg/s "
          f"({1e6 / rate_batch:.3f} us/msg, {6 * args.blocks} messages)")
    print(f"  ratio batch / rosbags              : {rate_batch / rate_rosbags:12.1f}")
    del prebuilt, runs  # about 80 MB the recordings below should not share the caches with

    root = Path(tempfile.mkdtemp(prefix="bench_batch_", dir=args.dir))
    rows = []
    try:
        for warm in (record_dicts, record_batch):  # generated code and layouts, made once
            warm(root / "warm", blocks[:2], states[:2], args.compression)
            shutil.rmtree(root / "warm")
        for name, count, run in (
            ("dict", args.baseline_blocks,
             lambda p, b, s: record_dicts(p, b, s, args.compression)),
            ("rosbags", args.reference_blocks,
             lambda p, b, s: record_rosbags(p, b, s, args.compression)),
            ("numpy", args.blocks,
             lambda p, b, s: record_batch(p, b, s, args.compression)),
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

    print(f"recording {N}-sample blocks at {RATE:g} Hz, 6 messages per block, compression "
          f"{args.compression}, written under {args.dir or tempfile.gettempdir()}")
    print(f"{'path':>13} {'blocks':>7} {'sim [s]':>8} {'wall [s]':>9} {'cpu [s]':>8} "
          f"{'MB':>7} {'x real time':>12} {'msg/s':>10} {'ratio':>8}")
    base = None
    for name, count, wall, cpu, size in rows:
        sim = count * N / RATE
        speed = sim / wall  # = samples per second / 1000
        base = base or speed
        print(f"{name:>13} {count:7d} {sim:8.1f} {wall:9.3f} {cpu:8.3f} {size / 1e6:7.1f} "
              f"{speed:12.0f} {6 * count / wall:10.0f} {speed / base:8.1f}")
    speeds = {name: count / cpu for name, count, _, cpu, _ in rows}
    print(f"batch recorder / per-message rosbags recording, per CPU second: "
          f"{speeds['numpy'] / speeds['rosbags']:.1f} x (write_blocks), "
          f"{speeds['samples'] / speeds['rosbags']:.1f} x (write_samples)")
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
