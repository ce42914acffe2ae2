"""Benchmark: the node graph's start, flight, stop and round trip, each beside its baseline.

Run (after ./test.sh or ./run.sh has set everything up; about 2 minutes idle)::

    source scripts/env.sh && python bench/bench_graph_speed.py [--json FILE] [--keep DIR]

Prints, in one run, each figure with the baseline measured in the same run:

- node start: ``ros2 run PKG EXE --help`` of every executable of aero_dva_sim and
  dva_controller against ``python -c "import rclpy, numpy"`` (best of ``--repeats``, taken in
  turns);
- the 30 s lockstep schedule flight (``run_flight --controller schedule --real-time-factor 0``,
  flown ``--flights`` times, the median's figures printed with every flight's factor;
  the README's flight): sim time / wall time against the same flight in this process (the
  flight runtime with the schedule law after every block, ``closed_loop.fly``: the arithmetic
  and the law without DDS or processes);
  run_flight's wall time from start to summary, split into start, flight, stop and summary;
- the per-block round trip and where it goes: the simulator's own split of the flight's wall
  time (stepping, publishing, held for the command; CPU beside wall), the serialization of the
  block's messages and the law's arithmetic timed here, and a condition -> command ping-pong
  between two processes (``bench/graph_echo.py``) with the echo on the events executor and on a
  bare wait set: DDS, and what the executor adds per node;
- latency at rate 1 (``--real-time-factor 1``, ``--latency-duration`` s of the ramp): from a
  flight condition to the command answering it, both stamped on arrival by a probe node in this
  process (median, p99, max), idle and beside two CPU-bound loops this benchmark starts and
  stops;
- the record: the lockstep flight flown again beside the two busy loops gives the idle record
  digit for digit, as every idle flight's (divergence, RMS, mean c2, commands recorded).

The machine's load average is printed first: on a machine shared with other work, the wall
times (every figure here but the CPU ones) measure the sharing too.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

RECORD = ("divergence_ratio", "leading_edge_rms", "mean_damping", "commands_recorded")
BUSY_LOOP = "while True:\n    pass\n"
PACKAGES = ("aero_dva_sim", "dva_controller")
HERE = Path(__file__).resolve().parent


def executables() -> list[tuple[str, str]]:
    """(package, executable) of every executable ``ros2 run`` finds in the project's packages."""
    from ament_index_python.packages import get_package_prefix

    out = []
    for package in PACKAGES:
        folder = Path(get_package_prefix(package)) / "lib" / package
        out += [(package, p.name) for p in sorted(folder.iterdir())
                if p.is_file() and os.access(p, os.X_OK)]
    return out


def wall_of(argv: list[str]) -> float:
    started = time.perf_counter()
    done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"bench: {' '.join(argv)} exited {done.returncode}: "
                         f"{done.stderr.strip()[-300:]}")
    return wall


def node_start(repeats: int) -> dict:
    """Best wall time of each executable's ``--help`` and of the import baseline, in turns."""
    baseline = [sys.executable, "-c", "import rclpy, numpy"]
    runs = {"import rclpy, numpy": baseline}
    runs.update({f"{pkg} {exe}": ["ros2", "run", pkg, exe, "--help"]
                 for pkg, exe in executables()})
    times: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(repeats):
        for name, argv in runs.items():
            times[name].append(wall_of(argv))
    return {name: min(t) for name, t in times.items()}


