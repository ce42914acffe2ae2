"""``bag_player``: publish a recorded bag back into the graph, like ``ros2 bag play``.

The messages of a rosbag2-layout MCAP bag (one file or split) are published as their recorded
CDR bytes, untouched, in log-time order, each with the QoS its publishers offered when it was
recorded (reliability, durability, depth from ``metadata.yaml``). ``/clock`` follows the log
times, so nodes with ``use_sim_time:=true`` run on the recording's time (the bag's own
``/clock`` is then not played). With ``rate`` > 0 a message goes out when its log time, scaled
by the rate, is due on the wall clock; with ``rate`` 0 as fast as the player can publish, and
nothing is lost only while each subscriber's queue has room for what it has not yet taken
(ROS 2 has no signal of a subscriber's progress; DDS acknowledgements arrive with the writer's
heartbeats, about every 3 s here, far too late to pace by). Topics are remapped with
``--ros-args -r FROM:=TO`` on the bag's names (``-r /wing/acceleration:=/replay/acceleration``).

The playing runs on its own thread (precise pacing, no executor in between); the node's
executor only serves the graph. When the bag ends the player publishes one status on
``/diagnostics`` (counts per topic, wall time, lateness, damage) and exits, unless ``loop``.
A damaged bag (crashed recorder, cut file, a chunk failing its CRC) plays every chunk whose
CRC holds, with a warning there and in the status saying how much was skipped; the process
then exits with ``PLAYED_LESS`` (1: completed, partial) unless it played all that the bag's
index promises. A graph that never came up (``wait_timeout_fails``) exits 3 with nothing
played; the other exit codes are every executable's (aero_dva.exits).

Its parameters (units, defaults, ranges) are the table ``SPEC`` of
:mod:`aero_dva_sim.bag_player_spec`, which the node declares them from and ``bag_player --help``
prints.
"""
from __future__ import annotations

import sys
import threading
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from aero_dva import exits
from aero_dva.bag import channels as ch
from aero_dva_sim.bag_player_spec import SPEC, main
from aero_dva_sim.bag_source import BagSource, BagTopic
from dva_ros_common import conversions
from dva_ros_common.conversions import message_class
from dva_ros_common.node_params import declare_parameters

POLL = 0.01  # [s] wall time between looks at the graph while waiting for subscribers
SLICE = 0.1  # [s] longest sleep, so a stop request is noticed quickly
#: Exit code when the bag is damaged and less was played than its index promises (or an
#: unclosed bag, which has no index to tell): completed, partial.
PLAYED_LESS = exits.PARTIAL


def qos_profile(topic: BagTopic, default_depth: int) -> QoSProfile:
    """The QoS to offer ``topic`` with: its recorded reliability and durability, and a depth
    of at least ``default_depth``. A reliable writer sends again only what its history still
    holds, and the recorded depth (10 for the simulator's topics, which the graph reports for
    a remote writer) lasted 50 ms at 10x: a subscriber starved for longer lost blocks for
    good (a spectrum node frozen for 3 s lost 21 of 30). A transient-local topic keeps its
    recorded depth: that is how many messages a late subscriber gets."""
    qos = topic.qos
    latched = qos.durability == "transient_local"
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=qos.depth if latched and qos.depth > 0 else max(qos.depth, default_depth),
        reliability=ReliabilityPolicy.BEST_EFFORT if qos.reliability == "best_effort"
        else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if qos.durability == "transient_local"
        else DurabilityPolicy.VOLATILE,
    )


