"""Record a training plan's dwells into a rosbag2 MCAP bag, as the simulator node publishes.

The dwells of :func:`dva_offline.training.recording.simulate_dwells` follow one another on
one sim-time line (dwell ``k`` holds samples ``k N .. (k + 1) N - 1``) and are written through
:class:`aero_dva.bag.batch_recorder.BatchRecorder`: the node's topics, blocks of
``block_size`` samples, ``flight/condition`` with each dwell's airspeed and density,
``dva/damper_state`` with its c2 (source "sweep", as the simulator reports a sweep's c2), and
the final "simulator: flight" status with the bare wing's critical airspeed and the wing file.
The plan itself is kept in the bag directory (``training_plan.json``), so the bag alone says
what was flown. The state jumps at every dwell boundary (each dwell starts from its own
stationary state): windows must not straddle dwells, which ``dva train rbf`` cuts by the
recorded airspeed, density and c2.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.bag.batch_recorder import BatchRecorder
from aero_dva.flight.damper import DamperStatus
from dva_offline.training.plan_io import PLAN_FILE, plan_damping_problem, save_plan
from dva_offline.training.recording import BATCH, simulate_dwells

__all__ = ["RecordedPlan", "SWEEP_SOURCE", "record_plan"]

SWEEP_SOURCE = "sweep"  # dva_msgs/DamperCommand.SOURCE_SWEEP: the simulator sets c2 itself


@dataclass(frozen=True)
class RecordedPlan:
    """What :func:`record_plan` wrote."""

    bag: Path
    dwells: int
    samples: int
    sim_time: float
    wall_time: float
    bag_bytes: int
    topics: tuple[str, ...]


def record_plan(bag_dir, model, plan, *, wing: str = "", wing_fingerprint: str = "",
                displacement: bool = True,
                block_size: int = 50, batch: int = BATCH,
                progress: Callable[[int, int], None] | None = None) -> RecordedPlan:
    """Fly the plan's dwells and record them (see the module docstring).

    Parameters
    ----------
    bag_dir : path-like
        Bag directory to create (must not exist or be empty).
    model : AeroelasticModel
        The wing with its tunable Maxwell DVA, the plan's.
    plan : TrainingPlan
    wing, wing_fingerprint : str
        The wing file's name (written to the final status and the plan file) and its
        :func:`~aero_dva.wing.wing_io.wing_fingerprint` (to the final status).
    displacement : bool
        Record ``wing/displacement`` (needed by ``--labels measured-argmin`` and reports).
    block_size : int
        Samples per message block; must divide the window.
    progress : callable, optional
        ``progress(samples_done, samples_total)``.
    """
    problem = plan_damping_problem(plan)
    if problem is not None:  # the damper applies nothing outside its range
        raise ValueError(problem)
    s = plan.settings
    n = s.window_samples
    if isinstance(block_size, bool) or not isinstance(block_size, int) or block_size < 1 \
            or n % block_size:
        raise ValueError(f"block_size must be a positive integer dividing the window "
                         f"({n} samples), got {block_size!r}")
    started = time.monotonic()
    total = plan.n_dwells * n
    per_dwell = n // block_size
    with BatchRecorder(bag_dir, s.sample_rate, displacement=displacement) as recorder:
        # the plan first: a recording cut short still says what it was to hold
        save_plan(plan, Path(bag_dir) / PLAN_FILE, wing)
        done = 0
        for chunk in simulate_dwells(model, plan, batch=batch):
            k = np.arange(chunk.first_dwell, chunk.first_dwell + chunk.n_dwells)
            first = int(k[0]) * n
            blocks = np.repeat(k, per_dwell)
            t0 = (first + block_size * np.arange(blocks.size)) / s.sample_rate
            c2 = plan.damping[blocks]
            damper = {"time": t0, "commanded_damping": c2, "applied_damping": c2,
                      "min_damping": np.full(blocks.size, s.damping_range[0]),
                      "max_damping": np.full(blocks.size, s.damping_range[1]),
                      "command_age": np.zeros(blocks.size),
                      "status": np.full(blocks.size, float(DamperStatus.OK))}
            # (k, c, N) -> (c, k N): the dwells one after the other in time
            acc = chunk.accelerations.transpose(1, 0, 2).reshape(3, -1)
            disp = chunk.displacements.transpose(1, 0, 2).reshape(4, -1) if displacement \
                else None
            recorder.write_samples(first, acc, disp, chunk.force.reshape(-1),
                                   block_size=block_size, airspeed=plan.airspeed[blocks],
                                   density=plan.density[blocks], damper=damper,
                                   source=SWEEP_SOURCE)
            done = first + chunk.n_dwells * n
            if progress is not None:
                progress(done, total)
        wall = time.monotonic() - started
        values = {"sim_time_s": done / s.sample_rate, "wall_time_s": wall,
                  "real_time_factor": done / s.sample_rate / wall if wall > 0 else 0.0,
                  "critical_airspeed_no_dva": plan.critical_airspeed,
                  "wing": wing, "wing_fingerprint": wing_fingerprint,
                  "training_plan": PLAN_FILE, "dwells": plan.n_dwells,
                  "initial_state": "stationary (each dwell)"}
        recorder.write_diagnostics(done / s.sample_rate, [("ok", "flight completed", values)])
        topics = tuple(recorder.topics.values())
        summary = recorder.close()
    directory = Path(getattr(summary, "directory", bag_dir))
    size = sum(f.stat().st_size for f in Path(bag_dir).iterdir() if f.is_file())
    return RecordedPlan(bag=directory, dwells=plan.n_dwells, samples=done,
                        sim_time=done / s.sample_rate, wall_time=time.monotonic() - started,
                        bag_bytes=size, topics=topics)
