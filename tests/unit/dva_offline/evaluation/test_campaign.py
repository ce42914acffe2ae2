"""Campaign jobs: serial, local workers and a local Ray give the same results."""
from __future__ import annotations

import functools
import sys
import threading

import pytest

from dva_offline.evaluation.campaign import CampaignError, run_jobs


def _square_with_offset(offset: int, item: int) -> dict:
    return {"item": item, "value": item * item + offset}


def _results(**kwargs) -> dict:
    work = functools.partial(_square_with_offset, 3)
    return {item: result for item, result in run_jobs(range(7), work, **kwargs)}


def test_serial_runs_in_order():
    seen = [item for item, _ in run_jobs([3, 1, 2], lambda x: x)]
    assert seen == [3, 1, 2]


def test_local_workers_give_the_serial_results_and_overlap():
    active, most = 0, 0
    lock = threading.Lock()
    both_running = threading.Barrier(2, timeout=120)

    def work(item):
        nonlocal active, most
        with lock:
            active += 1
            most = max(most, active)
        if item < 2:
            both_running.wait()  # the first two jobs can only pass together
        with lock:
            active -= 1
        return item * 2

    results = dict(run_jobs(range(6), work, workers=2))
    assert results == {i: 2 * i for i in range(6)}
    assert most == 2
    assert _results(workers=3) == _results()


def test_forked_workers_inherit_work_that_cannot_be_pickled():
    """The forked workers get ``work`` from the fork, not through a pipe: a closure over a
    lock (unpicklable) runs, in other processes, and gives the serial results."""
    import os

    lock = threading.Lock()

    def work(item):
        with lock:
            return item * 3, os.getpid()

    results = dict(run_jobs(range(8), work, workers=2, processes=True))
    assert {i: v for i, (v, _) in results.items()} == {i: 3 * i for i in range(8)}
    assert os.getpid() not in {pid for _, pid in results.values()}
    assert _results(workers=2, processes=True) == _results()


def test_forked_campaigns_cannot_nest():
    def inner(item):
        return sum(v for _, v in run_jobs(range(3), abs, workers=2, processes=True))

    with pytest.raises(CampaignError, match="nested"):
        list(run_jobs([1, 2], inner, workers=2, processes=True))


def test_a_failing_job_raises_when_collected():
    def work(item):
        if item == 2:
            raise RuntimeError("job 2 failed")
        return item

    with pytest.raises(RuntimeError, match="job 2 failed"):
        list(run_jobs(range(4), work, workers=2))


@pytest.mark.parametrize("workers", [0, -1, 1.5, True])
def test_bad_worker_counts_are_refused(workers):
    with pytest.raises(CampaignError, match="workers"):
        list(run_jobs([1], abs, workers=workers))


def test_missing_ray_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(CampaignError, match="needs Ray"):
        list(run_jobs([1], abs, ray_address="local"))


@pytest.mark.slow
def test_local_ray_gives_the_serial_results():
    pytest.importorskip("ray")
    assert _results(ray_address="local", workers=2) == _results()
