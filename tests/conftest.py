"""Shared test configuration: repository paths, and the tests' graphs kept on this host."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# Every DDS participant of the tests (in-process contexts, the nodes they start, run_flight)
# discovers the others on this host only, as the project's runs do (docs/reliability.md); a
# range set in the environment is kept.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


@pytest.fixture(scope="session")
def repo() -> Path:
    """The repository root."""
    return REPO
