"""ROS glue shared by every node: the executor and how it spins, the body of ``main`` (with
``--help`` from the node's parameter table, :mod:`dva_ros_common.node_params`) and input health
on ``/diagnostics``.

Executor: rclpy's default executor rebuilds its wait set in Python for every callback, which
held the node graph far below the events executor's rate (``bench/bench_graph.py`` measures both;
docs/performance.md). Jazzy ships ``rclpy.experimental.EventsExecutor`` (a C++ event queue; the
same callbacks, timers, futures and raw subscriptions). ``DVA_EXECUTOR`` chooses: ``events``
(default) or ``single_threaded`` (rclpy's default). The events executor of the Jazzy wheels
neither returns from an unbounded spin when the context is shut down (SIGINT/SIGTERM) nor from
``spin_until_future_complete`` without a timeout, so :func:`spin` always spins in bounded
slices and checks between them.

:class:`InputHealth` reads the parameters of :data:`INPUT_HEALTH_PARAMS` (a node lists them
in its parameter table, :mod:`dva_ros_common.node_params`): ``stale_timeout`` [s] ROS time
without input after which the periodic status turns WARN, and ``diagnostic_period`` [s] ROS time
between periodic status reports on ``/diagnostics`` (also the least wall time between two
reports of the same kind of event).
"""
from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable, Mapping

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.task import Future

from aero_dva import exits
from aero_dva.bag.channels import DIAGNOSTICS
from aero_dva.text_input import loggable
from dva_ros_common.conversions import ERROR, WARN, diagnostic_array, diagnostic_status
from dva_ros_common.node_params import (  # noqa: F401 - DATA_DEPTH: its users import it here
    DATA_DEPTH,
    INPUT_HEALTH_PARAMS,
    NodeSpec,
    command_line,
    declare_parameters,
)
from dva_ros_common.shared_memory import clear_dead_ports

#: Most characters of a node's one-line start-up error.
ERROR_CHARS = 600


#: A node's own status: level, message and extra key/values for ``/diagnostics``.
Status = tuple[int, str, Mapping[str, object]]


class InputHealth:
    """Diagnostics of a node driven by one input topic.

    Events (:meth:`report`) and a periodic status go to ``/diagnostics`` under the status name
    ``"<node>: <subject>"``. The status is the node's own (``status()``) with its ``counts``,
    except that stale input replaces it with a WARN; only a node's ERROR outranks stale input.
    """

    def __init__(
        self,
        node: Node,
        subject: str,
        input_topic: str,
        counts: Mapping[str, int],
        status: Callable[[], Status],
    ) -> None:
        values = {}
        for row in INPUT_HEALTH_PARAMS:  # declared from the node's table, or here
            if not node.has_parameter(row.name):
                declare_parameters(node, NodeSpec(node.get_name(), "", "", (row,)))
            values[row.name] = float(node.get_parameter(row.name).value)
        self._node = node
        self._input_topic = input_topic
        self._counts = counts
        self._status = status
        self._stale_ns = round(values["stale_timeout"] * 1e9)
        self._period = values["diagnostic_period"]
        self.name = f"{node.get_fully_qualified_name().lstrip('/')}: {subject}"
        self._last_input_ns: int | None = None
        self._first_tick_ns: int | None = None
        self._last_report: dict[str, float] = {}
        self._pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS.name, 10)
        node.create_timer(self._period, self._publish_status)

    def mark_input(self) -> int:
        """Note that input arrived; return the node's ROS time of it [ns]."""
        self._last_input_ns = self._node.get_clock().now().nanoseconds
        return self._last_input_ns

    def report(self, level: int, event: str, text: str, **values) -> None:
        """Publish one event on /diagnostics, at most once per period for each kind of event
        (wall time, so a stopped sim clock cannot mute it); the caller's counts take every one."""
        wall = time.monotonic()
        last = self._last_report.get(event)
        if last is not None and wall - last < self._period:
            return
        self._last_report[event] = wall
        self._node.get_logger().warning(text)
        self._publish(level, text, dict(event=event, **values))

    def _publish_status(self) -> None:
        now = self._node.get_clock().now().nanoseconds
        if self._first_tick_ns is None or now < self._first_tick_ns:
            self._first_tick_ns = now  # start, or the clock jumped back (a new sim run)
        since = self._last_input_ns if self._last_input_ns is not None else self._first_tick_ns
        age = max(now - since, 0) / 1e9
        level, text, values = self._status()
        if now - since > self._stale_ns and level != ERROR:
            level, text = WARN, f"stale input: no {self._input_topic} for {age:.3g} s"
        self._publish(level, text, dict(self._counts, event="status", input_age=age, **values))

    def _publish(self, level: int, text: str, values: Mapping[str, object]) -> None:
        stamp = self._node.get_clock().now().to_msg()
        status = diagnostic_status(level, self.name, text, values)
        self._pub.publish(diagnostic_array(stamp, [status]))


#: What rclpy raises when a node is built on a context that a signal has just shut down.
RCLError = _rclpy.RCLError
ENV_VAR = "DVA_EXECUTOR"
EXECUTORS = ("events", "single_threaded")
SLICE = 0.02  # [s] wall time between checks for shutdown (a signal waits for the slice's end)


