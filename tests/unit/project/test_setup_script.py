"""The setup script fails early, clearly and without a traceback on broken inputs."""
from __future__ import annotations

import os
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
    assert result.returncode == 1
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
    assert result.returncode == 1
    assert "is Python 3.12" in result.stderr and "need CPython 3.11" in result.stderr
    assert not (tmp_path / "venv").exists()


def test_other_ros_distro_is_refused(tmp_path):
    result = _setup(tmp_path, ROS_DISTRO="humble")
    assert result.returncode == 1
    assert "'humble'" in result.stderr and "Jazzy" in result.stderr
    assert not (tmp_path / "venv").exists()
