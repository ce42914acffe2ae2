"""Nodes as processes, as ``ros2 run`` starts them, and a probe that logs what they publish.

A :class:`RosSession` reserves a ROS_DOMAIN_ID (so trials and tests never hear each other),
starts node processes on it, and spins an in-process probe node in a background thread. Every
probe record carries the wall time (``time.monotonic()``) it arrived, so a fault injected at a
known wall time can be set against what the graph published before and after it.
"""
from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Log
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSHistoryPolicy, QoSProfile, QoSReliabilityPolicy

from aero_dva_sim.run_flight import die_with_parent, executable
from dva_msgs.msg import (
    AccelerationBlock,
    DamperState,
    DisplacementBlock,
    FlightCondition,
    ForceBlock,
)
from dva_ros_common.node_tools import close_executor
from dva_ros_common.ros_domain import reserved_domain, use_discovery

DATA_TOPICS = {"wing/acceleration": AccelerationBlock, "wing/displacement": DisplacementBlock,
               "wing/excitation": ForceBlock, "flight/condition": FlightCondition,
               "dva/damper_state": DamperState}
RELIABLE_DEEP = QoSProfile(depth=100_000, reliability=QoSReliabilityPolicy.RELIABLE,
                           history=QoSHistoryPolicy.KEEP_LAST)


