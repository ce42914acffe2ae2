"""One process of bench/bench_graph_speed.py's round trip: a flight condition out, a damper
command back, between two processes over DDS, as the simulator and the airspeed controller
exchange them in every lockstep block, but with no arithmetic and no other message.

Run (bench_graph_speed.py starts both on a domain of its own)::

    python bench/graph_echo.py echo events|waitset
    python bench/graph_echo.py ping --count N   # prints one JSON line

The ping waits on one rcl wait set and takes each answer itself (the least Python between DDS
and the clock it reads). The echo answers in a subscription callback of the events executor, as
the nodes do (dva_ros_common.node_tools), or, ``waitset``, as the ping does: the difference is
what the executor adds to one message's way in and out of a node.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import rclpy
from rclpy.qos import QoSProfile

from dva_msgs.msg import DamperCommand, FlightCondition

PING, PONG = "bench_echo/condition", "bench_echo/command"
WARM_UP = 50  # round trips before the timed ones (discovery settled, caches warm)


def wait_matched(node, publisher, subscription, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while publisher.get_subscription_count() < 1 or subscription.get_publisher_count() < 1:
        if time.monotonic() > deadline:
            raise SystemExit(f"graph_echo: {node.get_name()}: no match within {timeout} s")
        time.sleep(0.01)


def waitset_loop(node, subscription, on_message, resend=None) -> None:
    """Wait on one rcl wait set for ``subscription``; hand every message taken to
    ``on_message`` until it returns False. With ``resend``: call it every 0.1 s until the
    first message has come (the other side may not have matched yet)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    wait_set = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, node.context.handle)
    while True:
        wait_set.clear_entities()
        wait_set.add_subscription(subscription.handle)
        wait_set.wait(100_000_000 if resend else -1)
        taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
        if taken is None:
            if resend:
                resend()
            continue
        resend = None
        if on_message(taken[0]) is False:
            return


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("role", choices=("ping", "echo"))
    parser.add_argument("mode", nargs="?", choices=("events", "waitset"), default="waitset")
    parser.add_argument("--count", type=int, default=500, help="timed round trips (ping)")
    args = parser.parse_args(argv)
    rclpy.init()
    node = rclpy.create_node(f"bench_echo_{args.role}")
    qos = QoSProfile(depth=10)
    if args.role == "echo":
        publisher = node.create_publisher(DamperCommand, PONG, qos)

        def on_message(msg: FlightCondition) -> bool:
            publisher.publish(DamperCommand(header=msg.header, damping=msg.airspeed,
                                            source="echo"))
            return True
        subscription = node.create_subscription(FlightCondition, PING, on_message, qos)
        try:
            if args.mode == "events":
                from rclpy.experimental import EventsExecutor

                from dva_ros_common.node_tools import spin

                executor = EventsExecutor()
                executor.add_node(node)
                spin(executor)  # in bounded slices, as the nodes spin it
            else:
                waitset_loop(node, subscription, on_message)
        except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
            pass
        return 0

    publisher = node.create_publisher(FlightCondition, PING, qos)
    times: list[float] = []
    sent = [0.0, 0]  # when the ping in flight was sent, and its number

    def send() -> None:
        sent[1] += 1
        msg = FlightCondition(airspeed=100.0, density=1.2)
        msg.header.stamp.sec = sent[1]
        sent[0] = time.perf_counter()
        publisher.publish(msg)

    def on_answer(msg: DamperCommand) -> bool:
        if msg.header.stamp.sec != sent[1]:
            return True  # an answer to a ping resent before the echo had matched
        times.append(time.perf_counter() - sent[0])
        if len(times) >= WARM_UP + args.count:
            return False
        send()
        return True
    subscription = node.create_subscription(DamperCommand, PONG, on_answer, qos)
    wait_matched(node, publisher, subscription)
    # The first answer through a wait set, resent until it comes: the echo has matched too.
    first = node.create_subscription(DamperCommand, PONG, lambda _m: None, qos)
    send()
    waitset_loop(node, first, lambda _m: False, resend=send)
    node.destroy_subscription(first)
    send()
    waitset_loop(node, subscription, on_answer)
    print(json.dumps({"round_trips_s": times[WARM_UP:]}))
    return 0 if len(times) >= WARM_UP + args.count else 1


if __name__ == "__main__":
    sys.exit(main())
