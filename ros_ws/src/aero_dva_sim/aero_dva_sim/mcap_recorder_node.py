"""``mcap_recorder``: record topics to a rosbag2-layout MCAP bag, like ``ros2 bag record -s mcap``.

Topics are discovered while the node runs and recorded as serialized CDR, untouched, with their
``ros2msg`` schemas (and dependencies) from the installed .msg files. On SIGINT/SIGTERM the
recorder first takes what is still queued (it can lag its publishers under load), then closes
the bag cleanly: everything received is in the MCAP file, and ``metadata.yaml`` is written.

Parameters
----------
output : str, default "bags/run_<UTC time>"
    Bag directory to create; it must not exist or be empty (nothing is ever overwritten).
topics : string array, default [] (all topics)
    Record only these topics (names resolved in the node's namespace).
exclude : string array, default []
    Never record these topics.
discovery_period : float, default 0.1
    Wall-clock seconds between looks for new topics.
flush_period : float, default 1.0
    Wall-clock seconds between flushes of the MCAP chunk (bounds what a crash can lose).
"""
from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy

from aero_dva.bag.mcap_io import BagWriter, MessageDefinitionNotFound, qos_profile_yaml
from dva_ros_common.node_tools import run_node


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (rosidl_runtime_py is not available everywhere)."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


class McapRecorder(Node):
    """Subscribe (raw) to every matching topic and append each message to the bag."""

    def __init__(self, **kwargs) -> None:
        super().__init__("mcap_recorder", **kwargs)
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        self.declare_parameter("output", f"bags/run_{stamp}")
        self.declare_parameter("topics", [""])
        self.declare_parameter("exclude", [""])
        self.declare_parameter("discovery_period", 0.1)
        self.declare_parameter("flush_period", 1.0)
        self._only = {self.resolve_topic_name(t) for t in self._strings("topics")}
        self._exclude = {self.resolve_topic_name(t) for t in self._strings("exclude")}
        self.output = Path(self.get_parameter("output").value)
        self._writer = BagWriter(self.output)
        self._recorded: dict[str, object] = {}
        self._skipped: set[str] = set()
        self.received = 0
        try:
            wall = Clock(clock_type=ClockType.STEADY_TIME)
            self.create_timer(float(self.get_parameter("discovery_period").value),
                              self._discover, clock=wall)
            self.create_timer(float(self.get_parameter("flush_period").value), self._flush,
                              clock=wall)
            self._discover()
        except BaseException:  # e.g. a signal while starting: still leave a valid, empty bag
            self._writer.close()
            raise
        self.get_logger().info(f"recording to {self.output}")

    def _strings(self, name: str) -> list[str]:
        return [s for s in self.get_parameter(name).value if s]

    def _wanted(self, topic: str) -> bool:
        return topic not in self._exclude and (not self._only or topic in self._only)

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recorded or topic in self._skipped or not self._wanted(topic):
                continue
            if len(types) != 1:
                self._skip(topic, f"it has several types {types}")
                continue
            try:
                self._writer.add_topic(topic, types[0], qos_profile_yaml())
                msg_type = message_class(types[0])
            except (MessageDefinitionNotFound, ImportError, AttributeError, ValueError) as exc:
                self._skip(topic, str(exc))
                continue
            self._recorded[topic] = self.create_subscription(
                msg_type, topic, lambda data, t=topic: self._record(t, data),
                self._qos_for(topic), raw=True)
            self.get_logger().info(f"recording {topic} [{types[0]}]")

    def _qos_for(self, topic: str) -> QoSProfile:
        # Match what the publishers offer, as rosbag2 does: a reliable reader would not match a
        # best-effort writer, and transient-local writers can replay what came before.
        offered = [info.qos_profile for info in self.get_publishers_info_by_topic(topic)]
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
        self._writer.write(topic, data, self.get_clock().now().nanoseconds)
        self.received += 1

    def _flush(self) -> None:
        if not self._writer.closed:
            self._writer.flush()

    def close(self) -> None:
        """Close the bag (idempotent): footer, summary and metadata.yaml."""
        if not self._writer.closed:
            self._writer.close()
            # After a signal the context is shut down and /rosout is gone: say it on stderr.
            print(f"[mcap_recorder] closed {self.output} with {self.received} messages",
                  file=sys.stderr)


def main(args=None) -> int:
    # On SIGINT/SIGTERM, record what is still queued before closing the bag.
    return run_node(McapRecorder, "mcap_recorder", args, drain=lambda node: node.received)


if __name__ == "__main__":
    sys.exit(main())
