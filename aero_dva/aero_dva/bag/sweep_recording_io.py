"""Record a stepped sweep through the batch path, simulated parallel in time.

:func:`record_sweep` writes the bag :func:`~aero_dva.bag.runtime_recording.record_runtime`
writes for the same flight (same topics, schemas, messages and diagnostics; the samples equal
to round-off), from whole arrays computed by :mod:`aero_dva.flight.sweep_simulator` instead of
50-sample steps. Per process, the main thread simulates chunk after chunk while a second
thread encodes, hashes and writes them.

With ``jobs > 1`` the flight is cut into consecutive spans
(:func:`~aero_dva.flight.sweep_simulator.split_sweep`) and each span is simulated and written
by its own process into its own file of a split bag, as rosbag2 splits bags (``<name>_0.mcap``,
``<name>_1.mcap``, ...; every file a complete MCAP file, the messages in time order across
them, ``metadata.yaml`` listing them). The messages are the same bits as with one process. The
last span is flown by the calling process, which writes the final status and ``metadata.yaml``
once every file is closed.
"""
from __future__ import annotations

import math
import multiprocessing
import os
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.bag.batch_recorder import DAMPER_COLUMNS, BatchRecorder, load_definitions
from aero_dva.bag.chunk_framing import close_split_bag
from aero_dva.bag.runtime_recording import (
    RecordedFlight,
    flight_status_values,
    published_topics,
    record_runtime,
)
from aero_dva.bag.writer import BagSummary, create_bag_directory
from aero_dva.flight import sweep_simulator
from aero_dva.flight.damper import DamperModel, DamperStatus
from aero_dva.flight.discrete_model import ACCELERATION_OUTPUTS, OUTPUT_NAMES
from aero_dva.flight.divergence import stop_message
from aero_dva.flight.flight_runtime import SWEEP_SOURCE
from aero_dva.flight.scenario import airspeed_at, density_at, sample_times, sweep_damping_at

__all__ = ["PREFIX_COST", "default_jobs", "record_sweep"]

_QUEUE = 2  # chunks queued for a writer thread
#: Cost of carrying the state over a sample before a process's span (force and segment end
#: states, no outputs) relative to simulating and writing it: 0.19 s against 1.3 s of CPU for
#: the default training sweep. Spans are sized so that every process has the same work.
PREFIX_COST = 0.15
_MIN_SPAN = 4 * sweep_simulator.CHUNK_SAMPLES  # shorter flights are not worth a process


def default_jobs(n_samples: int) -> int:
    """Processes for a sweep of ``n_samples``: the usable cores (at most 4), one span of at
    least about a million samples each; 1 where processes cannot be forked."""
    if "fork" not in multiprocessing.get_all_start_methods():
        return 1
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, 4, int(n_samples) // _MIN_SPAN))


@dataclass(frozen=True)
class _Sweep:
    """What every process of a recording needs (inherited by forked processes)."""

    runtime: object  # FlightRuntime, only read
    plan: sweep_simulator.SweepPlan
    maps: sweep_simulator.SweepMaps  # built once, before any fork
    block: int  # samples per message block
    outputs: tuple[str, ...]
    displacement: bool
    chunk_samples: int
    overlap: bool
    started: float  # time.monotonic() when the recording started (system-wide clock)

    @property
    def rate(self) -> float:
        return self.runtime.sample_rate