def baseline_flight(schedule: Path, repeats: int = 3) -> tuple[float, float, int, int]:
    """(sim s, wall s, blocks, samples) of the same lockstep schedule flight in this process:
    the simulator node's flight runtime with the schedule law of ``schedule`` answering every
    block's condition, its command acting from the next block (``closed_loop.fly``, the least
    wall time of ``repeats``)."""
    from aero_dva.flight.flight_runtime import load_runtime_config
    from dva_offline.evaluation.closed_loop import fly, law_control

    law = law_control("schedule", {"schedule_file": str(schedule)})
    best = None
    for _ in range(repeats):
        config = load_runtime_config({})
        started = time.perf_counter()
        outcome = fly(config, law)
        wall = time.perf_counter() - started
        if best is None or wall < best[1]:
            blocks = -(-outcome.samples // config.scenario.block_size)
            best = (outcome.samples / outcome.sample_rate, wall, blocks, outcome.samples)
    return best


def schedule_file(directory: Path) -> Path:
    """The airspeed schedule ``./run.sh`` fits (``dva control schedule``)."""
    path = directory / "schedule.json"
    subprocess.run([str(Path(sys.executable).with_name("dva")), "control", "schedule",
                    "--out", str(path)], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return path


def run_flight(schedule: Path, bag: Path, extra: list[str] = ()) -> dict:
    """One ``run_flight --controller schedule ... --json``; its summary and the wall time of
    the command as a whole."""
    argv = ["ros2", "run", "aero_dva_sim", "run_flight", "--controller", "schedule",
            "--schedule", str(schedule), "--output", str(bag), "--json", *extra]
    started = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"bench: run_flight exited {done.returncode}: "
                         f"{done.stderr.strip()[-500:]}")
    summary = json.loads(done.stdout)
    summary["command_wall_time"] = wall
    return summary


def end_report(bag: Path) -> dict:
    """The simulator's end-of-flight report from the bag (numbers as floats)."""
    from aero_dva.bag.flight_log_io import load_flight_log

    final = [d["values"] for d in load_flight_log(bag).diagnostics
             if d["name"] == "simulator: flight" and "wall_time_s" in d["values"]][-1]
    out = {}
    for key, value in final.items():
        with contextlib.suppress(ValueError):
            out[key] = float(value)
    return out


@contextlib.contextmanager
def busy_loops(count: int):
    """``count`` CPU-bound processes for the duration of the block (killed after)."""
    loops = [subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) for _ in range(count)]
    try:
        time.sleep(0.5)  # both on the CPU before the measured work starts
        yield
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()


def message_costs(repeats: int = 200) -> dict:
    """[s] per block: building and serializing the messages the simulator sends, the
    controller's deserializing of its inputs and its command's round, the law's arithmetic."""
    import rclpy.serialization as ser
    from rosgraph_msgs.msg import Clock

    from aero_dva.control import controllers as table
    from aero_dva.control.controllers import Condition
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
    from dva_msgs.msg import DamperCommand, FlightCondition
    from dva_ros_common import conversions

    runtime = FlightRuntime(load_runtime_config({}))
    block = runtime.step()
    fs, i0, t0 = runtime.sample_rate, block.first_index, block.t0
    makers = (
        lambda: conversions.clock(block.t_end),
        lambda: conversions.flight_condition(t0, block.airspeed[0], block.density[0]),
        lambda: conversions.damper_state(runtime.flown_damper),
        lambda: conversions.acceleration_block(t0, fs, i0, block.accelerations),
        lambda: conversions.displacement_block(t0, fs, i0, block.displacements),
        lambda: conversions.force_block(t0, fs, i0, block.force))

    def timed(fn) -> float:
        fn()  # the first call loads the type support
        best = []
        for _ in range(5):
            started = time.perf_counter()
            for _ in range(repeats):
                fn()
            best.append((time.perf_counter() - started) / repeats)
        return min(best)

    build = sum(timed(make) for make in makers)
    messages = [make() for make in makers]
    serialize = sum(timed(lambda m=m: ser.serialize_message(m)) for m in messages)
    command = conversions.damper_command(t0, 300.0, "airspeed_schedule")
    command_data = ser.serialize_message(command)
    inputs = [(ser.serialize_message(make()), kind) for make, kind in
              ((makers[0], Clock), (makers[1], FlightCondition))]
    deserialize = sum(timed(lambda d=d, k=k: ser.deserialize_message(d, k)) for d, k in inputs)
    command_round = (timed(lambda: conversions.damper_command(t0, 300.0, "airspeed_schedule"))
                     + timed(lambda: ser.serialize_message(command))
                     + timed(lambda: ser.deserialize_message(command_data, DamperCommand)))
    law = table.controller("schedule").make_law({"a0": -2150.0, "a1": 31.5})
    condition = Condition(airspeed=100.0, density=1.2)
    arithmetic = timed(lambda: law.answer("condition", 0, condition))
    return {"build": build, "serialize": serialize, "deserialize": deserialize,
            "command": command_round, "law": arithmetic}