def make_executor() -> Executor:
    """A new executor of the kind ``$DVA_EXECUTOR`` names (default: events)."""
    kind = os.environ.get(ENV_VAR) or "events"
    if kind not in EXECUTORS:
        raise ValueError(f"{ENV_VAR}={kind!r} is not one of {', '.join(EXECUTORS)}")
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:  # an rclpy older than Jazzy
        kind = "single_threaded"
    return EventsExecutor() if kind == "events" else SingleThreadedExecutor()


def spin(executor: Executor, until: Future | None = None,
         stop_when: Callable[[], bool] | None = None) -> None:
    """Spin until ``until`` is done (for ever without one) or ``stop_when()`` is true; raise
    ExternalShutdownException when the context is shut down, as ``rclpy.spin`` does."""
    until = until or Future()
    while not until.done() and not (stop_when and stop_when()):
        if not rclpy.ok():
            raise ExternalShutdownException()
        executor.spin_until_future_complete(until, timeout_sec=SLICE)


DRAIN_IDLE = 0.05  # [s] wall time without a message that ends a drain
DRAIN_SETTLE = 0.01  # [s] the same once the node holds what it waits for (stragglers only)
DRAIN_LIMIT = 5.0  # [s] wall time a drain takes at most


def _drain(executor: Executor, taken: Callable[[], int],
           complete: Callable[[], bool | None] | None = None) -> tuple[int, float]:
    """Take the messages that arrived before a stop request and wait in the executor's queue:
    spin until ``taken()`` has not grown for DRAIN_IDLE s, at most DRAIN_LIMIT s. With
    ``complete`` (whether the node holds every message it knows were sent; None: it does not
    know), spin while it is False, and once it is True only until DRAIN_SETTLE s pass without
    a message. Returns the messages taken and the wall time it took [s]."""
    start = time.monotonic()
    first = last = taken()
    quiet_since = start
    while time.monotonic() < start + DRAIN_LIMIT:
        executor.spin_once(timeout_sec=0.002)
        now = taken()
        if now != last:
            last, quiet_since = now, time.monotonic()
            continue
        done = None if complete is None else complete()
        quiet = time.monotonic() - quiet_since
        if (done is None and quiet >= DRAIN_IDLE) or (done and quiet >= DRAIN_SETTLE):
            break
    return last - first, time.monotonic() - start


class _Signals:
    """SIGINT and SIGTERM, caught in place of rclpy's handlers: ``received`` is the first
    signal's number (None before one).

    rclpy's handlers shut the context down at once (dropping every message still queued) and
    then chain to Python's own SIGINT handler, whose KeyboardInterrupt lands wherever the
    interpreter happens to be - once inside the very handler that was cleaning up after the
    shutdown (a CI run: exit code -2 instead of 0). These only note the signal; the spin loop
    reads it between slices and the node stops in order. The handler takes no lock: it runs
    between two bytecodes of the main thread, which may hold any lock at that moment."""

    def __init__(self) -> None:
        self.received: int | None = None
        signal.signal(signal.SIGINT, self._note)
        signal.signal(signal.SIGTERM, self._note)

    def _note(self, signum, _frame) -> None:
        if self.received is None:
            self.received = signum

    def __call__(self) -> bool:
        return self.received is not None


def close_executor(executor: Executor, *nodes: Node) -> None:
    """Shut ``executor`` down, then destroy its nodes and ``nodes``; call it once nothing spins.

    rclpy's Python executor keeps its last wait set and the suspended generator over it
    between two ``spin_once`` calls (rclpy/executors.py, ``_wait_for_ready_callbacks``);
    when it last handed out a QoS event, that generator still holds the event and context
    handles "in use". ``shutdown()`` drops both, so no executor object refers to a node's
    entities when they are destroyed (destroying entities under a live executor is
    ros2/rclpy#319 and #663). A pytest worker died once in
    ``destroy_node`` in the other order (docs/reliability.md); isolated repeats of that order
    did not crash, so this is the safe order, not a proven cause.
    """
    owned = list(executor.get_nodes())
    owned += [node for node in nodes if node not in owned]
    executor.shutdown()
    for node in owned:
        node.destroy_node()


