"""``mcap_recorder``: record topics to a rosbag2-layout MCAP bag, like ``ros2 bag record -s mcap``.

Topics are discovered while the node runs and recorded as serialized CDR, untouched, with their
``ros2msg`` schemas (and dependencies) from the installed .msg files. On SIGINT/SIGTERM the
recorder first takes what is still queued (it can lag its publishers under load), then closes
the bag cleanly: everything received is in the MCAP file, and ``metadata.yaml`` is written.
Once it has recorded the simulator's end-of-flight report, which counts what the simulator
published on each topic and the commands it received (the answer to the last block's input
included), it takes queued messages until it holds every one of them (at most
``dva_ros_common.node_tools.DRAIN_LIMIT`` s), and says on closing whether it does. As soon as
it holds them it says so on ``dva/recorded`` (a topic it does not record), stamped with the
report's stamp: the simulator exits on that word (DDS acknowledgements would wait for the
writer's next heartbeat, up to 3 s).

Its parameters (units, defaults, ranges) are the table ``SPEC`` of
:mod:`aero_dva_sim.mcap_recorder_spec`, which the node declares them from and
``mcap_recorder --help`` prints. Log times are the node's clock: sim time with
``use_sim_time:=true``.
"""
from __future__ import annotations

import math
import sys
import time
from collections import Counter
from pathlib import Path

import yaml
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy

from aero_dva.atomic_io import unique_directory
from aero_dva.bag import channels as ch
from aero_dva.bag.schemas import MessageDefinitionNotFound
from aero_dva.bag.writer import BagWriter, qos_profile_yaml
from aero_dva.text_input import loggable
from aero_dva_sim.mcap_recorder_spec import SPEC, main
from dva_ros_common.conversions import diagnostic_array, diagnostic_status, message_class
from dva_ros_common.node_params import declare_parameters
from dva_ros_common.node_tools import RCLError

#: The simulator's counts of a topic in its flight reports: what it published, and what it
#: received (the commands, the answer to its last input included).
COUNTED = ("published:", "received:")


def offered_qos_yaml(profiles) -> str:
    """``offered_qos_profiles`` YAML (rosbag2 metadata) of the publishers' rclpy QoS profiles.

    The graph does not tell a remote publisher's history: it is stored as system_default
    (depth 0), as rosbag2 stores it; reliability and durability are what a player needs."""
    rows = []
    for q in profiles:
        def name(policy, known):
            text = getattr(policy, "name", str(policy)).lower()
            return text if text in known else "system_default"

        rows += yaml.safe_load(qos_profile_yaml(
            reliability=name(q.reliability, ("reliable", "best_effort")),
            durability=name(q.durability, ("volatile", "transient_local")),
            history=name(q.history, ("keep_last", "keep_all")),
            depth=max(int(q.depth), 0)))
    return yaml.safe_dump(rows, sort_keys=False).strip() if rows else qos_profile_yaml()