class BagPlayer(Node):
    """Publish a bag's messages with their recorded timing on a thread of its own."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        if not values["bag"]:
            raise ValueError("parameter 'bag' is required (a bag directory or .mcap file)")
        self.source = BagSource(values["bag"])  # BagReadError (a ValueError) names the bag
        if self.source.damage:
            self.get_logger().warning(f"bag {values['bag']} is damaged: it plays every chunk "
                                      f"whose CRC holds ({self.source.damage})")
        self.rate = float(values["rate"])
        self.loop = bool(values["loop"])
        self.offset_ns = round(float(values["start_offset"]) * 1e9)
        duration = float(values["duration"])
        self.duration_ns = round(duration * 1e9) if duration > 0 else None
        self._play_clock = bool(values["clock"])
        self._wait_for = int(values["wait_for_subscribers"])
        self._wait_nodes = [n for n in values["wait_for_nodes"] if n]
        self._wait_topics = [self._topic_count(t) for t in values["wait_for_topics"] if t]
        self._wait_timeout = float(values["wait_timeout"])
        self._wait_fails = bool(values["wait_timeout_fails"])
        self.exit_code = 0  # run_node's exit code: FAILED when the graph never came up
        self._delay = float(values["delay"])
        self._ack_timeout = float(values["ack_timeout"])
        self.played = self._select(values["topics"])

        self._pub = {}
        for name in self.played:
            topic = self.source.topics[name]
            try:
                msg_type = message_class(topic.type_name)
            except (ImportError, AttributeError, ValueError) as exc:
                raise ValueError(f"bag {values['bag']}: topic {name} has type "
                                 f"{topic.type_name!r}, which is not installed ({exc})") from None
            self._pub[name] = self.create_publisher(
                msg_type, name, qos_profile(topic, int(values["qos_depth"])))
        self._clock_pub = self.create_publisher(Clock, ch.CLOCK.name, 10) \
            if self._play_clock else None
        self._diag_pub = self.create_publisher(DiagnosticArray, ch.DIAGNOSTICS.name, 10)

        self.counts = dict.fromkeys(self.played, 0)
        self.clock_published = 0
        self.lateness: list[float] = []  # [s] wall time a message went out after it was due
        self.finished = Future()
        self.done = self.finished if bool(values["exit_on_end"]) else None
        self.summary: dict = {}
        self.exit_code = 0  # PLAYED_LESS when a damaged bag played less than it promises
        self._played_span_ns = 0  # [ns] log time from the first to the last message played
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bag_player", daemon=True)
        described = ", ".join(f"{n} ({self.source.topics[n].message_count})" for n in self.played)
        self.get_logger().info(f"playing {values['bag']} at rate {self.rate:g}: {described}")
        self._thread.start()

    @staticmethod
    def _topic_count(entry: str) -> tuple[str, int]:
        name, _, count = entry.rpartition(":") if ":" in entry else (entry, "", "1")
        try:
            return name, int(count)
        except ValueError:
            raise ValueError(f"parameter 'wait_for_topics': {entry!r} is not TOPIC or "
                             "TOPIC:N") from None

    def _select(self, wanted) -> list[str]:
        names = [w if w.startswith("/") else "/" + w for w in wanted if w]
        available = self.source.topics
        unknown = [n for n in names if n not in available]
        if unknown:
            raise ValueError(f"parameter 'topics': {unknown} not in the bag; its topics: "
                             f"{sorted(available)}")
        if self._play_clock and "/clock" in names:
            raise ValueError("parameter 'topics' names /clock while 'clock' is true (the "
                             "player's own /clock): set clock:=false to play the recorded one")
        chosen = names or sorted(available)
        if self._play_clock and not names:
            chosen = [n for n in chosen if n != ch.CLOCK.name]  # the player's clock replaces it
        if not chosen:
            raise ValueError("nothing to play: the bag has no topics")
        return chosen

    # ------------------------------------------------------------------ the playing thread
    def _run(self) -> None:
        outcome = "stopped"
        try:
            if self._wait_for_graph():
                self._sleep_until(time.monotonic() + self._delay)
                started = time.monotonic()
                rounds = 0
                while not self._stop.is_set():
                    self._play_once()
                    rounds += 1
                    if not self.loop:
                        break
                if not self._stop.is_set():
                    outcome = "completed"
                self._report(outcome, time.monotonic() - started, rounds)
                self._linger()
        except Exception as exc:  # the context went away under a publish: a stop, not a crash
            if self.context.ok():
                outcome = f"failed: {type(exc).__name__}: {exc}"
                self.get_logger().error(f"playing stopped: {outcome}")
        finally:
            if not self.finished.done():
                self.finished.set_result(outcome)

    def _wait_for_graph(self) -> bool:
        deadline = time.monotonic() + self._wait_timeout
        while not self._stop.is_set():
            missing = self._missing()
            if not missing:
                return True
            if time.monotonic() > deadline:
                if self._wait_fails:
                    self.get_logger().error(f"the node graph was not complete after "
                                            f"{self._wait_timeout:g} s (missing: {missing}): "
                                            "nothing played")
                    self.exit_code = exits.FAILED
                    return False
                self.get_logger().warning(f"starting without {missing} after "
                                          f"{self._wait_timeout:g} s")
                return True
            time.sleep(POLL)
        return False

    def _missing(self) -> list[str]:
        """What the first message still waits for (empty: nothing)."""
        missing = [f"{self._wait_for} subscribers on {n}" for n, p in self._pub.items()
                   if p.get_subscription_count() < self._wait_for]
        if self._wait_nodes:
            present = set(self.get_node_names())
            missing += [f"node {n}" for n in self._wait_nodes if n not in present]
            # A node in the graph has its subscriptions in the graph too: wait until our
            # publishers have matched every one of them, so none misses the first messages.
            for name, pub in self._pub.items():
                known = len(self.get_subscriptions_info_by_topic(pub.topic_name))
                if pub.get_subscription_count() < known:
                    missing.append(f"matching of {known} subscribers on {name}")
        for topic, count in self._wait_topics:
            if self.count_publishers(topic) < 1 or self.count_subscribers(topic) < count:
                missing.append(f"a publisher and {count} subscribers on {topic}")
        return missing

    def _play_once(self) -> None:
        origin = self.source.start_ns  # None: a damaged bag; its first message's time then
        first_ns = None
        wall0 = 0.0
        last_clock = last_ns = None
        for log_ns, topic, data in self.source.messages(self.played):
            if self._stop.is_set():
                return
            if origin is None:
                origin = log_ns
            start = origin + self.offset_ns
            if log_ns < start:
                continue
            if self.duration_ns is not None and log_ns > start + self.duration_ns:
                break
            if first_ns is None:
                first_ns, wall0 = log_ns, time.monotonic()
            if self.rate > 0:
                due = wall0 + (log_ns - first_ns) / 1e9 / self.rate
                self._sleep_until(due)
                self.lateness.append(time.monotonic() - due)
            if self._clock_pub is not None and log_ns != last_clock:
                self._clock_pub.publish(Clock(clock=conversions.ns_to_time(log_ns)))
                self.clock_published += 1
                last_clock = log_ns
            last_ns = log_ns
            pub = self._pub[topic]
            pub.publish(data)
            self.counts[topic] += 1
        self._played_span_ns = 0 if first_ns is None else last_ns - first_ns
        if self.source.read_problems:
            self.get_logger().warning(
                f"bag is damaged: skipped what does not read ({self.source.read_problems[-1]})")

    def _linger(self) -> None:
        """Before exiting, let the subscribers acknowledge the last messages and the status
        (reliable topics; ``ack_timeout`` in all: a wait that ends as soon as all is
        acknowledged, so a long one costs nothing when the subscribers keep up)."""
        deadline = time.monotonic() + self._ack_timeout
        for pub in [*self._pub.values(), self._diag_pub]:
            left = deadline - time.monotonic()
            if left <= 0 or self._stop.is_set():
                return
            pub.wait_for_all_acked(Duration(seconds=left))

    def _sleep_until(self, due: float) -> None:
        while not self._stop.is_set():
            left = due - time.monotonic()
            if left <= 0:
                return
            time.sleep(min(left, SLICE))

    def _report(self, outcome: str, wall: float, rounds: int) -> None:
        span = self._played_span_ns / 1e9
        total = sum(self.counts.values())
        values = {"outcome": outcome, "messages": total, "wall_time_s": wall,
                  "bag_time_played_s": span, "rounds": rounds,
                  "messages_per_s": total / wall if wall > 0 else float("inf"),
                  "real_time_factor": span * rounds / wall if wall > 0 else float("inf")}
        if self.lateness:
            late = np.asarray(self.lateness)
            values.update(lateness_median_s=float(np.median(late)),
                          lateness_p99_s=float(np.percentile(late, 99)),
                          lateness_max_s=float(late.max()))
        values.update({f"published:{t}": n for t, n in self.counts.items()})
        if self._clock_pub is not None:
            values["published:/clock"] = self.clock_published
        damaged = self.source.damage
        promised = self.source.promised(self.played)
        # Whether everything the bag's index promises was read: only a whole reading
        # (no start offset or duration) of an indexed bag can tell.
        whole = self.source.complete and self.offset_ns == 0 and self.duration_ns is None
        read = total // max(rounds, 1)
        short = promised - read if whole and self.source.indexed else None
        if damaged:
            values.update(damage=damaged, promised=promised,
                          skipped=-1 if short is None else short)
            self.exit_code = 0 if short == 0 else PLAYED_LESS
        level = conversions.WARN if damaged else conversions.OK
        text = f"played {total} messages of {self.source.path} in {wall:.3g} s"
        if damaged:
            text += (f"; the bag is damaged: played {read} of the {promised} messages its "
                     + ("index promises" if self.source.indexed else "readable part holds")
                     + ("" if short is None else f" ({short} skipped)")
                     + f", every chunk whose CRC holds ({damaged})")
        self.summary = values
        self.get_logger().info(text)
        self._diag_pub.publish(conversions.diagnostic_array(
            self.get_clock().now().to_msg(),
            [conversions.diagnostic_status(level, "bag_player: playback", text, values,
                                           "aero_dva_sim")]))

    def close(self) -> None:
        """Stop the playing thread (idempotent)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            # the node is destroyed next: the thread must be out of its publish calls first
            # (it checks the stop between two messages; the bound only ends a hang)
            self._thread.join(timeout=60.0)
            if self._thread.is_alive():
                raise RuntimeError("the playing thread did not stop within 60 s")


if __name__ == "__main__":
    sys.exit(main())
