"""A publisher that holds its first messages until enough subscribers have matched it.

DDS matches the two ends of a topic separately: a controller can hear the simulator's first
block before its own command publisher has matched the simulator or the recorder, and a message
sent then is lost to whoever has not matched yet. In ``run_flight`` the simulator holds sim time
until the first command arrives, so holding the first commands until the simulator and the
recorder have both matched costs nothing and loses none. Once open, the gate stays open.
"""
from __future__ import annotations

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from dva_ros_common.node_tools import DATA_DEPTH

POLL_PERIOD = 0.005  # [s] wall time between looks at the matched count while holding
MAX_HELD = 10000  # messages held at most; the oldest go first beyond it


class HeldPublisher:
    """``publish`` as rclpy's, except that messages wait until ``count`` subscribers match
    (:data:`dva_ros_common.node_params.HOLD_PARAM` is the row of a node's table that sets it).

    Its writer on ``topic`` keeps :data:`~dva_ros_common.node_tools.DATA_DEPTH` messages: what
    it publishes is recorded, and a starved recorder must still get it whole."""

    def __init__(self, node: Node, msg_type, topic: str, count: int) -> None:
        self._publisher = node.create_publisher(msg_type, topic, DATA_DEPTH)
        self._count = int(count)
        self._held: list = []
        self._timer = None
        if self._count > 0:
            self._timer = node.create_timer(POLL_PERIOD, self._release,
                                            clock=Clock(clock_type=ClockType.STEADY_TIME))

    @property
    def open(self) -> bool:
        return self._timer is None

    def publish(self, msg) -> None:
        if self._timer is None:
            self._publisher.publish(msg)
            return
        self._held.append(msg)
        del self._held[:-MAX_HELD]
        self._release()

    def _release(self) -> None:
        if self._timer is None or self._publisher.get_subscription_count() < self._count:
            return
        self._timer.cancel()
        self._timer = None
        held, self._held = self._held, []
        for msg in held:
            self._publisher.publish(msg)
