"""Damper command bursts at 10 kHz and invalid commands: what the damper applies and reports.

One session per kind of command: a probe (which also publishes the commands) and the
``simulator`` process, flying in real time (real-time factor 1, so 10 kHz of wall time is
10 kHz of sim time, the clock of the damper's stale timeout) and not waiting for commands.
Each burst: a valid baseline command (``BASELINE`` N s/m at 50 Hz for 0.4 s), then
``burst_seconds`` of commands of the kind at ``rate`` Hz, then quiet until the fallback.
The damper states and /diagnostics that arrive from the burst's start to 0.1 s after its end
are the burst's.
"""
from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from builtin_interfaces.msg import Time

from aero_dva.flight.damper import DAMPER_RANGE
from bench.faults.recorder_faults import TrialError
from bench.faults.ros_processes import ros_session, wait_until, write_scenario
from dva_msgs.msg import DamperCommand

BASELINE = 800.0  # [N s/m]
STATUS_NAMES = {0: "ok", 1: "saturated", 2: "fallback", 3: "rejected", 4: "no command"}


def _cycle(values: list[float]) -> Callable[[np.random.Generator, int], float]:
    return lambda rng, i: values[i % len(values)]


# kind -> c2 of the i-th command of a burst [N s/m]
KINDS: dict[str, Callable[[np.random.Generator, int], float]] = {
    "valid": lambda rng, i: float(rng.uniform(*DAMPER_RANGE)),
    "above range (5000)": _cycle([5000.0]),
    "NaN": _cycle([math.nan]),
    "+inf": _cycle([math.inf]),
    "-inf": _cycle([-math.inf]),
    "negative (-100)": _cycle([-100.0]),
    "huge (1e12)": _cycle([1e12]),
    "mixed": lambda rng, i: [float(rng.uniform(*DAMPER_RANGE)), math.nan, math.inf, -100.0,
                             1e12][i % 5],
}


@dataclass(frozen=True)
class BurstTrial:
    """One burst and what came back from the simulator during it.

    Attributes
    ----------
    kind : str
    sent : int
        Commands published.
    rate : float
        [Hz] achieved publishing rate.
    states : int
        Damper states received during the burst.
    applied_min, applied_max : float
        [N s/m] c2 applied in those states.
    applied_valid : bool
        Every applied c2 was finite and inside the damper's range.
    statuses : dict
        Status name -> number of those states.
    diagnostics : int
        /diagnostics reports of rejected commands from the simulator during the burst (its
        once-per-flight warnings, such as flying ahead of the controller, are not counted).
    diagnostic_rate : float
        [1/s] of those, per second of burst.
    diagnostic_texts : list of str
        The distinct messages (at most 3).
    logs : int
        Warnings of the simulator on /rosout during the burst.
    sim_rate : float
        Sim seconds per wall second during the burst (1 if the burst did not slow the flight).
    """

    kind: str
    sent: int
    rate: float
    states: int
    applied_min: float
    applied_max: float
    applied_valid: bool
    statuses: dict
    diagnostics: int
    diagnostic_rate: float
    diagnostic_texts: list
    logs: int
    sim_rate: float

    def to_dict(self) -> dict:
        return asdict(self)


def _sim_stamp(probe) -> Time:
    """The newest sim time heard (the stamp of the newest damper state)."""
    seconds = probe.states[-1].stamp if probe.states else 0.0
    return Time(sec=int(seconds), nanosec=int(round((seconds % 1.0) * 1e9)) % 1_000_000_000)


def _publish_for(publisher, seconds: float, rate: float, value: Callable[[int], float],
                 probe) -> int:
    """Publish ``value(i)`` at ``rate`` Hz of wall time for ``seconds``; the number sent.
    A tight loop, not sleeps: sleeping cannot pace 100 us."""
    start = time.perf_counter()
    sent = 0
    msg = DamperCommand(source="fault_burst")
    while True:
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return sent
        while sent < elapsed * rate:
            msg.header.stamp = _sim_stamp(probe)
            msg.damping = value(sent)
            publisher.publish(msg)
            sent += 1


