"""Benchmark: the bag player's top rate on the 30 s ramp flight, against reading the bag alone.

Run (after ./test.sh or ./run.sh has set everything up)::

    source scripts/env.sh && python bench/bench_bag_player.py [--bag BAG] [--repeats 3]

Measures, in one run:
- baseline: the player's reading of the bag alone (aero_dva_sim.bag_source, every message as
  raw CDR, no ROS) in messages/s;
- the player at rate 0 (as fast as it can publish) with an ``mcap_recorder`` process subscribed
  to every played topic, over DDS: messages/s and x real time of the flight (the player's own
  wall time from its first to its last message), the ratio to the baseline, and how many of
  the played messages the recorder got;
- with ``--timing``: the player at rate 1.0 (30 s): its lateness against the log times
  (median, 99th percentile, largest).

Without ``--bag`` a 30 s flight is flown first (run_flight, airspeed schedule, as fast as the
graph goes) and its bag used: the study's ramp with its end at 1.0 U_cr instead of 1.2, so
that the whole 30 s are flown (the 0.8 -> 1.2 U_cr ramp of ./run.sh diverges near 28 s).
"""
from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from aero_dva.bag.reader import bag_topics
from aero_dva_sim.bag_player_node import BagPlayer
from aero_dva_sim.bag_source import BagSource
from aero_dva_sim.run_flight import die_with_parent, executable
from aero_dva_sim.run_flight import main as run_flight
from dva_ros_common.node_tools import close_executor
from dva_ros_common.ros_domain import reserved_domain, use_discovery

TOPICS = ["/wing/acceleration", "/wing/displacement", "/wing/excitation", "/flight/condition",
          "/dva/damper_state", "/dva/damper_command"]


SCENARIO = """name: ramp_to_ucr
duration: 30.0
sample_rate: 1000.0
block_size: 50
airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 1.0}
density: {base: 1.2, variation: 0.0, frequency: 1.0}
excitation: {force_std: 1000.0, seed: 1}
"""


def fly(root: Path) -> Path:
    scenario = root / "ramp_to_ucr.yaml"
    scenario.write_text(SCENARIO)
    schedule = root / "schedule.json"  # as ./run.sh fits it
    subprocess.run(["dva", "control", "schedule", "--out", str(schedule)], check=True,
                   capture_output=True)
    bag = root / "flight"
    code = run_flight(["--scenario", str(scenario), "--controller", "schedule", "--schedule",
                       str(schedule), "--real-time-factor", "0", "--output", str(bag)])
    if code != 0:
        raise SystemExit(f"the flight failed ({code})")
    return bag


def read_only(bag: Path, topics: list[str]) -> tuple[int, float]:
    """(messages, wall seconds) of reading the played topics through the player's reader."""
    source = BagSource(bag)
    start = time.perf_counter()
    n = sum(1 for _ in source.messages(topics))
    return n, time.perf_counter() - start


def play(bag: Path, topics: list[str], rate: float, domain: int, out: Path) -> dict:
    """Play into an mcap_recorder process; the player's summary and what the recorder got."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    recorder = subprocess.Popen(
        [executable("aero_dva_sim", "mcap_recorder"), "--ros-args", "-p", f"output:={out}",
         "-p", "exclude:=[/rosout,/parameter_events]", "-p", "discovery_period:=0.02"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        preexec_fn=die_with_parent)
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = SingleThreadedExecutor(context=context)
    player = None
    try:
        player = BagPlayer(context=context, parameter_overrides=[
            Parameter("bag", value=str(bag)), Parameter("rate", value=rate),
            Parameter("topics", value=topics), Parameter("wait_for_subscribers", value=1),
            Parameter("wait_timeout", value=60.0)])
        executor.add_node(player)
        deadline = time.monotonic() + 600.0
        while not player.finished.done() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        summary = dict(player.summary)
    finally:
        if player is not None:
            player.close()
        close_executor(executor, *([player] if player is not None else []))
        rclpy.try_shutdown(context=context)
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=30)
    got = bag_topics(out)
    summary["received"] = sum(got[t].message_count for t in topics if t in got)
    return summary


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bag", help="a recorded flight (default: fly the 30 s ramp first)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--timing", action="store_true", help="also play once at rate 1.0")
    args = parser.parse_args()
    use_discovery()  # this host only, as the project's runs
    with tempfile.TemporaryDirectory() as tmp, reserved_domain() as domain:
        root = Path(tmp)
        bag = Path(args.bag) if args.bag else fly(root)
        present = bag_topics(bag)
        topics = [t for t in TOPICS if t in present]
        n_bag = sum(present[t].message_count for t in topics)
        base, rows = [], []
        for i in range(args.repeats):
            n, wall = read_only(bag, topics)
            base.append(n / wall)
            rows.append(play(bag, topics, 0.0, domain, root / f"rate0_{i}"))
        span = rows[0]["bag_time_played_s"]
        print(f"bag                {bag}: {n_bag} messages on {len(topics)} topics over "
              f"{span:.2f} s of log time")
        print(f"machine            load average {os.getloadavg()[0]:.2f} on "
              f"{os.cpu_count()} CPUs; {args.repeats} repeats, median (min..max)")

        def line(name, values, unit):
            print(f"{name:34s} {statistics.median(values):10.0f} {unit} "
                  f"({min(values):.0f}..{max(values):.0f})")

        line("read only (baseline, no ROS)", base, "messages/s")
        rates = [r["messages_per_s"] for r in rows]
        line("bag_player rate 0 -> recorder", rates, "messages/s")
        factors = [r["real_time_factor"] for r in rows]
        print(f"{'  x real time of the flight':34s} {statistics.median(factors):10.1f} x "
              f"({min(factors):.1f}..{max(factors):.1f})")
        ratios = [r / b for r, b in zip(rates, base)]
        print(f"{'  ratio to the baseline':34s} {statistics.median(ratios):10.3f}   "
              f"({min(ratios):.3f}..{max(ratios):.3f})")
        received = [r["received"] for r in rows]
        print(f"{'  received by the recorder':34s} {min(received)}..{max(received)} of "
              f"{rows[0]['messages']} played")
        if args.timing:
            timed = play(bag, topics, 1.0, domain, root / "rate1")
            print(f"bag_player rate 1.0: {timed['wall_time_s']:.2f} s wall for {span:.2f} s; "
                  f"lateness median {1e3 * timed['lateness_median_s']:.2f} ms, p99 "
                  f"{1e3 * timed['lateness_p99_s']:.2f} ms, max "
                  f"{1e3 * timed['lateness_max_s']:.2f} ms; received {timed['received']} of "
                  f"{timed['messages']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
