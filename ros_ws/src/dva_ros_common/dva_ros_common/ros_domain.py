"""The ROS domain a run's graph talks on: reserved for that run, and kept on this host.

:func:`reserved_domain` holds a ROS_DOMAIN_ID (1-100) that no other run on the host holds
meanwhile, by domain_coordinator's scheme (a bound TCP port per domain: ``launch_testing`` and
other users of it keep out of ours). Its own context manager catches ``OSError`` around its
``yield``, so an ``OSError`` of the run (an existing folder, a full disk) made it try the next
domain and end in ``RuntimeError: generator didn't stop after throw()`` with the cause lost;
here the run's exceptions never reach it, and the domain is released whatever happens.

:func:`discovery_range`: the graphs the project starts (``run_flight``, replay, ``dva evaluate
--graph``, the tests) discover each other on this host only (Jazzy's
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``), so a flight neither announces itself to the
network nor hears a participant there (docs/reliability.md, the trust boundary). The
environment's ``ROS_AUTOMATIC_DISCOVERY_RANGE``, or ``--discovery subnet``, opens it.
"""
from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

__all__ = ["DISCOVERY_CHOICES", "DISCOVERY_HELP", "ENV_RANGE", "discovery_range",
           "reserved_domain", "use_discovery"]

ENV_RANGE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
#: ``--discovery`` choice -> the variable's value.
DISCOVERY_CHOICES = {"localhost": "LOCALHOST", "subnet": "SUBNET"}
DISCOVERY_HELP = ("where the graph's nodes discover each other: localhost (this host only) or "
                  f"subnet (the local network too); default: ${ENV_RANGE} if set, else "
                  "localhost")


@contextlib.contextmanager
def reserved_domain() -> Iterator[int]:
    """A ROS_DOMAIN_ID held for the block (see the module docstring)."""
    from domain_coordinator import domain_id

    coordinator = domain_id()
    domain = coordinator.__enter__()  # RuntimeError when all 100 are taken
    try:
        yield domain
    finally:
        coordinator.__exit__(None, None, None)  # releases the port; never sees our error


def discovery_range(choice: str | None = None) -> str:
    """The ``ROS_AUTOMATIC_DISCOVERY_RANGE`` a graph runs with: ``choice`` (a key of
    :data:`DISCOVERY_CHOICES`), else the environment's, else ``LOCALHOST``."""
    if choice:
        return DISCOVERY_CHOICES[choice]
    return os.environ.get(ENV_RANGE) or DISCOVERY_CHOICES["localhost"]


def use_discovery(choice: str | None = None) -> str:
    """Set :func:`discovery_range` in this process's environment (the nodes it starts inherit
    it; an rclpy context made after reads it); return it."""
    value = discovery_range(choice)
    os.environ[ENV_RANGE] = value
    return value
