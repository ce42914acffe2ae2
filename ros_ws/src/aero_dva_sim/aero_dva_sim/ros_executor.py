"""The executor the nodes of this package spin in, and how they spin it.

rclpy's default executor rebuilds its wait set in Python for every callback (about 1-2 ms per
simulated block in the simulator and the recorder, profiled), which held the node graph near
10x real time on 2 cores. Jazzy ships ``rclpy.experimental.EventsExecutor`` (a C++ event
queue; the same callbacks, timers, futures and raw subscriptions). ``DVA_EXECUTOR`` chooses:
``events`` or ``single_threaded`` (rclpy's default).

The events executor of the Jazzy wheels neither returns from an unbounded spin when the context
is shut down (SIGINT/SIGTERM) nor from ``spin_until_future_complete`` without a timeout (seen
here: both block for ever), so :func:`spin` always spins in bounded slices and checks between
them.
"""
from __future__ import annotations

import os

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.task import Future

#: What rclpy raises when a node is built on a context that a signal has just shut down.
RCLError = _rclpy.RCLError
ENV_VAR = "DVA_EXECUTOR"
CHOICES = ("events", "single_threaded")
DEFAULT = "events"
SLICE = 0.1  # [s] wall time between checks for shutdown


def make_executor() -> Executor:
    """A new executor of the kind ``$DVA_EXECUTOR`` names (default: events)."""
    kind = os.environ.get(ENV_VAR) or DEFAULT
    if kind not in CHOICES:
        raise ValueError(f"{ENV_VAR}={kind!r} is not one of {', '.join(CHOICES)}")
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:  # an rclpy older than Jazzy
        kind = "single_threaded"
    return EventsExecutor() if kind == "events" else SingleThreadedExecutor()


def spin(executor: Executor, until: Future | None = None) -> None:
    """Spin until ``until`` is done (for ever without one); raise ExternalShutdownException
    when the context is shut down (Ctrl-C, SIGTERM), as ``rclpy.spin`` does."""
    until = until or Future()
    while not until.done():
        if not rclpy.ok():
            raise ExternalShutdownException()
        executor.spin_until_future_complete(until, timeout_sec=SLICE)