class McapRecorder(Node):
    """Subscribe (raw) to every matching topic and append each message to the bag."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        self._only = {self._resolve(t, "topics") for t in self._strings("topics")}
        self._exclude = {self._resolve(t, "exclude") for t in self._strings("exclude")}
        # a default name another recorder took in the same second moves on to <name>_2, ...
        self.output = Path(values["output"]) if values["output"] else \
            unique_directory(Path(f"bags/run_{stamp}"), "bag")
        self._expect_report = bool(values["expect_flight_report"])
        self._writer = BagWriter(self.output)
        self._recorded: dict[str, object] = {}
        self._skipped: set[str] = set()
        self.received = 0
        self.received_by_topic: Counter[str] = Counter()
        self.lost_by_topic: Counter[str] = Counter()  # samples DDS reports lost to us
        # topic -> messages the simulator published (or received: the commands), from its last
        # flight report (None: none)
        self.simulator_counted: dict[str, int] | None = None
        self._report_stamp = None  # the header stamp of that report, until it is said recorded
        self._max_bytes = int(values["max_message_bytes"])
        self._oversized: Counter[str] = Counter()  # messages too large to record, by topic
        self._oversized_said: dict[str, float] = {}
        self._diagnostics = self.resolve_topic_name(ch.DIAGNOSTICS.name)
        self._diagnostic_type = message_class(ch.DIAGNOSTICS.type_name)
        self._word_topic = self.resolve_topic_name(ch.RECORDED.name)
        # The word needs the flight report: a recorder that leaves /diagnostics out offers
        # none, and the simulator then waits for DDS acknowledgements instead.
        self._word = self.create_publisher(message_class(ch.RECORDED.type_name),
                                           ch.RECORDED.name, 10) \
            if self._wanted(self._diagnostics) else None
        try:
            wall = Clock(clock_type=ClockType.STEADY_TIME)
            self.create_timer(float(values["discovery_period"]),
                              self._discover, clock=wall)
            self.create_timer(float(values["flush_period"]), self._flush,
                              clock=wall)
            self._discover()
        except BaseException:  # e.g. a signal while starting: still leave a valid, empty bag
            self._writer.close()
            raise
        self.get_logger().info(f"recording to {self.output}")

    def _resolve(self, topic: str, parameter: str) -> str:
        """``topic`` resolved in the node's namespace; ValueError (one line) if it is not a
        valid topic name."""
        try:
            return self.resolve_topic_name(topic)
        except RCLError as exc:
            reason = str(exc).split(": ", 1)[-1].split(", at ")[0]
            raise ValueError(f"parameter '{parameter}': '{loggable(topic)}' is not a valid "
                             f"topic name ({reason})") from None

    def _strings(self, name: str) -> list[str]:
        return [s for s in self.get_parameter(name).value if s]

    def _wanted(self, topic: str) -> bool:
        return topic not in self._exclude and topic != self._word_topic and (
            not self._only or topic in self._only)

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recorded or topic in self._skipped or not self._wanted(topic):
                continue
            if len(types) != 1:
                self._skip(topic, f"it has several types {types}")
                continue
            offered = [info.qos_profile for info in self.get_publishers_info_by_topic(topic)]
            try:
                self._writer.add_topic(topic, types[0], offered_qos_yaml(offered))
                msg_type = message_class(types[0])
            except (MessageDefinitionNotFound, ImportError, AttributeError, ValueError) as exc:
                self._skip(topic, str(exc))
                continue
            self._recorded[topic] = self.create_subscription(
                msg_type, topic, lambda data, t=topic: self._record(t, data),
                self._qos_for(offered), raw=True,
                event_callbacks=SubscriptionEventCallbacks(
                    message_lost=lambda info, t=topic: self._lost(t, info)))
            self.get_logger().info(f"recording {topic} [{types[0]}]")

    @staticmethod
    def _qos_for(offered) -> QoSProfile:
        # Match what the publishers offer, as rosbag2 does: a reliable reader would not match a
        # best-effort writer, and transient-local writers can replay what came before.
        reliable = all(q.reliability == QoSReliabilityPolicy.RELIABLE for q in offered)
        latched = offered and all(
            q.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL for q in offered)
        return QoSProfile(
            depth=1000,
            reliability=QoSReliabilityPolicy.RELIABLE if reliable
            else QoSReliabilityPolicy.BEST_EFFORT,
            durability=QoSDurabilityPolicy.TRANSIENT_LOCAL if latched
            else QoSDurabilityPolicy.VOLATILE,
        )

    def _skip(self, topic: str, why: str) -> None:
        self._skipped.add(topic)
        self.get_logger().warning(f"not recording {topic}: {why}")

    def _record(self, topic: str, data: bytes) -> None:
        if len(data) > self._max_bytes:
            self._oversized[topic] += 1
            wall = time.monotonic()
            if wall - self._oversized_said.get(topic, -math.inf) >= 1.0:
                self._oversized_said[topic] = wall
                self.get_logger().warning(
                    f"{loggable(topic)}: a message of {len(data):,} bytes not recorded (more "
                    f"than max_message_bytes {self._max_bytes:,}; {self._oversized[topic]} "
                    "on this topic)")
            return
        self._writer.write(topic, data, self.get_clock().now().nanoseconds)
        self.received += 1
        self.received_by_topic[topic] += 1
        if topic == self._diagnostics:
            self._read_flight_report(data)
        if self._report_stamp is not None and self.complete():
            self._say_recorded()

    def _read_flight_report(self, data: bytes) -> None:
        """Keep the simulator's counts of what it published and received, from its flight
        reports: the messages on those topics the bag must hold (the topics it records: one it
        leaves out is not waited for)."""
        from rclpy.serialization import deserialize_message

        report = deserialize_message(data, self._diagnostic_type)
        for status in report.status:
            if status.name != ch.FLIGHT_DIAGNOSTIC_NAME:
                continue
            counts = {topic: int(kv.value) for kv in status.values
                      if kv.key.startswith(COUNTED) and self._wanted(
                          topic := self.resolve_topic_name(kv.key.partition(":")[2]))}
            if counts:
                self.simulator_counted = counts
                self._report_stamp = report.header.stamp

    def _say_recorded(self) -> None:
        """Say on ``dva/recorded`` that the bag holds every message of the last flight report
        (or knows it lost), once per report; the simulator waits for this before it exits."""
        values = {f"recorded:{t}": self.received_by_topic[t] for t in self.simulator_counted}
        values.update({f"lost:{t}": n for t, n in self.lost_by_topic.items() if n})
        self._word.publish(diagnostic_array(self._report_stamp, [diagnostic_status(
            0, ch.RECORDED_NAME, "every message the flight report counts is recorded",
            values, self.get_fully_qualified_name())]))
        self._report_stamp = None

    def complete(self) -> bool | None:
        """Whether every message the simulator's flight report counts (published, or received:
        the commands) is in the bag or known lost (its reader's lost-sample events; it cannot
        come any more), None before such a report has come (False with
        ``expect_flight_report``: the report itself is still to come)."""
        if self.simulator_counted is None:
            return False if self._expect_report else None
        return all(self.received_by_topic[t] + self.lost_by_topic[t] >= n
                   for t, n in self.simulator_counted.items())

    def _lost(self, topic: str, info) -> None:
        # A sample this reader's transport dropped (its process starved) after the writer had
        # let it go from its history, so it cannot come again: not in the bag, and said so.
        # Counted from the running total: under load the event comes many times with a
        # change of 0 and the total already raised (a loaded integration run logged 2489 lost,
        # "0 lost" each time, and a closing line without them).
        total = int(info.total_count)
        new = total - self.lost_by_topic[topic]
        if new <= 0:
            return
        self.lost_by_topic[topic] = total
        self.get_logger().warning(f"{topic}: {new} message(s) lost before they reached the "
                                  f"recorder ({total} in all)")

    def _flush(self) -> None:
        if not self._writer.closed:
            self._writer.flush()

    def close(self) -> None:
        """Close the bag (idempotent): footer, summary and metadata.yaml."""
        if not self._writer.closed:
            self._writer.close()
            # After a signal the context is shut down and /rosout is gone: say it on stderr.
            lost = sum(self.lost_by_topic.values())
            said = f" ({lost} lost before reaching it: {dict(self.lost_by_topic)})" if lost else ""
            if self._oversized:
                said += (f" ({sum(self._oversized.values())} too large, not recorded: "
                         f"{loggable(dict(self._oversized), 300)})")
            print(f"[mcap_recorder] closed {self.output} with {self.received} messages{said}"
                  f"{self._completeness()}", file=sys.stderr)

    def _completeness(self) -> str:
        if self.simulator_counted is None:
            return ""
        wanted = sum(self.simulator_counted.values())
        missing = sum(max(0, n - self.received_by_topic[t])
                      for t, n in self.simulator_counted.items())
        return (f"; all {wanted} its flight report counts" if not missing else
                f"; {missing} of the {wanted} its flight report counts missing")


if __name__ == "__main__":
    sys.exit(main())