def echo_round_trips(count: int) -> dict:
    """[s] median round trip of the condition -> command ping-pong, the echo on the events
    executor and on a bare wait set (each on a ROS domain reserved for it)."""
    from domain_coordinator import domain_id

    out = {}
    for mode in ("waitset", "events"):
        with domain_id() as domain:
            env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
            echo = subprocess.Popen([sys.executable, str(HERE / "graph_echo.py"), "echo", mode],
                                    env=env, stdout=subprocess.DEVNULL)
            try:
                done = subprocess.run([sys.executable, str(HERE / "graph_echo.py"), "ping",
                                       "--count", str(count)], env=env, capture_output=True,
                                      text=True, timeout=120)
            finally:
                echo.kill()
                echo.wait()
            if done.returncode != 0:
                raise SystemExit(f"bench: graph_echo ping ({mode}) failed: "
                                 f"{done.stderr.strip()[-300:]}")
            # (Fast DDS prints its transport errors on stdout: the JSON is the last line)
            trips = json.loads(done.stdout.strip().splitlines()[-1])["round_trips_s"]
            out[mode] = {"median": statistics.median(trips),
                         "p99": float(np.percentile(trips, 99))}
    return out


class LatencyProbe:
    """A node on the flight's domain stamping the arrival of every flight condition and every
    damper command (perf_counter), by the condition's stamp."""

    def __init__(self, domain: int) -> None:
        import rclpy
        from rclpy.experimental import EventsExecutor
        from rclpy.qos import qos_profile_sensor_data

        from aero_dva.bag import channels as ch
        from dva_msgs.msg import DamperCommand, FlightCondition

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("latency_probe", context=self.context)
        self.conditions: dict[tuple[int, int], float] = {}
        self.commands: dict[tuple[int, int], float] = {}
        for kind, name, into in ((FlightCondition, ch.FLIGHT_CONDITION.name, self.conditions),
                                 (DamperCommand, ch.DAMPER_COMMAND.name, self.commands)):
            self.node.create_subscription(
                kind, name, lambda msg, into=into: into.setdefault(
                    (msg.header.stamp.sec, msg.header.stamp.nanosec), time.perf_counter()),
                qos_profile_sensor_data)
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        from rclpy.task import Future

        while self.context.ok():  # in bounded slices, as the nodes spin it
            with contextlib.suppress(Exception):
                self.executor.spin_until_future_complete(Future(), timeout_sec=0.1)

    def latencies(self) -> np.ndarray:
        """[s] command arrival - condition arrival, for every condition answered."""
        return np.array([self.commands[k] - t for k, t in self.conditions.items()
                         if k in self.commands])

    def close(self) -> None:
        self.context.try_shutdown()
        self.thread.join(timeout=5.0)


def latency_flight(schedule: Path, scenario: Path, bag: Path) -> dict:
    """A rate-1 flight with the probe on its domain; the latency statistics [s]."""
    from domain_coordinator import domain_id

    with domain_id() as domain:
        probe = LatencyProbe(domain)
        try:
            summary = run_flight(schedule, bag, ["--scenario", str(scenario),
                                                 "--real-time-factor", "1",
                                                 "--domain-id", str(domain)])
        finally:
            probe.close()
    latency = probe.latencies()
    if latency.size == 0:
        raise SystemExit("bench: the latency probe heard no condition answered")
    return {"n": int(latency.size), "median": float(np.median(latency)),
            "p99": float(np.percentile(latency, 99)), "max": float(latency.max()),
            "blocks": summary["blocks"]}


def short_ramp(directory: Path, duration: float) -> Path:
    """The package's ramp scenario cut to ``duration`` s (the same ramp rate is not needed:
    the latency is the graph's, not the wing's)."""
    import yaml

    from aero_dva.data_files import data_file

    scenario = yaml.safe_load(data_file("scenario_ramp.yaml").read_text())
    scenario.update(name="ramp_short", duration=float(duration))
    path = directory / "scenario_short.yaml"
    path.write_text(yaml.safe_dump(scenario))
    return path


