"""The README's and docs' examples that fly the ROS graph print what the pages say.

The main job (``scripts/main_job.sh``, what ``./run.sh`` runs) is flown once, in a scratch
directory; its bag and schedule stand in for the time-stamped names the pages show. Wall times,
real-time factors and paths are masked (tests/docs_examples.py); every other number must be the
page's.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.docs_examples import REPO, TIMES, Example, differences, find, run, scratch
from tests.docs_registry import EXAMPLES

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: What a run may change in a run_flight summary: wall times, the real-time factor, paths.
SUMMARY_MASKS = (TIMES, r"\d+\.\dx real time", r"(/\S+)?runs/main_\S+")
PAGE_BAG, PAGE_SCHEDULE = "runs/main_20261125T141236Z", "runs/schedule_20261125T141236Z.json"


@pytest.fixture(scope="module")
def main_job(tmp_path_factory):
    """(scratch directory, what the main job printed, its bag, its schedule)."""
    cwd = scratch(tmp_path_factory.mktemp("docs") / "work")
    printed, code = run(f"bash {REPO / 'scripts' / 'main_job.sh'}", cwd)
    assert code == 0, printed
    bag = re.search(r"^bag \(MCAP\)\s+(\S+)$", printed, flags=re.M).group(1)
    schedule = next((cwd / "runs").glob("schedule_*.json"))
    return cwd, printed, str(Path(bag).relative_to(cwd)), str(schedule.relative_to(cwd))


def test_every_ros_example_has_its_test():
    ros = {(e.page, e.anchor) for e in EXAMPLES if e.ros}
    assert ros == {("README.md", "controller           schedule"),
                   ("README.md", "divergence           none within the flight"),
                   ("README.md", "$ dva replay runs/main_"),
                   ("docs/replay.md", "$ dva replay runs/main_")}


def test_the_main_job_prints_the_readmes_summary(main_job):
    _, printed, _, _ = main_job
    documented = find("README.md", "controller           schedule").body
    diff = differences(documented, printed, SUMMARY_MASKS)
    assert diff is None, f"README.md's ./run.sh summary drifted:\n{diff}"


def test_the_switching_flight_prints_the_readmes_lines(tmp_path):
    cwd = scratch(tmp_path / "work")
    printed, code = run("ros2 run aero_dva_sim run_flight --controller switching --damping 624.7 "
                        "--output runs/switching", cwd)
    assert code == 0, printed
    documented = find("README.md", "divergence           none within the flight").body
    diff = differences(documented, printed, SUMMARY_MASKS, subset=True)
    assert diff is None, f"README.md's switching flight drifted:\n{diff}"


@pytest.mark.parametrize("page", ["README.md", "docs/replay.md"])
def test_the_replays_of_the_main_jobs_bag(page, main_job):
    cwd, _, bag, schedule = main_job
    example = Example(page, "$ dva replay runs/main_", masks=(TIMES,), subset=True,
                      replace=((PAGE_BAG, bag), (PAGE_SCHEDULE, schedule)))
    for out in ("runs/replay_schedule", "runs/replay_schedule_offline", "runs/replay_plunge"):
        run(f"rm -rf {out} {out}_logs", cwd)  # both pages replay into the same names
    example.check(cwd)