def stamp_seconds(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def ros_args(**params) -> list[str]:
    """``--ros-args -p name:=value ...`` (lists as ``[a,b]``, strings in a list quoted: rcl
    reads the value as YAML, where ``[topic:1]`` would be a mapping; booleans lower case)."""
    out = ["--ros-args"]
    for name, value in params.items():
        if isinstance(value, bool):
            text = str(value).lower()
        elif isinstance(value, (list, tuple)):
            text = "[" + ",".join(json.dumps(v) if isinstance(v, str) else str(v)
                                  for v in value) + "]"
        else:
            text = str(value)
        out += ["-p", f"{name}:={text}"]
    return out


class NodeProcess:
    """A node executable run as a process on the session's domain; output to a log file."""

    def __init__(self, name: str, argv: list[str], domain: int, log_path: Path):
        self.name = name
        self.log_path = log_path
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
        with open(log_path, "wb") as log:
            self.proc = subprocess.Popen(argv, env=env, stdout=log, stderr=subprocess.STDOUT,
                                         preexec_fn=die_with_parent)

    def signal(self, number: int) -> float:
        """Send a signal; the wall time (monotonic) it was sent."""
        sent = time.monotonic()
        self.proc.send_signal(number)
        return sent

    def wait(self, timeout: float) -> int | None:
        """The exit code, or None if it is still running after ``timeout`` seconds."""
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None

    def stop(self, timeout: float = 10.0) -> int:
        """SIGINT, then SIGKILL after ``timeout`` s; the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            if self.wait(timeout) is None:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")


@dataclass(frozen=True)
class Block:
    wall: float
    first_sample_index: int
    stamp: float


@dataclass(frozen=True)
class StateRecord:
    wall: float
    stamp: float
    applied: float
    commanded: float
    status: int
    command_age: float
    source: str


@dataclass(frozen=True)
class DiagnosticRecord:
    wall: float
    stamp: float
    level: int
    name: str
    message: str
    values: dict


@dataclass(frozen=True)
class LogRecord:
    wall: float
    level: int
    name: str
    message: str


class Probe(Node):
    """Logs acceleration blocks, damper states, /diagnostics and /rosout with arrival times.

    ``data_topics``: subscribe to every data topic of the simulator (so that a simulator
    waiting for two subscribers per topic waits for this probe as well as the recorder).
    """

    def __init__(self, context: Context, data_topics: bool = False, rosout: bool = False):
        super().__init__("fault_probe", context=context)
        self.blocks: list[Block] = []
        self.states: list[StateRecord] = []
        self.diagnostics: list[DiagnosticRecord] = []
        self.logs: list[LogRecord] = []
        self.create_subscription(AccelerationBlock, "wing/acceleration", self._on_block,
                                 RELIABLE_DEEP)
        self.create_subscription(DamperState, "dva/damper_state", self._on_state, RELIABLE_DEEP)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics,
                                 RELIABLE_DEEP)
        if rosout:
            self.create_subscription(Log, "/rosout", self._on_log, RELIABLE_DEEP)
        if data_topics:  # the others only count as subscribers: raw, never decoded
            for topic, kind in DATA_TOPICS.items():
                if topic not in ("wing/acceleration", "dva/damper_state"):
                    self.create_subscription(kind, topic, lambda _: None, RELIABLE_DEEP,
                                             raw=True)

    def _on_block(self, msg: AccelerationBlock) -> None:
        self.blocks.append(Block(time.monotonic(), int(msg.first_sample_index),
                                 stamp_seconds(msg.header.stamp)))

    def _on_state(self, msg: DamperState) -> None:
        self.states.append(StateRecord(time.monotonic(), stamp_seconds(msg.header.stamp),
                                       msg.applied_damping, msg.commanded_damping, msg.status,
                                       msg.command_age, msg.source))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        wall = time.monotonic()
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            level = status.level  # a byte in rclpy
            level = level[0] if isinstance(level, bytes) else int(level)
            self.diagnostics.append(DiagnosticRecord(wall, stamp_seconds(msg.header.stamp),
                                                     level, status.name, status.message, values))

    def _on_log(self, msg: Log) -> None:
        self.logs.append(LogRecord(time.monotonic(), int(msg.level), msg.name, msg.msg))


SPINNER_STOP_TIMEOUT = 120.0  # [s] wall time for the probe's spin thread to stop


class RosSession:
    """A reserved domain, an rclpy context with a probe spinning in a thread, node processes.

    Use :func:`ros_session`; it stops every process and the spinner at the end.
    """

    def __init__(self, domain: int, context: Context, log_dir: Path):
        self.domain = domain
        self.context = context
        self.log_dir = log_dir
        self.processes: list[NodeProcess] = []
        self.executor = SingleThreadedExecutor(context=context)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.probe: Probe | None = None

    def start_probe(self, **options) -> Probe:
        self.probe = Probe(self.context, **options)
        self.executor.add_node(self.probe)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()
        return self.probe

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.02)

    def node(self, name: str) -> Node:
        """An in-process node on the session's context (not spun: for publishers)."""
        return Node(name, context=self.context)

    def start(self, package: str, name: str, **params) -> NodeProcess:
        argv = [executable(package, name), *ros_args(**params)]
        process = NodeProcess(name, argv, self.domain,
                              self.log_dir / f"{name}_{len(self.processes)}.log")
        self.processes.append(process)
        return process

    def close(self) -> None:
        for process in reversed(self.processes):
            process.stop()
        self._stop.set()
        if self._thread is not None:
            # Wait for the spinner to leave spin_once: a node must not be destroyed while
            # another thread is inside the executor (the 5 s this waited before could run out
            # on a loaded machine). It stops within one wait (0.02 s) and one callback; the
            # bound only keeps a hang from lasting forever.
            self._thread.join(timeout=SPINNER_STOP_TIMEOUT)
            if self._thread.is_alive():
                raise RuntimeError(f"the probe's spin thread did not stop within "
                                   f"{SPINNER_STOP_TIMEOUT:.0f} s; its nodes are left as they "
                                   "are (destroying them under a running executor crashes)")
        close_executor(self.executor)


@contextlib.contextmanager
def ros_session(log_dir: Path) -> Iterator[RosSession]:
    """A :class:`RosSession` on a ROS_DOMAIN_ID reserved for it, discovering on this host only
    (as the project's runs do; the environment's range is kept)."""
    log_dir.mkdir(parents=True, exist_ok=True)
    use_discovery()
    with reserved_domain() as domain:
        context = Context()
        rclpy.init(context=context, domain_id=domain)
        session = RosSession(domain, context, log_dir)
        try:
            yield session
        finally:
            session.close()
            rclpy.try_shutdown(context=context)


def wait_until(condition: Callable[[], bool], timeout: float, poll: float = 0.002) -> bool:
    """Poll ``condition`` until it holds or ``timeout`` [s] of wall time passed."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll)
    return True


def write_scenario(path: Path, *, duration: float, airspeed_ratio: float = 0.9,
                   seed: int = 1) -> Path:
    """A constant-airspeed scenario below flutter (the wing neither diverges nor stops)."""
    path.write_text(
        f"name: faults\nduration: {duration}\nsample_rate: 1000.0\nblock_size: 50\n"
        f"airspeed: {{kind: constant, value_ratio: {airspeed_ratio}}}\ndensity: {{base: 1.2}}\n"
        f"excitation: {{force_std: 1000.0, seed: {seed}}}\n", encoding="utf-8")
    return path