def run_burst_session(kind: str, bursts: int, work: Path, *, rate: float = 10_000.0,
                      burst_seconds: float = 0.3, seed: int = 0,
                      start_timeout: float = 60.0) -> BurstSession:
    """``bursts`` bursts of one kind in one flight, in the empty directory ``work``."""
    rng = np.random.default_rng(seed)
    value_of = KINDS[kind]
    quiet = 0.8  # [s] after a burst: longer than the stale timeout
    cycle = 0.4 + burst_seconds + quiet
    # The flight ends soon after the last burst: its summary counts the rejected commands.
    duration = round(bursts * cycle + 3.0, 1)
    scenario = write_scenario(work / "scenario.yaml", duration=duration)
    trials = []
    with ros_session(work / "logs") as session:
        probe = session.start_probe(rosout=True)
        node = session.node("fault_burst")
        publisher = node.create_publisher(DamperCommand, "dva/damper_command", 10)
        simulator = session.start("aero_dva_sim", "simulator", scenario=str(scenario),
                                  real_time_factor=1.0, max_command_lag=0.0,
                                  wait_for_nodes=["fault_probe"])
        if not wait_until(lambda: bool(probe.states), start_timeout):
            raise TrialError(f"no damper state within {start_timeout:g} s:\n"
                             f"{simulator.output()}")
        if not wait_until(lambda: publisher.get_subscription_count() > 0, start_timeout):
            raise TrialError("the simulator does not subscribe to dva/damper_command")
        for _ in range(bursts):
            _publish_paced(publisher, 0.4, 50.0, probe)
            begin = time.monotonic()
            sent = _publish_for(publisher, burst_seconds, rate,
                                lambda i: value_of(rng, i), probe)
            end = time.monotonic()
            time.sleep(quiet)
            trials.append(_burst_result(kind, probe, sent, begin, end))
        node.destroy_node()
        wait_until(lambda: any(d.message == "flight completed" for d in list(probe.diagnostics)),
                   duration + 30.0)
        simulator.stop()
    summary = next((d.values for d in probe.diagnostics if d.message == "flight completed"), {})
    rejected = sum(int(v) for k, v in summary.items() if k.startswith("rejected:"))
    return BurstSession(kind, trials, sum(t.sent for t in trials), rejected, bool(summary))


@dataclass(frozen=True)
class BurstSession:
    """The bursts of one kind, and the simulator's count of the commands it rejected.

    ``rejected`` counts every rejected command the simulator took off the wire (its
    end-of-flight summary); ``summary_seen`` is False if that summary did not arrive.
    """

    kind: str
    trials: list[BurstTrial]
    sent: int
    rejected: int
    summary_seen: bool


def _publish_paced(publisher, seconds: float, rate: float, probe) -> None:
    msg = DamperCommand(source="fault_baseline", damping=BASELINE)
    for _ in range(round(seconds * rate)):
        msg.header.stamp = _sim_stamp(probe)
        publisher.publish(msg)
        time.sleep(1.0 / rate)


def _burst_result(kind: str, probe, sent: int, begin: float, end: float) -> BurstTrial:
    until = end + 0.1
    states = [s for s in list(probe.states) if begin <= s.wall <= until]
    diagnostics = [d for d in list(probe.diagnostics)
                   if begin <= d.wall <= until and d.name.startswith("simulator")
                   and d.message.startswith("rejected damper command")]
    logs = [g for g in list(probe.logs)
            if begin <= g.wall <= until and g.name == "simulator" and g.level >= 30]
    applied = [s.applied for s in states] or [math.nan]
    valid = all(math.isfinite(a) and DAMPER_RANGE[0] <= a <= DAMPER_RANGE[1] for a in applied)
    span = states[-1].wall - states[0].wall if len(states) > 1 else 0.0
    sim_rate = (states[-1].stamp - states[0].stamp) / span if span > 0 else math.nan
    return BurstTrial(
        kind=kind, sent=sent, rate=sent / (end - begin), states=len(states),
        applied_min=min(applied), applied_max=max(applied), applied_valid=valid,
        statuses=dict(Counter(STATUS_NAMES[s.status] for s in states)),
        diagnostics=len(diagnostics), diagnostic_rate=len(diagnostics) / (end - begin),
        diagnostic_texts=sorted({d.message for d in diagnostics})[:3], logs=len(logs),
        sim_rate=sim_rate)
