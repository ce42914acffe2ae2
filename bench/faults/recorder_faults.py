"""The recorder killed by SIGINT, SIGTERM or SIGKILL at a chosen moment of a flight.

One trial: a probe (in this process), the ``mcap_recorder`` and the ``simulator`` (processes,
as ``ros2 run`` starts them) on a reserved domain. The simulator flies a constant airspeed
below flutter and waits until both the probe and the recorder subscribe to every data topic,
so both hear the flight from its first block. ``kill_after`` seconds of wall time after the
probe received the first acceleration block, the recorder gets the signal. What the probe had
received by then is what was published before the signal; the bag (recovered after SIGKILL)
is compared with it by the blocks' ``first_sample_index``.

With ``stall`` > 0 the recorder is frozen (SIGSTOP) for that long just before the signal and
resumed (SIGCONT) right before it: the signal then meets a recorder that is ``stall`` seconds
behind its publishers, as a busy recorder on a loaded machine can be.
"""
from __future__ import annotations

import re
import signal
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from bench.faults.bag_recovery import complete_chunk_indexes, read_indexes, recover
from bench.faults.ros_processes import ros_session, wait_until, write_scenario

SIGNALS = {"SIGINT": signal.SIGINT, "SIGTERM": signal.SIGTERM, "SIGKILL": signal.SIGKILL}
BLOCK_SAMPLES = 50  # samples per block of the trial scenario
SAMPLE_RATE = 1000.0  # [Hz]


class TrialError(RuntimeError):
    """A trial that could not run (a node did not start); carries the node logs."""


@dataclass(frozen=True)
class RecorderTrial:
    """What one recorder fault did to the bag (counts of acceleration blocks).

    Attributes
    ----------
    signal : str
    stall : float
        [s] the recorder was frozen this long right before the signal.
    kill_after : float
        [s] wall time from the first block to the signal.
    exit_code : int or None
        The recorder's (None: still running 20 s after the signal, then killed).
    closed : bool
        metadata.yaml was written (the bag was closed).
    published_before : int
        Blocks the probe had received when the signal was sent.
    recorded : int
        Blocks read back from the bag (recovered after SIGKILL).
    lost : int
        Blocks published before the signal and not in the bag.
    gaps : int
        Blocks missing between the first and the last block read back.
    after_signal : int
        Blocks in the bag that the probe received only after the signal.
    in_complete_chunks : int or None
        SIGKILL: blocks inside the chunks that are complete in the file.
    missing_from_complete_chunks : int or None
        SIGKILL: of those, the blocks the recovery did not give back (the invariant: 0).
    method : str
        How the bag was read back.
    lost_window : float
        [s] wall time from the earliest lost block's arrival at the probe to the signal:
        the stretch of recording lost (to compare with the recorder's flush period).
    lost_at_start, lost_at_end : int
        Lost blocks before the first / after the last block read back.
    lost_in_stall : int
        Lost blocks that reached the probe while the recorder was frozen.
    recorder_messages : int or None
        Messages the recorder said it wrote when it closed the bag (all topics).
    """

    signal: str
    stall: float
    kill_after: float
    exit_code: int | None
    closed: bool
    published_before: int
    recorded: int
    lost: int
    gaps: int
    after_signal: int
    in_complete_chunks: int | None
    missing_from_complete_chunks: int | None
    method: str
    lost_window: float
    lost_at_start: int
    lost_at_end: int
    lost_in_stall: int
    recorder_messages: int | None

    @property
    def lost_seconds(self) -> float:
        """[s] sim time of the data lost."""
        return self.lost * BLOCK_SAMPLES / SAMPLE_RATE

    def to_dict(self) -> dict:
        return {**asdict(self), "lost_seconds": self.lost_seconds}


def _gaps(indexes: list[int]) -> int:
    if not indexes:
        return 0
    unique = sorted(set(indexes))
    return (unique[-1] - unique[0]) // BLOCK_SAMPLES + 1 - len(unique)


def run_recorder_trial(signal_name: str, kill_after: float, work: Path, *,
                       real_time_factor: float = 10.0, flush_period: float = 1.0,
                       stall: float = 0.0, start_timeout: float = 60.0) -> RecorderTrial:
    """One trial in the empty directory ``work`` (bag, scenario and node logs go there)."""
    number = SIGNALS[signal_name]
    bag = work / "bag"
    flight = (kill_after + 3.0) * real_time_factor  # [s sim] the flight outlasts the trial
    scenario = write_scenario(work / "scenario.yaml", duration=round(flight, 1))
    with ros_session(work / "logs") as session:
        probe = session.start_probe(data_topics=True)
        recorder = session.start("aero_dva_sim", "mcap_recorder", output=str(bag),
                                 use_sim_time=True, flush_period=flush_period)
        simulator = session.start("aero_dva_sim", "simulator", scenario=str(scenario),
                                  real_time_factor=real_time_factor, wait_for_subscribers=2,
                                  damper_timeout=1e9, exit_on_end=False)
        if not wait_until(lambda: bool(probe.blocks), start_timeout):
            raise TrialError("no acceleration block within "
                             f"{start_timeout:g} s:\n{recorder.output()}\n{simulator.output()}")
        first = probe.blocks[0].wall
        if stall > 0:
            wait_until(lambda: time.monotonic() >= first + kill_after - stall, kill_after + 1.0)
            recorder.signal(signal.SIGSTOP)
        wait_until(lambda: time.monotonic() >= first + kill_after, kill_after + 1.0)
        if stall > 0:
            recorder.signal(signal.SIGCONT)
        sent = recorder.signal(number)
        heard = list(probe.blocks)
        code = recorder.wait(20.0)
        if code is None:
            recorder.proc.kill()
            recorder.proc.wait()
        simulator.stop()
        log = recorder.output()
    before = {b.first_sample_index for b in heard if b.wall < sent}
    closed = (bag / "metadata.yaml").is_file()
    in_chunks = missing = None
    if closed:  # a closed bag needs no recovery: read as any bag
        indexes, method = read_indexes(bag), "reader (bag closed)"
    else:
        recovered = recover(bag, work)
        indexes, method = recovered.indexes, recovered.method
        mcap_files = sorted(bag.glob("*.mcap"))
        if mcap_files:
            chunked = set(complete_chunk_indexes(mcap_files[0]))
            in_chunks, missing = len(chunked), len(chunked - set(indexes))
    got = set(indexes)
    lost_set = before - got
    lost_walls = [b.wall for b in heard if b.wall < sent and b.first_sample_index not in got]
    said = re.search(r"closed .* with (\d+) messages", log)
    return RecorderTrial(
        signal=signal_name, stall=stall, kill_after=kill_after, exit_code=code, closed=closed,
        published_before=len(before), recorded=len(got), lost=len(before - got),
        gaps=_gaps(indexes), after_signal=len(got - before), in_complete_chunks=in_chunks,
        missing_from_complete_chunks=missing, method=method,
        lost_window=sent - min(lost_walls) if lost_walls else 0.0,
        lost_at_start=sum(i < min(got) for i in lost_set) if got else len(lost_set),
        lost_at_end=sum(i > max(got) for i in lost_set) if got else 0,
        lost_in_stall=sum(sent - stall <= w for w in lost_walls) if stall > 0 else 0,
        recorder_messages=int(said.group(1)) if said else None)
