"""Record a flight flown by the ROS-free simulators, as the node graph would record it.

:func:`record_runtime` steps a :class:`~aero_dva.flight.flight_runtime.FlightRuntime` block by
block and writes what the simulator node publishes (the blocks, the stale-damper warning, the
final "simulator: flight" status with the node's key-values) through the
:class:`~aero_dva.bag.batch_recorder.BatchRecorder`; :func:`record_flight_blocks` writes given
blocks. :func:`aero_dva.bag.sweep_recording_io.record_sweep` records a stepped sweep simulated
parallel in time and returns the same :class:`RecordedFlight`.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from aero_dva.bag import channels as ch
from aero_dva.bag.batch_recorder import BatchRecorder
from aero_dva.bag.writer import BagSummary
from aero_dva.flight.damper import DamperStatus
from aero_dva.flight.divergence import stop_message

__all__ = ["RecordedFlight", "flight_status_values", "published_topics", "record_flight_blocks",
           "record_runtime"]


def published_topics() -> list[str]:
    """The simulator's per-block topics under its namespace (the "published:<topic>" keys of
    its final status), in publish order."""
    return [c.name for c in ch.SIMULATOR_BLOCK if not c.name.startswith("/")]


def _check_batch_blocks(batch_blocks) -> None:
    if isinstance(batch_blocks, bool) or not isinstance(batch_blocks, int) or batch_blocks < 1:
        raise ValueError(f"batch_blocks must be a positive integer, got {batch_blocks!r}")


def _samples(runtime) -> int:
    return int(round(runtime.time * runtime.sample_rate))


def record_flight_blocks(bag_dir, blocks: Iterable, damper_states: Iterable | None,
                         sample_rate: float, *, batch_blocks: int = 1000,
                         **options) -> BagSummary:
    """Record blocks (and optional damper snapshots, one per block) into a new bag.

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create.
    blocks : iterable of FlightSamples
        Consumed lazily, ``batch_blocks`` at a time.
    damper_states : iterable of DamperSnapshot or None
        One per block; None records no ``dva/damper_state`` topic.
    sample_rate : float
        [Hz]
    batch_blocks : int
        Blocks encoded together.
    **options
        ``namespace``, ``compression``, ``chunk_size``, ``ros_distro``, ``chunk_crc`` of
        :class:`~aero_dva.bag.batch_recorder.BatchRecorder`.

    Returns
    -------
    BagSummary
    """
    _check_batch_blocks(batch_blocks)
    with BatchRecorder(bag_dir, sample_rate, damper_state=damper_states is not None,
                       **options) as recorder:
        states = iter(damper_states) if damper_states is not None else None
        batch, snaps = [], []
        for i, block in enumerate(blocks):
            batch.append(block)
            if states is not None:
                try:
                    snaps.append(next(states))
                except StopIteration:
                    raise ValueError(f"damper_states ended after {i} snapshots; one per block "
                                     "is needed") from None
            if len(batch) == batch_blocks:
                recorder.write_blocks(batch, snaps if states is not None else None)
                batch, snaps = [], []
        if batch:
            recorder.write_blocks(batch, snaps if states is not None else None)
        if states is not None and next(states, None) is not None:
            raise ValueError("damper_states has more snapshots than there are blocks")
        return recorder.close()


@dataclass(frozen=True)
class RecordedFlight:
    """What :func:`record_runtime` recorded.

    Attributes
    ----------
    summary : BagSummary
    outcome : {"completed", "diverged"}
    sim_time : float
        [s] sim time flown.
    wall_time : float
        [s] wall time of stepping and recording.
    samples, blocks : int
    method : {"stepped", "parallel"}
        FlightRuntime stepped block by block, or the parallel-in-time sweep.
    """

    summary: BagSummary
    outcome: str
    sim_time: float
    wall_time: float
    samples: int
    blocks: int
    method: str = "stepped"


def record_runtime(bag_dir, runtime, progress: Callable[[int, int], None] | None = None, *,
                   batch_blocks: int = 1000, **options) -> RecordedFlight:
    """Fly a :class:`~aero_dva.flight.flight_runtime.FlightRuntime` to its end and record it.

    What the simulator node publishes, in its order: per block ``/clock``, the sample blocks,
    the flight condition and the damper state; a ``/diagnostics`` warning when the damper falls
    back to its stale value; at the end a ``/diagnostics`` status "simulator: flight" ("flight
    completed", level OK, or "flight stopped at U = ...", level ERROR) with
    the node's key-values (sim_time_s, wall_time_s, real_time_factor, critical_airspeed_no_dva,
    published:<topic>). No controller runs: c2 is the sweep's own or the damper's initial one.

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create.
    runtime : FlightRuntime
        A fresh runtime (stepped here to the end).
    progress : callable, optional
        Called as ``progress(samples_done, samples_total)`` after each batch.
    batch_blocks, **options
        As for :func:`record_flight_blocks`.

    Returns
    -------
    RecordedFlight
    """
    _check_batch_blocks(batch_blocks)
    total = int(runtime.scenario.n_samples)
    started = time.monotonic()
    published = dict.fromkeys(published_topics(), 0)
    blocks_done = 0
    with BatchRecorder(bag_dir, runtime.sample_rate, **options) as recorder:
        batch, snaps = [], []

        def flush():
            nonlocal batch, snaps
            if batch:
                recorder.write_blocks(batch, snaps if recorder.damper_state else None)
                for topic in published:
                    published[topic] += len(batch)
                batch, snaps = [], []
                if progress is not None:
                    progress(_samples(runtime), total)

        def summary() -> dict:
            return flight_status_values(runtime.time, started, runtime, published)

        last_status = None
        outcome = "completed"
        while not runtime.done:
            block = runtime.step()
            snapshot = runtime.flown_damper  # stamped at the block's start
            batch.append(block)
            snaps.append(snapshot)
            blocks_done += 1
            status = int(snapshot.status)
            if status != last_status and status == DamperStatus.FALLBACK_STALE:
                flush()
                recorder.write_diagnostics(runtime.time, [(
                    "warn", "no damper command within "
                    f"{runtime.config.damper.stale_timeout:g} s: fallback c2 = "
                    f"{snapshot.applied_damping:g} N s/m applied", {})])
            last_status = status
            if block.diverged:
                flush()
                u = float(block.airspeed[-1])
                recorder.write_diagnostics(runtime.time, [(
                    "error", stop_message(u, runtime.critical_airspeed, block.t0), summary())])
                outcome = "diverged"
                break
            if len(batch) >= batch_blocks:
                flush()
        else:
            flush()
            recorder.write_diagnostics(runtime.time, [("ok", "flight completed", summary())])
        bag = recorder.close()
    return RecordedFlight(summary=bag, outcome=outcome, sim_time=float(runtime.time),
                          wall_time=time.monotonic() - started,
                          samples=_samples(runtime),
                          blocks=blocks_done)


def flight_status_values(sim: float, started: float, runtime, published: dict) -> dict:
    """The key-values of the node's final "simulator: flight" status: ``sim`` [s] flown,
    wall time since ``started`` (``time.monotonic()``), the real-time factor, the runtime's
    critical airspeed and ``published:<topic>`` counts."""
    wall = time.monotonic() - started
    values = {"sim_time_s": sim, "wall_time_s": wall,
              "real_time_factor": sim / wall if wall > 0 else math.inf,
              "critical_airspeed_no_dva": runtime.critical_airspeed}
    values.update({f"published:{t}": n for t, n in published.items()})
    return values
