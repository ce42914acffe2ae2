"""The controller process killed (SIGKILL) mid-flight: how the damper falls back.

One trial: a probe, the ``fixed_controller`` (commanding ``damping``) and the ``simulator`` as
processes on a reserved domain, on sim time. Once the probe has seen the controller's c2
applied, the controller is killed ``kill_after`` seconds of wall time later. The trial then
watches ``dva/damper_state`` until the damper reports the stale fallback, and ``/diagnostics``
for the simulator's warning about it.

Two modes: ``lockstep`` flies as ``run_flight`` does (``max_command_lag`` 0.1 s: the simulator
waits for the controller, up to ``command_wait_timeout`` = 2 s of wall time, before flying on),
``free`` flies without waiting (``max_command_lag`` 0).
"""
from __future__ import annotations

import math
import signal
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

from aero_dva.flight.damper import DEFAULT_STALE_TIMEOUT
from bench.faults.recorder_faults import TrialError
from bench.faults.ros_processes import ros_session, wait_until, write_scenario

MODES = {"lockstep": 0.1, "free": 0.0}  # mode -> max_command_lag [s sim]
STATUS_OK, STATUS_FALLBACK = 0, 2  # dva_msgs/DamperState.STATUS_*
STATUS_NAMES = {0: "ok", 1: "saturated", 2: "fallback", 3: "rejected", 4: "no command"}


@dataclass(frozen=True)
class ControllerTrial:
    """How the damper went from the dead controller's c2 to the fallback.

    Attributes
    ----------
    mode : str
    kill_after : float
        [s] wall time from the controller's c2 being applied to the kill.
    commanded, fallback : float
        [N s/m] the controller's c2, and the c2 of the first fallback state.
    fallback_wall_delay : float
        [s] wall time from the kill to the first fallback state reaching the probe.
    command_age : float
        [s] sim time since the last accepted command, in the first fallback state: the sim
        time the damper held the dead controller's c2. (The probe cannot tell the sim time of
        the kill itself: its own backlog of states makes it late by a varying amount.)
    diagnostic_wall_delay : float or None
        [s] wall time from the kill to the simulator's fallback warning on /diagnostics.
    diagnostic : str
        That warning.
    applied_min, applied_max : float
        [N s/m] c2 applied in the states that reached the probe between the kill and the
        fallback (by wall time: none when the fallback's state is the first to arrive).
    held_min, held_max : float
        [N s/m] c2 applied in the states (status ok) stamped (sim time) from the last accepted
        command to the fallback: the damper's own account of what it held, whatever the
        probe's backlog.
    held_states : int
        How many such states reached the probe.
    statuses_between : dict
        Status name -> number of states between the kill and the fallback.
    longest_stall : float
        [s] longest wall time between two damper states after the kill (the simulator waiting
        for the controller).
    stalls : list of float
        [s] every such gap longer than 0.2 s, in order.
    """

    mode: str
    kill_after: float
    commanded: float
    fallback: float
    fallback_wall_delay: float
    command_age: float
    diagnostic_wall_delay: float | None
    diagnostic: str
    applied_min: float
    applied_max: float
    held_min: float
    held_max: float
    held_states: int
    statuses_between: dict
    longest_stall: float
    stalls: list

    def to_dict(self) -> dict:
        return asdict(self)


