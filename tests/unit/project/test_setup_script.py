"""The setup script fails early, clearly and without a traceback on broken inputs (exit 2),
and a second setup of one checkout waits for the first under a lock."""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]


def _setup(tmp_path: Path, **env_overrides: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ROS_", "AMENT_"))}
    env.update(DVA_VENV=str(tmp_path / "venv"), **env_overrides)
    return subprocess.run(["bash", str(REPO / "scripts/setup.sh")], env=env,
                          capture_output=True, text=True, timeout=300)


def test_missing_python_311_names_the_fix(tmp_path):
    result = _setup(tmp_path, DVA_PYTHON=str(tmp_path / "no-such-python3.11"))
    assert result.returncode == 2
    assert "Python 3.11 was not found" in result.stderr
    assert "apt-get install python3.11" in result.stderr
    assert "DVA_PYTHON=" in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "venv").exists()  # nothing half-made


def test_wrong_python_version_is_refused(tmp_path):
    fake = tmp_path / "python3.11"
    fake.write_text("#!/bin/sh\necho 3.12\n")
    fake.chmod(0o755)
    result = _setup(tmp_path, DVA_PYTHON=str(fake))
    assert result.returncode == 2
    assert "is Python 3.12" in result.stderr and "need CPython 3.11" in result.stderr
    assert not (tmp_path / "venv").exists()


def test_other_ros_distro_is_refused(tmp_path):
    result = _setup(tmp_path, ROS_DISTRO="humble")
    assert result.returncode == 2
    assert "'humble'" in result.stderr and "Jazzy" in result.stderr
    assert not (tmp_path / "venv").exists()


def test_a_second_setup_waits_for_the_first_under_a_lock(tmp_path):
    """The lock of a checkout (a copy of the script: its checkout is tmp_path) is held here, as
    a first setup would hold it; the second says it waits, and goes on only once it is free."""
    (tmp_path / "scripts").mkdir()
    shutil.copy(REPO / "scripts/setup.sh", tmp_path / "scripts/setup.sh")
    fake = tmp_path / "python3.11"  # passes the checks of the interpreter
    fake.write_text("#!/bin/sh\necho 3.11\n")
    fake.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ROS_", "AMENT_"))}
    env.update(DVA_VENV=str(tmp_path / "venv"), DVA_PYTHON=str(fake))
    with open(tmp_path / ".dva-setup.lock", "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        second = subprocess.Popen(["bash", str(tmp_path / "scripts/setup.sh")], env=env,
                                  stderr=subprocess.PIPE, text=True)
        said = second.stderr.readline()
        assert "another setup of this checkout is running" in said, said
        assert "waiting for it to finish" in said
        assert second.poll() is None  # it cannot pass the lock while it is held
    rest = second.stderr.read()  # the lock is free: it goes on (and stops at the missing
    assert second.wait(timeout=60) == 3, rest  # requirements files of this bare copy: 3)
    assert "the other setup finished" in rest and "Traceback" not in rest
