"""Independent jobs of a campaign (flights, for example), one at a time, on several local
workers, or on a Ray cluster; results are handed back as each job finishes.

A job is ``work(item)`` for one item; jobs must not depend on each other or on the order they
run in, so every route gives the same results. Local workers are threads where a job's work
happens in processes it starts (``run_flight`` and its nodes: the thread only waits for them),
or forked processes where the job computes in Python itself (``processes=True``: in-process
flights, which threads would serialise on the interpreter lock). On Ray each job is a task
(one CPU each); Ray's workers must see the same installation of the project at the same paths
(true for a local Ray started here; on a cluster, install the project alike on every machine).
"""
from __future__ import annotations

import concurrent.futures as cf
from collections.abc import Callable, Iterator, Sequence
from typing import TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")


class CampaignError(ValueError):
    """Bad campaign settings (worker count, Ray address) or Ray unavailable."""


def check_workers(workers: int) -> int:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise CampaignError(f"workers must be an integer >= 1, got {workers!r}")
    return workers


def run_jobs(items: Sequence[Item], work: Callable[[Item], Result], *, workers: int = 1,
             ray_address: str | None = None, processes: bool = False
             ) -> Iterator[tuple[Item, Result]]:
    """``(item, work(item))`` for every item, as the jobs finish.

    Parameters
    ----------
    items : sequence
        The jobs' inputs.
    work : callable
        ``work(item) -> result``; on Ray it must be picklable (a module-level function or a
        ``functools.partial`` of one).
    workers : int
        Local jobs at a time; 1 runs them in order in this thread.
    processes : bool
        Local workers are forked processes, not threads: they inherit ``work`` (it need not
        be picklable; the items and results must be).
    ray_address : str, optional
        A Ray cluster's address, ``"auto"`` for the cluster this machine is part of, or
        ``"local"`` to start a local Ray with ``workers`` CPUs. Overrides local workers.

    An exception in one job propagates when its result is collected; jobs already submitted
    are cancelled where possible (local) or left to Ray.
    """
    check_workers(workers)
    items = list(items)
    if ray_address is not None:
        yield from _run_on_ray(items, work, ray_address, workers)
    elif workers == 1 or len(items) <= 1:
        for item in items:
            yield item, work(item)
    else:
        if processes:
            yield from _run_forked(items, work, workers)
            return
        with cf.ThreadPoolExecutor(max_workers=workers) as pool:
            yield from _collect(pool, {pool.submit(work, item): item for item in items})


_INHERITED: Callable | None = None  # the forked workers' ``work``


def _run_forked(items, work, workers: int):
    # The workers are forked after ``work`` is stored here, so they inherit it (a shared
    # evaluation setup, say) instead of receiving a pickled copy with every job; only the
    # items and the results cross the pipes.
    import multiprocessing

    global _INHERITED
    if _INHERITED is not None:
        raise CampaignError("forked campaigns cannot be nested or run concurrently")
    _INHERITED = work
    try:
        with cf.ProcessPoolExecutor(max_workers=workers,
                                    mp_context=multiprocessing.get_context("fork")) as pool:
            yield from _collect(pool, {pool.submit(_call_inherited, item): item
                                       for item in items})
    finally:
        _INHERITED = None


def _call_inherited(item):
    return _INHERITED(item)


def _collect(pool, futures):
    try:
        for future in cf.as_completed(futures):
            yield futures[future], future.result()
    finally:
        for future in futures:
            future.cancel()


def _run_on_ray(items, work, address: str, workers: int):
    try:
        import ray
    except ImportError:
        raise CampaignError("--ray needs Ray: pip install 'ray[default]' (or the project's "
                            "'ray' extra: pip install -e 'offline[ray]')") from None
    if not address:
        raise CampaignError("the Ray address is empty (use an address, 'auto' or 'local')")
    started_here = not ray.is_initialized()
    if started_here:
        try:
            if address == "local":
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=address, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise CampaignError(f"cannot reach the Ray cluster at {address!r}: {exc}") from None
    try:
        task = ray.remote(num_cpus=1)(_call)
        shared = ray.put(work)  # stored once in the cluster, not once per job
        pending = {task.remote(shared, item): item for item in items}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                yield pending.pop(ref), ray.get(ref)
    finally:
        if started_here:
            ray.shutdown()


def _call(work, item):
    return work(item)
