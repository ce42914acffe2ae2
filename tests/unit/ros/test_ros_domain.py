"""The ROS domain a graph run holds (dva_ros_common.ros_domain): an error of the run reaches
the caller as itself and the domain is released; the graphs stay on this host unless asked."""
from __future__ import annotations

import errno
import os
import socket

import pytest

pytest.importorskip("domain_coordinator", reason="needs the ROS 2 environment")

from domain_coordinator.impl import PORT_BASE  # noqa: E402

from dva_ros_common import ros_domain  # noqa: E402
from dva_ros_common.ros_domain import ENV_RANGE, discovery_range, reserved_domain  # noqa: E402


def _free(domain: int) -> bool:
    """Nobody holds ``domain`` (domain_coordinator's scheme: a bound port per domain)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind(("", PORT_BASE + domain))
        except OSError:
            return False
    return True


@pytest.mark.parametrize("error", [OSError(errno.ENOSPC, "No space left on device"),
                                   FileExistsError("runs/x_logs exists"), RuntimeError("x")])
def test_an_error_of_the_run_is_raised_as_itself_and_the_domain_released(error):
    # domain_coordinator's own context manager caught an OSError at its yield, tried the next
    # domain and ended in "generator didn't stop after throw()", the cause lost
    with pytest.raises(type(error)) as raised:
        with reserved_domain() as domain:
            assert 1 <= domain <= 100 and not _free(domain)  # held while the run runs
            raise error
    assert raised.value is error
    assert _free(domain)


def test_the_domain_is_released_after_a_run_that_ends_well():
    with reserved_domain() as domain:
        assert not _free(domain)
    assert _free(domain)


def test_discovery_stays_on_the_host_unless_asked(monkeypatch):
    monkeypatch.delenv(ENV_RANGE, raising=False)
    assert discovery_range() == "LOCALHOST"
    assert discovery_range("subnet") == "SUBNET"
    monkeypatch.setenv(ENV_RANGE, "SUBNET")  # a user's environment is kept ...
    assert discovery_range() == "SUBNET"
    assert discovery_range("localhost") == "LOCALHOST"  # ... unless the option says otherwise
    monkeypatch.delenv(ENV_RANGE)
    assert ros_domain.use_discovery() == "LOCALHOST"
    assert os.environ[ENV_RANGE] == "LOCALHOST"  # what the nodes a run starts inherit