def ms(seconds: float) -> str:
    return f"{seconds * 1e3:.2f} ms"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3,
                        help="runs of each --help (and of the import baseline); best taken")
    parser.add_argument("--latency-duration", type=float, default=10.0,
                        help="[s] sim time (= wall time) of each rate-1 flight (default 10)")
    parser.add_argument("--echo-count", type=int, default=500,
                        help="timed round trips of the ping-pong")
    parser.add_argument("--flights", type=int, default=3,
                        help="idle lockstep flights; the median's figures are printed "
                             "(default: %(default)s)")
    parser.add_argument("--json", help="also write every figure to this JSON file")
    parser.add_argument("--keep", help="directory to keep the bags in (default: temporary)")
    args = parser.parse_args()
    if args.repeats < 1 or args.latency_duration <= 0 or args.echo_count < 10 or \
            args.flights < 1:
        parser.error("--repeats >= 1, --latency-duration > 0, --echo-count >= 10 and "
                     "--flights >= 1")
    figures: dict = {"load_average_at_start": os.getloadavg()}
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())} "
          f"({os.cpu_count()} CPUs); wall times below include whatever else runs")
    started = time.perf_counter()

    # -- node start
    start = figures["node_start"] = node_start(args.repeats)
    base = start.pop("import rclpy, numpy")
    print(f"\nnode start (best of {args.repeats}): baseline python -c 'import rclpy, numpy' "
          f"{base:.3f} s")
    for name, wall in start.items():
        print(f"  ros2 run {name:<40} --help {wall:.3f} s = {wall / base:.2f}x the baseline "
              f"(target <= 1.3x: {'met' if wall <= 1.3 * base else 'NOT met'})")
    figures["node_start_baseline"] = base

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep or tmp)
        root.mkdir(parents=True, exist_ok=True)
        schedule = schedule_file(root)

        # -- flight, start, stop
        sim_s, runtime_wall, runtime_blocks, runtime_samples = baseline_flight(schedule)
        # the median of --flights flights: one flight's figure moves by +-5 % from run to run
        flights = [run_flight(schedule, root / f"lockstep_idle_{i}", ["--real-time-factor", "0"])
                   for i in range(args.flights)]
        order = sorted(range(len(flights)), key=lambda i: flights[i]["flight_wall_time"])
        median = order[len(order) // 2]
        idle = flights[median]
        report = end_report(root / f"lockstep_idle_{median}")
        phases = idle["phase_wall_times"]
        factor = idle["duration"] / idle["flight_wall_time"]
        each = " / ".join(f"{f['duration'] / f['flight_wall_time']:.1f}x" for f in flights)
        print(f"\nflight (30 s lockstep schedule flight, the median of {len(flights)}: {each}): "
              f"{idle['duration']:.2f} s sim in "
              f"{idle['flight_wall_time']:.3f} s wall = {factor:.1f}x real time "
              f"(target >= 50x: {'met' if factor >= 50 else 'NOT met'}); baseline, the same "
              f"flight in this process (best of 3): {sim_s:.2f} s in {runtime_wall:.3f} s = "
              f"{sim_s / runtime_wall:.0f}x, ended at the same sample: "
              f"{'yes' if abs(sim_s - idle['duration']) < 1e-9 else 'NO'}")
        print(f"run_flight start to summary (that flight): {idle['command_wall_time']:.2f} s "
              f"wall (target "
              f"<= 3 s: {'met' if idle['command_wall_time'] <= 3 else 'NOT met'}); inside "
              f"run_flight: start {phases['start']:.2f} s, flight {phases['flight']:.2f} s, "
              f"stop {phases['stop']:.2f} s, summary {phases['summary']:.2f} s; the rest "
              f"({idle['command_wall_time'] - idle['wall_time'] - phases['summary']:.2f} s) "
              f"is run_flight's own start (its baseline: node start above)")
        print(f"  start: the simulator's process up to the end of its set-up "
              f"{report.get('node_start_wall_s', float('nan')):.2f} s (imports, wing, U_cr), "
              f"then waiting for the rest of the graph to start and match "
              f"{report.get('graph_wait_wall_s', float('nan')):.2f} s")
        figures.update(in_process={"sim_s": sim_s, "wall_s": runtime_wall,
                                   "samples": runtime_samples},
                       lockstep_idle_flights=[f["flight_wall_time"] for f in flights],
                       lockstep_idle={k: idle[k] for k in (
                           "duration", "flight_wall_time", "wall_time", "command_wall_time",
                           "phase_wall_times", "blocks", *RECORD)},
                       simulator_report=report)

        # -- the per-block round trip
        blocks = report["blocks"]
        per_block = report["wall_time_s"] / blocks
        costs = message_costs()
        echo = echo_round_trips(args.echo_count)
        executor = max(0.0, echo["events"]["median"] - echo["waitset"]["median"])
        runtime_block = runtime_wall / runtime_blocks
        print(f"\nper-block round trip: {ms(per_block)} wall per 50 ms block ({blocks:.0f} "
              f"blocks); baseline, a block of the same flight in this process: "
              f"{ms(runtime_block)}")
        split = {k: report[f"{k}_wall_s"] / blocks for k in ("stepping", "publishing", "held")}
        between = per_block - sum(split.values())
        print("  the simulator's split (wall / CPU of its thread), which adds up to the block: "
              f"stepping {ms(split['stepping'])} / {ms(report['stepping_cpu_s'] / blocks)}, "
              f"publishing {ms(split['publishing'])} / "
              f"{ms(report['publishing_cpu_s'] / blocks)}, held (from the end of publishing to "
              f"the next block: the command awaited, taken and checked) {ms(split['held'])}, "
              f"between blocks (its executor) "
              f"{ms(between)}; its process CPU {ms(report['process_cpu_s'] / blocks)}")
        print(f"  stepping: the same arithmetic in this process {ms(runtime_block)} with the "
              f"law ({ms(costs['law'])} of it); the rest of the node's stepping is the "
              "graph's other processes sharing the two cores and their caches")
        publish_python = costs["build"] + costs["serialize"]
        print(f"  publishing: building the block's 6 messages {ms(costs['build'])} and "
              f"serializing them {ms(costs['serialize'])} (timed here); the rest, "
              f"{ms(split['publishing'] - publish_python)}, is the DDS writes to their readers "
              "(the recorder's 6, the controller's /clock)")
        print(f"  held: in lockstep a block's condition goes out as soon as the block before is "
              f"stepped, so the controller answers while the simulator publishes; the round "
              f"trip, timed apart: DDS condition -> command "
              f"ping-pong between two processes on bare wait sets, median "
              f"{ms(echo['waitset']['median'])} (p99 {ms(echo['waitset']['p99'])}); on the "
              f"events executor {ms(echo['events']['median'])} (p99 "
              f"{ms(echo['events']['p99'])}: {ms(executor)} per node passed); the controller's "
              f"deserializing {ms(costs['deserialize'])} and its command "
              f"{ms(costs['command'])}")
        figures.update(per_block_s=per_block, runtime_block_s=runtime_block,
                       split_s=dict(split, between=between), message_costs_s=costs, echo_s=echo,
                       executor_per_node_s=executor)

        # -- latency at rate 1, idle and beside two busy loops
        scenario = short_ramp(root, args.latency_duration)
        latency = {"idle": latency_flight(schedule, scenario, root / "rate1_idle")}
        with busy_loops(2):
            latency["busy"] = latency_flight(schedule, scenario, root / "rate1_busy")
            loaded = run_flight(schedule, root / "lockstep_busy", ["--real-time-factor", "0"])
        print(f"\nlatency at rate 1 ({args.latency_duration:g} s flights), a flight condition "
              "to its command, both as a probe node receives them:")
        for kind, lat in latency.items():
            label = "no busy loops" if kind == "idle" else "beside two busy loops"
            target = (f" (target p99 <= 5 ms: {'met' if lat['p99'] <= 5e-3 else 'NOT met'})"
                      if kind == "idle" else "")
            print(f"  {label:<22} median {ms(lat['median'])}, p99 {ms(lat['p99'])}, max "
                  f"{ms(lat['max'])} over {lat['n']} conditions{target}")
        figures["latency_rate_1_s"] = latency

        # -- the record, idle and loaded
        same = all(f[k] == loaded[k] for f in flights for k in RECORD)
        print(f"\nrecord of the lockstep flight, idle ({len(flights)} flights) / beside two busy "
              "loops: " + "; ".join(
            f"{k} {idle[k]!r} / {loaded[k]!r}" for k in RECORD)
            + f": {'identical' if same else 'DIFFERENT'} (the loaded flight: "
            f"{loaded['duration'] / loaded['flight_wall_time']:.1f}x real time)")
        figures.update(lockstep_busy={k: loaded[k] for k in (
            "duration", "flight_wall_time", "wall_time", "phase_wall_times", *RECORD)},
            records_identical=same)
    figures["bench_wall_s"] = time.perf_counter() - started
    figures["load_average_at_end"] = os.getloadavg()
    print(f"\nbenchmark wall time {figures['bench_wall_s']:.0f} s; load average at end: "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2))
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