def run_node(node_class: Callable[[], Node], spec: NodeSpec, args=None, *,
             drain: Callable[[Node], int] | None = None,
             complete: Callable[[Node], bool | None] | None = None,
             own_process: bool | None = None) -> int:
    """Body of a node's ``main``: the exit code.

    ``-h``/``--help`` prints the node's parameter table (``spec``) and returns 0 without
    starting ROS; unknown arguments outside ``--ros-args`` return 2, as do bad parameters or
    files (a one-line error). The node spins until its ``done`` future completes, if it has
    one that is not None, or until SIGINT or SIGTERM (:class:`_Signals`: the context
    stays up until the node has stopped). A node with a ``close()`` method has it called
    once at the end, with SIGINT and SIGTERM ignored so that a second Ctrl-C cannot cut it
    short (the recorder closes its bag there). A node's ``exit_code`` attribute, if it has one,
    is the exit code after a normal end (the simulator's 3 for a flight that could not fly).
    A signal ends a node that runs until stopped with 0, and one whose ``done`` future was
    not done yet with 130 (interrupted: aero_dva.exits). An error while spinning or closing
    is one line and exit code 3 (``DVA_DEBUG=1``: the traceback). ``args`` is the whole
    command line (default ``sys.argv``). ``own_process`` (default: ``args`` is None, the
    process's own command line): the process ends here once its node has run
    (:func:`end_process`).

    ``drain(node)``, a count of messages the node has taken: after a signal the node takes
    what is still queued (until the count stops growing, :func:`_drain`) before ``close()``.
    A busy recorder can be a second behind its publishers; without this, a signal would drop
    that second (bench/bench_faults.py). ``complete(node)``: whether it holds every message it
    knows were sent (None: it does not know); the drain waits for that instead of a quiet
    spell.
    """
    from rclpy.signals import SignalHandlerOptions

    code = command_line(spec, sys.argv if args is None else args)
    if code is not None:
        return code
    node_name = spec.name
    signalled = _Signals()  # first: a signal while rclpy starts is noted too
    clear_dead_ports(f"[{node_name}]")  # else the node could hang before its first line
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as exc:  # e.g. ROS_SECURITY_* set without a usable keystore
        return _failed(node_name, exc, "ROS 2 could not start")
    node = None
    code = None
    try:
        try:
            executor = make_executor()  # first: a bad choice must not leave files behind
            node = node_class()
        except RCLError as exc:  # e.g. security asked of a DDS built without it
            return _failed(node_name, exc, "ROS 2 could not create the node")
        except (ValueError, OSError, ParameterException) as exc:  # file errors included
            if exits.debug():
                raise
            # one line, whatever the text it quotes holds (escape codes, newlines, megabytes)
            line = exits.os_error_line(exc) if isinstance(exc, OSError) and exc.strerror \
                else loggable(exc, ERROR_CHARS)
            print(f"{node_name}: error: {line}", file=sys.stderr)
            return exits.os_error_code(exc) if isinstance(exc, OSError) and exc.errno \
                else exits.BAD_INPUT
        executor.add_node(node)
        done = getattr(node, "done", None)
        spin(executor, done, stop_when=signalled)
        if signalled() and done is not None and not done.done():
            code = exits.INTERRUPTED  # its job was cut short
        if drain is not None and signalled():
            taken, took = _drain(executor, lambda: drain(node),
                                 None if complete is None else lambda: complete(node))
            # (in the log: a stop that lost messages can be told from one that had none queued)
            print(f"[{node_name}] stop requested (signal {signalled.received}): took {taken} "
                  f"queued messages in {took:.3f} s", file=sys.stderr)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # a shutdown from outside the node's own handlers: a clean exit
    except RuntimeError as exc:  # RCLError is one
        # The events executor could not hand a message to Python mid-stop (pybind11 "Unable
        # to convert call argument", about 1 in 20 SIGINTs of a busy recorder under rclpy's
        # handlers, bench/bench_faults.py): a clean exit when a stop was asked for.
        if not signalled() and rclpy.ok():
            code = _failed(node_name, exc)
    except Exception as exc:  # a fault while spinning: one line, not a traceback
        code = _failed(node_name, exc)
    finally:
        if node is not None:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            try:
                if hasattr(node, "close"):
                    node.close()
                close_executor(executor, node)
            except Exception as exc:  # the recorder's bag cannot be closed (no space left)
                code = _failed(node_name, exc)
        rclpy.try_shutdown()
    if code is None:  # a node may end in a failure it reports
        code = int(getattr(node, "exit_code", 0) or 0)
    if (args is None if own_process is None else own_process) and node is not None:
        end_process(code)
    return code


def _failed(node_name: str, exc: Exception, what: str | None = None) -> int:
    """Say a node's fault in one line (raise it with ``DVA_DEBUG=1``); its exit code.
    ``what`` failed, if known (else it is an internal error)."""
    if exits.debug():
        raise exc
    if isinstance(exc, OSError):
        line = exits.os_error_line(exc)
    elif what is not None:
        line = f"{what}: {' '.join(str(exc).split())[:300]}"
    else:
        detail = " ".join(str(exc).split())[:200]
        line = (f"internal error ({type(exc).__name__}: {detail}); rerun with DVA_DEBUG=1 for "
                "the traceback")
    print(f"{node_name}: error: {line}", file=sys.stderr)
    return exits.FAILED


def end_process(code: int) -> None:
    """End the process of a node that has stopped and closed (its files written): flush what
    it printed, release its DDS participant, and exit without the interpreter's and the DDS
    library's teardown, which add nothing to a stopped node: Fast DDS's participant factory
    sleeps 100 ms in its destructor, and with Python's own teardown each node took 0.1-0.3 s
    to exit, which ``run_flight`` waits for at every stop (docs/performance.md)."""
    sys.stdout.flush()
    sys.stderr.flush()
    from rclpy.utilities import get_default_context

    get_default_context().destroy()  # deletes the participant: peers see it leave at once
    os._exit(code)