def run_controller_trial(mode: str, kill_after: float, work: Path, *, damping: float = 1500.0,
                         real_time_factor: float = 10.0,
                         damper_timeout: float = DEFAULT_STALE_TIMEOUT,
                         start_timeout: float = 60.0) -> ControllerTrial:
    """One trial in the empty directory ``work`` (scenario and node logs go there)."""
    flight = (kill_after + 10.0) * real_time_factor
    scenario = write_scenario(work / "scenario.yaml", duration=round(flight, 1))
    with ros_session(work / "logs") as session:
        probe = session.start_probe()
        controller = session.start("dva_controller", "fixed_controller", damping=damping,
                                   rate=20.0, use_sim_time=True)
        simulator = session.start(
            "aero_dva_sim", "simulator", scenario=str(scenario),
            real_time_factor=real_time_factor, max_command_lag=MODES[mode],
            damper_timeout=damper_timeout, exit_on_end=False,
            # The flight starts once the probe hears the damper states, the controller hears
            # the clock and its command publisher is matched (a node in the graph is not yet
            # a matched endpoint: a loaded machine once flew the whole free-running flight
            # before the controller's commands got through). Not complete in time: the
            # simulator fails instead of flying without them.
            wait_for_nodes=["fixed_controller", "fault_probe"],
            wait_for_topics=["dva/damper_state:1", "/clock:1"],
            wait_for_command_publishers=1, wait_timeout=start_timeout,
            wait_timeout_fails=True)

        def applied() -> bool:
            return any(s.status == STATUS_OK and s.source == "fixed" for s in probe.states)

        # (a simulator that failed, e.g. on an incomplete graph, ends the wait at once)
        if not wait_until(lambda: applied() or simulator.proc.poll() is not None,
                          2 * start_timeout) or not applied():
            seen = Counter((STATUS_NAMES[s.status], s.source) for s in list(probe.states))
            raise TrialError(f"the controller's c2 was not applied within "
                             f"{2 * start_timeout:g} s (damper states seen by (status, "
                             f"source): {dict(seen)}):\n{controller.output()}\n"
                             f"{simulator.output()}")
        ok_at = next(s.wall for s in probe.states if s.status == STATUS_OK)
        wait_until(lambda: time.monotonic() >= ok_at + kill_after, kill_after + 1.0)
        killed = controller.signal(signal.SIGKILL)

        def fallback_seen() -> bool:
            return any(s.wall > killed and s.status == STATUS_FALLBACK
                       for s in list(probe.states))

        seen = wait_until(fallback_seen, 20.0)
        wait_until(lambda: any(d.wall > killed and "fallback" in d.message
                               for d in list(probe.diagnostics)), 2.0)
        simulator.stop()
    if not seen:
        raise TrialError(f"no fallback within 20 s of the kill:\n{simulator.output()}")
    states = list(probe.states)
    before = [s for s in states if s.wall <= killed]
    after = [s for s in states if s.wall > killed]
    # The kill's fallback is the first fallback state after the controller's last applied c2,
    # in sim time: on a busy machine the free-running flight can fall back (and recover) before
    # the kill, and the probe can receive such earlier states after it.
    last_ok = max((s.stamp for s in states if s.status == STATUS_OK), default=-math.inf)
    first = min((s for s in states if s.status == STATUS_FALLBACK and s.stamp > last_ok),
                key=lambda s: s.stamp)
    between = [s for s in after if s.wall < first.wall]
    walls = [before[-1].wall] + [s.wall for s in after if s.wall <= first.wall]
    gaps = [b - a for a, b in zip(walls, walls[1:])]
    warning = next((d for d in probe.diagnostics if d.wall > killed and "fallback" in d.message),
                   None)
    values = [s.applied for s in between] or [math.nan]
    last_command = first.stamp - first.command_age
    # (the states in which the last command was in force; a command's age counts from its own
    # stamp, which a starved controller sets late, so the window may also reach back over an
    # earlier, correct fallback)
    held = [s.applied for s in states
            if last_command <= s.stamp < first.stamp and s.status == STATUS_OK] or [math.nan]
    return ControllerTrial(
        mode=mode, kill_after=kill_after, commanded=damping, fallback=first.applied,
        fallback_wall_delay=first.wall - killed, command_age=first.command_age,
        diagnostic_wall_delay=None if warning is None else warning.wall - killed,
        diagnostic="" if warning is None else warning.message,
        applied_min=min(values), applied_max=max(values),
        held_min=min(held), held_max=max(held), held_states=sum(map(math.isfinite, held)),
        statuses_between=dict(Counter(STATUS_NAMES[s.status] for s in between)),
        longest_stall=max(gaps) if gaps else 0.0, stalls=[g for g in gaps if g > 0.2])