def record_sweep(bag_dir, runtime, progress: Callable[[int, int], None] | None = None, *,
                 block_size: int | None = None, chunk_samples: int | None = None,
                 displacement: bool = True, overlap: bool | None = None, jobs: int = 1,
                 **options) -> RecordedFlight:
    """Record a stepped sweep simulated parallel in time (:mod:`aero_dva.flight.sweep_simulator`).

    A flight the parallel path does not model
    (:func:`~aero_dva.flight.sweep_simulator.unsupported_reason`: not a sweep, varying density, a
    hidden plant, ...) is flown by :func:`~aero_dva.bag.runtime_recording.record_runtime`
    instead (one process), so this is always safe to call. ``runtime`` is only read (its
    config, scenario and critical airspeed), not stepped.

    An error on any thread or process stops the recording and is raised here. The bag then
    holds what was written before the failure, a prefix of the flight without holes, and no
    final "flight completed" status, which is written only after every chunk of every file
    is in the bag.

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create.
    runtime : FlightRuntime
        A fresh runtime.
    progress : callable, optional
        ``progress(samples_done, samples_total)`` as chunks are simulated (their writing may
        still be under way).
    block_size : int, optional
        Samples per message block (default the scenario's, as the simulator node publishes);
        another value must divide every dwell, so that each block has one (U, c2).
    chunk_samples : int, optional
        Samples simulated and encoded together (default
        :data:`~aero_dva.flight.sweep_simulator.CHUNK_SAMPLES`; bounds the memory used).
    displacement : bool
        Record ``wing/displacement`` (True, as the graph records every topic). False records
        only what a wing test measures (accelerations, force, flight condition, damper
        state), as the graph's recorder does with ``exclude``, and skips computing the
        displacements (except the leading edge, for the divergence test); the messages of
        the other topics are the same bytes either way.
    overlap : bool, optional
        Write on a second thread (True) or in turn with the simulation (False; the same
        bytes). Default: a writer thread with one process; none with several, which keep
        the cores busy by themselves (measured 11 800 x against 11 100 x real time with the
        threads, two processes on two cores).
    jobs : int
        Processes (see the module docstring; :func:`default_jobs` picks one per core). 1
        writes a one-file bag; more write a split bag of up to ``jobs`` files (fewer when
        the flight has fewer dwells), with the same messages. Needs the "fork" start method
        (Linux; elsewhere 1 is used), and forks the calling process: call it where no other
        thread holds a lock the processes need (the CLI runs no other thread).
    **options
        ``namespace``, ``compression``, ``chunk_size``, ``ros_distro``, ``chunk_crc`` of
        :class:`~aero_dva.bag.batch_recorder.BatchRecorder`.

    Returns
    -------
    RecordedFlight
        ``method`` is "parallel" or "stepped" (the fallback).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, (int, np.integer)) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    reason = sweep_simulator.unsupported_reason(runtime.config, runtime.scenario)
    if reason is None and max(runtime.scenario.sweep_damping) > \
            runtime.config.damper.absurd_limit:
        reason = "the damper rejects some sweep c2"  # recorded as the node would, stepped
    if reason is not None:
        if block_size not in (None, runtime.block_size):
            raise ValueError(f"block_size {block_size} needs the parallel sweep path; this "
                             "flight is stepped with the scenario's block size")
        return record_runtime(bag_dir, runtime, progress, displacement=displacement,
                              **options)
    started = time.monotonic()
    scenario, config = runtime.scenario, runtime.config
    plan = sweep_simulator.plan_sweep(config, scenario)
    n = runtime.block_size if block_size is None else block_size
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"block_size must be a positive integer, got {block_size!r}")
    n = int(n)
    dwell = int(round(scenario.dwell * scenario.sample_rate))
    if block_size is not None and (dwell % n or np.any(plan.lengths % n)):
        raise ValueError(f"block_size {n} must divide the dwell ({dwell} samples) so that "
                         "each block has one (U, c2)")
    outputs = OUTPUT_NAMES if displacement else ("leading_edge",) + ACCELERATION_OUTPUTS
    if "fork" not in multiprocessing.get_all_start_methods():
        jobs = 1
    spans = sweep_simulator.split_sweep(plan, int(jobs), align=n,
                                    weights=_balanced_weights(int(jobs)))
    sweep = _Sweep(runtime=runtime, plan=plan, maps=sweep_simulator.sweep_maps(config, plan),
                   block=n, outputs=outputs, displacement=bool(displacement),
                   chunk_samples=chunk_samples or sweep_simulator.CHUNK_SAMPLES,
                   overlap=len(spans) == 1 if overlap is None else bool(overlap),
                   started=started)
    total = plan.n_samples

    def report(done: int) -> None:
        if progress is not None:
            progress(done, total)

    if len(spans) == 1:
        with BatchRecorder(bag_dir, sweep.rate, displacement=displacement,
                           **options) as recorder:
            done, diverged_at = _fly_span(sweep, recorder, spans[0], report)
            _write_status(sweep, recorder, done, diverged_at)
            bag = recorder.close()
    else:
        bag, done, diverged_at = _record_split(bag_dir, sweep, spans, report, options)
    return RecordedFlight(summary=bag,
                          outcome="completed" if diverged_at is None else "diverged",
                          sim_time=done / sweep.rate, wall_time=time.monotonic() - started,
                          samples=done, blocks=-(-done // n), method="parallel")


def _balanced_weights(parts: int) -> np.ndarray:
    """Span sizes giving every process the same work: span j also carries the state over
    the b_j samples before it, at :data:`PREFIX_COST` each, so b_(j+1) = (1 - r) b_j + C."""
    bounds = [0.0]
    for _ in range(parts):
        bounds.append((1.0 - PREFIX_COST) * bounds[-1] + 1.0)
    return np.diff(bounds)


def _fly_span(sweep: _Sweep, recorder: BatchRecorder, span: tuple[int, int],
              report: Callable[[int], None]) -> tuple[int, int | None]:
    """Simulate samples ``span[0] ..`` and write them as the node publishes them.

    Returns (samples flown to, first sample of the block that diverged or None); the flight
    stops after the diverging block, as the node's does.
    """
    runtime, n = sweep.runtime, sweep.block
    first, end = span
    limit = 0.5 * runtime.config.wing.chord  # StreamingSimulator's default divergence limit
    edge = sweep.outputs.index("leading_edge")
    done, diverged_at = first, None
    writer = _Pipeline(lambda item: _write_sweep_blocks(recorder, runtime, n, *item),
                       threaded=sweep.overlap)
    try:
        pending = None  # samples of a block cut by a chunk boundary
        chunks = sweep_simulator.simulate_sweep(runtime.config, sweep.plan,
                                            chunk_samples=sweep.chunk_samples,
                                            outputs=sweep.outputs, span=span,
                                            maps=sweep.maps)
        for chunk in chunks:
            data = (chunk.force, chunk.outputs)
            if pending is not None:
                data = tuple(np.concatenate([a, b], axis=-1) for a, b in zip(pending, data))
            length = data[0].size
            keep = length if done + length == end else length - (length % n)
            pending = tuple(a[..., keep:] for a in data) if keep < length else None
            force, out = (a[..., :keep] for a in data)
            if keep == 0:
                continue
            diverged = _first_diverged_block(out[edge], out, n, limit)
            if diverged is not None:  # the node publishes the diverging block, then stops
                keep = min(keep, (diverged + 1) * n)
                force, out = force[:keep], out[:, :keep]
                diverged_at = done + diverged * n
            writer.put((done, force, out[:4] if sweep.displacement else None, out[-3:]))
            done += keep
            report(done)
            if diverged_at is not None:
                break
        writer.finish()  # every chunk is in the file (or the writer's error is raised)
    except BaseException:
        writer.abandon()
        raise
    return done, diverged_at


def _write_status(sweep: _Sweep, recorder: BatchRecorder, done: int,
                  diverged_at: int | None) -> None:
    """The node's final "simulator: flight" status: completed, or where it stopped the flight."""
    runtime, rate = sweep.runtime, sweep.rate
    blocks = -(-done // sweep.block)
    published = dict.fromkeys(published_topics(), blocks)
    values = flight_status_values(done / rate, sweep.started, runtime, published)
    if diverged_at is None:
        recorder.write_diagnostics(done / rate, [("ok", "flight completed", values)])
        return
    t = sample_times(runtime.scenario, diverged_at, done - diverged_at)
    u = float(airspeed_at(runtime.scenario, t)[-1])
    recorder.write_diagnostics(done / rate, [(
        "error", stop_message(u, runtime.critical_airspeed, float(t[0])), values)])


# --------------------------------------------------------------------------------------------
# Several processes, one file each
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Part:
    """What a process reports of its span."""

    summary: BagSummary
    done: int
    diverged_at: int | None


def _record_split(bag_dir, sweep: _Sweep, spans: list[tuple[int, int]],
                  report: Callable[[int], None], options: dict
                  ) -> tuple[BagSummary, int, int | None]:
    """Fly ``spans[:-1]`` in forked processes and the last span here; returns (bag summary,
    samples flown to, first sample of the diverging block or None)."""
    context = multiprocessing.get_context("fork")
    load_definitions()  # once, inherited by the forked processes
    directory, _ = create_bag_directory(bag_dir)
    names = [f"{directory.name}_{j}.mcap" for j in range(len(spans))]
    counters = [context.Value("q", 0, lock=False) for _ in spans]
    children: list[tuple[multiprocessing.Process, object]] = []
    parts: list[_Part] = []
    recorder: BatchRecorder | None = None
    own: BagSummary | None = None

    def advance() -> None:
        report(sum(c.value for c in counters))

    try:
        # Fork before this process starts its writer threads.
        for j, span in enumerate(spans[:-1]):
            receive, send = context.Pipe(duplex=False)
            process = context.Process(
                target=_fly_part, name=f"sweep-span-{j}", daemon=True,
                args=(send, sweep, span, directory, names[j], counters[j], options))
            process.start()
            send.close()
            children.append((process, receive))
        first = spans[-1][0]
        recorder = BatchRecorder(directory, sweep.rate, displacement=sweep.displacement,
                                 file_name=names[-1], first_block=first // sweep.block,
                                 **options)

        def mine(done: int) -> None:
            counters[-1].value = done - first
            advance()

        done, diverged_at = _fly_span(sweep, recorder, spans[-1], mine)
        for j, (process, receive) in enumerate(children):
            parts.append(_wait(j, process, receive, advance))
        if all(p.diverged_at is None for p in parts):  # the flight's status goes last
            _write_status(sweep, recorder, done, diverged_at)
        own = recorder.close()
    except BaseException as exc:
        if isinstance(exc, Exception):  # the earlier spans still make a bag: let them finish
            for j in range(len(parts), len(children)):
                try:
                    parts.append(_wait(j, *children[j], advance))
                except RuntimeError:
                    break
        for process, _ in children:  # interrupted, or after a failed span: stop the rest
            if process.is_alive():
                process.terminate()
        for process, _ in children:
            process.join()
        if recorder is not None:
            own = recorder.close()  # idempotent; without the final status
        kept, _ = _prefix(parts, own if len(parts) == len(children) else None)
        _drop(directory, names[len(kept):])
        if kept:
            close_split_bag(directory, kept, options.get("ros_distro"))
        raise
    kept, diverged = _prefix(parts, own)
    _drop(directory, names[len(kept):])
    bag = close_split_bag(directory, kept, options.get("ros_distro"))
    if diverged is not None:  # the wing diverged in an earlier span: the flight stopped there
        return bag, diverged.done, diverged.diverged_at
    return bag, done, diverged_at


def _prefix(parts: list[_Part], own: BagSummary | None
            ) -> tuple[list[BagSummary], _Part | None]:
    """The files that make the bag, in order from the first, and the span where the wing
    diverged (None: none did). The bag is a prefix of the flight: it ends at a missing file
    (``own`` None) or after the span that diverged."""
    for j, part in enumerate(parts):
        if part.diverged_at is not None:
            return [p.summary for p in parts[:j + 1]], part
    return [p.summary for p in parts] + ([own] if own is not None else []), None


def _fly_part(send, sweep: _Sweep, span, directory: Path, name: str, counter,
              options: dict) -> None:
    """A forked process: fly one span into one file and send back a :class:`_Part`."""
    try:
        with BatchRecorder(directory, sweep.rate, displacement=sweep.displacement,
                           file_name=name, first_block=span[0] // sweep.block,
                           **options) as recorder:
            def mine(done: int) -> None:
                counter.value = done - span[0]

            done, diverged_at = _fly_span(sweep, recorder, span, mine)
            if diverged_at is not None:  # the flight ends in this file
                _write_status(sweep, recorder, done, diverged_at)
            summary = recorder.close()
        send.send(("ok", _Part(summary, done, diverged_at)))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises
        send.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        send.close()


def _wait(j: int, process, receive, advance: Callable[[], None]) -> _Part:
    """The result of span ``j``'s process (reporting progress while it runs)."""
    while not receive.poll(0.1):
        advance()
        if not process.is_alive() and not receive.poll(0):
            break
    try:
        kind, value = receive.recv()
    except EOFError:
        process.join()
        raise RuntimeError(f"the process recording span {j} of the sweep ended without a "
                           f"result (exit code {process.exitcode})") from None
    process.join()
    advance()
    if kind == "error":
        raise RuntimeError(f"recording span {j} of the sweep failed: {value}")
    return value


def _drop(directory: Path, names: list[str]) -> None:
    for name in names:
        (directory / name).unlink(missing_ok=True)


# --------------------------------------------------------------------------------------------
# Writing on a second thread
# --------------------------------------------------------------------------------------------


class _Pipeline:
    """Run ``write(item)`` for every item :meth:`put`, in order, on a second thread.

    The queue holds at most ``depth`` items, so a writer slower than its producer bounds the
    memory in flight. The writer's first error stops the writing (later items are dropped)
    and is raised by the next :meth:`put` or by :meth:`finish`. ``threaded=False`` writes
    in :meth:`put` itself (the reference). (Encoding on the main thread instead measured
    slower, 1.9 s against 1.25 s for the full sweep, probably because its many short
    GIL-free copies then wait for the GIL.)
    """

    _END = object()

    def __init__(self, write: Callable, *, threaded: bool = True, depth: int = _QUEUE):
        self._write = write
        self._error: BaseException | None = None
        self._cancelled = False
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue: queue.Queue = queue.Queue(maxsize=depth)
            self._thread = threading.Thread(target=self._run, name="bag-writer", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is self._END:
                return
            if self._error is None and not self._cancelled:  # else drain: put never blocks
                try:
                    self._write(item)
                except BaseException as exc:  # raised in the caller's thread
                    self._error = exc

    def put(self, item) -> None:
        if self._thread is None:
            self._write(item)
            return
        self._raise()
        self._queue.put(item)

    def finish(self) -> None:
        """Wait until every item is written; raise the writer's error, if any."""
        self._join()
        self._raise()

    def abandon(self) -> None:
        """Drop the items not yet written and stop the thread (after the caller failed)."""
        self._cancelled = True
        self._join()

    def _join(self) -> None:
        if self._thread is not None:
            self._queue.put(self._END)
            self._thread.join()
            self._thread = None

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error


# --------------------------------------------------------------------------------------------
# Sweep blocks
# --------------------------------------------------------------------------------------------


def _first_diverged_block(leading_edge: np.ndarray, outputs: np.ndarray, n: int,
                          limit: float) -> int | None:
    """Index of the first block of ``n`` samples that StreamingSimulator would call diverged.

    Its test: |leading edge| > ``limit``, or an output not finite (``outputs`` (m, T): the
    channels computed; a state that overflows makes every output it feeds non-finite).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        # Fast path, one pass per row: a row's sum is finite exactly when its values are
        # (short of an overflow of the sum itself, ~1e308, long after the limit).
        if np.max(np.abs(leading_edge)) <= limit and all(
                math.isfinite(float(np.sum(row))) for row in outputs):
            return None
        bad = ~(np.abs(leading_edge) <= limit)
        for row in outputs:
            bad |= ~np.isfinite(row)
    return int(np.argmax(bad)) // n


def _write_sweep_blocks(recorder: BatchRecorder, runtime, n: int, first: int, force, disp,
                        acc) -> int:
    """Write samples ``first ..`` of a sweep as the node publishes them; returns the blocks.

    ``disp`` may be None when the recorder records no displacement.
    """
    scenario = runtime.scenario
    count = -(-force.size // n)
    index = first + n * np.arange(count, dtype=np.int64)
    t0 = index / runtime.sample_rate  # == FlightSamples.t0, bit for bit
    c2 = sweep_damping_at(scenario, t0)
    damper = _sweep_damper_states(runtime.config.damper, t0, c2) if recorder.damper_state \
        else None
    return recorder.write_samples(first, acc, disp, force, block_size=n,
                                  airspeed=airspeed_at(scenario, t0),
                                  density=density_at(scenario, t0), damper=damper,
                                  source=SWEEP_SOURCE if damper is not None else None)


def _sweep_damper_states(config, t0: np.ndarray, c2: np.ndarray) -> dict[str, np.ndarray]:
    """The damper snapshot after each sweep block, as FlightRuntime leaves it.

    Per block the runtime commands the block's c2 at t0 and updates the damper to t0. An
    ideal damper (no lag) with c2 inside its range then reports c2 applied, age 0, status OK
    at t0: computed here for all blocks at once. Otherwise the damper model is stepped block by
    block, exactly as the runtime does.
    """
    k = len(t0)
    if config.time_constant == 0.0 and np.all((c2 >= config.min_damping)
                                              & (c2 <= config.max_damping)):
        return {"time": t0, "commanded_damping": c2, "applied_damping": c2,
                "min_damping": np.full(k, config.min_damping),
                "max_damping": np.full(k, config.max_damping),
                "command_age": np.zeros(k), "status": np.full(k, float(DamperStatus.OK))}
    model = DamperModel(config, start_time=0.0)
    rows = []
    for t, c in zip(t0.tolist(), c2.tolist()):
        model.command(c, t, SWEEP_SOURCE)
        model.update(t)
        snap = model.snapshot()
        if snap.source != SWEEP_SOURCE:
            raise ValueError(f"sweep c2 = {c} N s/m at t = {t} s was refused by the damper "
                             f"({snap.status.name}); the stepped path records that")
        rows.append((snap.time, snap.commanded_damping, snap.applied_damping,
                     snap.min_damping, snap.max_damping, snap.command_age, int(snap.status)))
    table = np.array(rows, dtype=np.float64).reshape(-1, len(DAMPER_COLUMNS))
    return dict(zip(DAMPER_COLUMNS, table.T))
