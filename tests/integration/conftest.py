"""Launch-free ROS 2 integration harness.

Each test gets its own rclpy Context initialised with a ROS_DOMAIN_ID reserved for this process
(dva_ros_common.ros_domain), so tests never see each other's traffic, and executors are spun
until a condition holds or a timeout passes: no sleeps as synchronisation.
"""
from __future__ import annotations

import os
import signal
import subprocess
import time
import weakref
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

try:
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from aero_dva_sim.run_flight import die_with_parent
    from dva_ros_common.node_tools import close_executor
    from dva_ros_common.ros_domain import reserved_domain
    from dva_ros_common.shared_memory import remove_unsized_ports
except ImportError as exc:  # pragma: no cover - environment problem, reported clearly
    raise pytest.UsageError(
        f"integration tests need rclpy and the built workspace ({exc}); run ./test.sh, or "
        "source scripts/env.sh first"
    ) from exc

pytestmark = pytest.mark.ros


@pytest.fixture(scope="session", autouse=True)
def broken_shared_memory_ports_removed() -> None:
    """Fast DDS port files a dead process left unsized would hang every test's graph
    (dva_ros_common.shared_memory)."""
    remove_unsized_ports()


@pytest.fixture
def ros_domain() -> Iterator[int]:
    """A ROS_DOMAIN_ID no other test process uses while the test runs."""
    with reserved_domain() as reserved:
        yield reserved


#: Every rclpy node this process makes: a node nobody destroys outlives its context's shutdown
#: (its DDS participant stays in the domain), and the domain, released after the test, is the
#: next test's: its graph then meets the old node (a switching_controller a test had only
#: removed from its executor stopped later flights as a second commander).
_NODES: weakref.WeakSet = weakref.WeakSet()
_node_init = Node.__init__


def _tracked_init(self, *args, **kwargs) -> None:
    _node_init(self, *args, **kwargs)
    _NODES.add(self)


Node.__init__ = _tracked_init


def _alive(node: Node) -> bool:
    try:
        node.get_name()
    except Exception:  # rclpy's InvalidHandle: destroyed
        return False
    return True


@pytest.fixture
def ros_context(ros_domain: int) -> Iterator[Context]:
    """A fresh, initialised rclpy Context on the test's own domain. A node of it the test left
    alive is destroyed before the domain is released, and fails the test."""
    context = Context()
    rclpy.init(context=context, domain_id=ros_domain)
    try:
        yield context
    finally:
        leaked = [node for node in list(_NODES) if node.context is context and _alive(node)]
        names = sorted(node.get_fully_qualified_name() for node in leaked)
        for node in leaked:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    if names:
        pytest.fail(f"the test left node(s) {names} alive: destroyed now, before its domain "
                    "is released")


@pytest.fixture
def executor(ros_context: Context) -> Iterator[SingleThreadedExecutor]:
    """A single-threaded executor bound to the test's context; its nodes are destroyed after."""
    exe = SingleThreadedExecutor(context=ros_context)
    try:
        yield exe
    finally:
        close_executor(exe)


#: Every wait's timeout is multiplied by this (DVA_TEST_TIMEOUT_SCALE). A wait returns as soon as
#: its condition holds, so a long timeout costs nothing on a passing test; the timeouts written in
#: the tests are what an idle machine needs, and a busy two-core machine (the tests beside other
#: jobs, or two pytest workers) can be several times slower.
TIMEOUT_SCALE = float(os.environ.get("DVA_TEST_TIMEOUT_SCALE", "4"))


def spin_until(executor, condition: Callable[[], bool], timeout: float) -> bool:
    """Spin ``executor`` until ``condition()`` is true or ``timeout`` x :data:`TIMEOUT_SCALE`
    [s] of wall time passed."""
    deadline = time.monotonic() + timeout * TIMEOUT_SCALE
    while not condition():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        executor.spin_once(timeout_sec=min(0.05, remaining))
    return True


@pytest.fixture
def spin():
    """``spin(executor, condition, timeout)`` -> bool, see :func:`spin_until`."""
    return spin_until


def ros2_run_path(package: str, executable: str) -> Path:
    """Resolve an executable exactly as ``ros2 run`` does: ament index prefix + lib/<pkg>/<exe>."""
    from ament_index_python.packages import get_package_prefix

    return Path(get_package_prefix(package)) / "lib" / package / executable


class NodeProcess:
    """A node started as a subprocess (as ``ros2 run`` would), stopped with SIGINT."""

    def __init__(self, argv: list[str], domain: int, log_path: Path):
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
        self.log_path = log_path
        self._log = open(log_path, "wb")  # noqa: SIM115 - closed in stop()
        # A node must not outlive the test run (it would talk on a domain no longer reserved).
        self.proc = subprocess.Popen(argv, env=env, stdout=self._log, stderr=subprocess.STDOUT,
                                     preexec_fn=die_with_parent)

    def stop(self, timeout: float = 60.0, signal_number: int = signal.SIGINT) -> int:
        """SIGINT (or ``signal_number``), wait up to ``timeout`` s (then kill); the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal_number)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()
        return self.proc.returncode

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")


@pytest.fixture
def start_process(ros_domain: int, tmp_path: Path):
    """``start_process(argv)`` -> NodeProcess on the test's domain; all are stopped after."""
    started: list[NodeProcess] = []

    def start(argv: list[str]) -> NodeProcess:
        log_path = tmp_path / f"proc{len(started)}.log"
        process = NodeProcess([str(a) for a in argv], ros_domain, log_path)
        started.append(process)
        return process

    yield start
    for process in started:
        process.stop()
