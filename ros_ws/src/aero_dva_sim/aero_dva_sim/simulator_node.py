"""``simulator``: flies a scenario with the wing and the tunable Maxwell DVA, and is the clock.

Each step simulates one block of samples (exact ZOH, :class:`~aero_dva.flight.streaming_simulator.
StreamingSimulator`; with ``stepping:=compiled`` by its compiled loop, loaded before the flight
starts), publishes it, and advances ``/clock``; the rest of the graph runs on that sim time
(``use_sim_time:=true``). Its end-of-flight report says where the flight's wall time went:
``stepping_wall_s`` (the arithmetic), ``publishing_wall_s`` (building and sending the blocks) and
``held_wall_s`` (held for the controller's command), and the CPU time of the first two
(``stepping_cpu_s``, ``publishing_cpu_s``; the rest of their wall time the thread waited) and of
the process (``process_cpu_s``); before the flight, the wall time from the process's start to the
end of its set-up (``node_start_wall_s``) and from there to the flight's start
(``graph_wait_wall_s``: the rest of the graph starting and matching). The damper applies the latest
accepted ``dva/damper_command`` through :class:`~aero_dva.flight.damper.DamperModel` (range, lag,
stale fallback, rejection of absurd commands). A command from the source of a per-sample law of the
controller table (``"switching"``, ``"clipped_optimal"``) arms that law in the damper path (gains
from its file, ``switching_gains``, ``clipped_optimal_gains``, checked on load): every sample of
the block then runs the law (:mod:`aero_dva.flight.per_sample.stream`), its observer reading the
measurements with ``damper_sensor_noise``; dva/damper_state reports the mode and switching rate,
dva/damper_block the c2 the law commanded, the c2 that acted and the damper force at each sample
of the block (the acting c2 for an exact replay, ``dva replay --offline``; the commanded one for
``dva discrepancy flight``), and /diagnostics each change of mode with its reason. A stepped-sweep
scenario applies its own c2 values and ignores commands.

Its parameters (units, defaults, ranges) are the table ``SPEC`` of
:mod:`aero_dva_sim.simulator_spec`, which the node declares them from and ``simulator --help``
prints (without importing this module).

Publishes wing/acceleration, wing/displacement, wing/excitation, flight/condition,
dva/damper_state, /clock and /diagnostics (and, with a per-sample law's gains, dva/damper_block
for each block the law flies); subscribes dva/damper_command.
Rejected commands are reported on /diagnostics at most once a second per reason, each report
with the number rejected since the last one (all are counted in the end-of-flight summary).
"""
from __future__ import annotations

import math
import os
import sys
import time

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future

from aero_dva import exits
from aero_dva.bag import channels as ch
from aero_dva.control import controllers as table
from aero_dva.control.switching_io import with_per_sample
from aero_dva.flight.damper import DamperMode, DamperStatus
from aero_dva.flight.divergence import stop_message
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.text_input import loggable
from aero_dva_sim.simulator_spec import PER_SAMPLE_FILES, SPEC, main
from dva_msgs.msg import DamperCommand
from dva_ros_common import conversions
from dva_ros_common.conversions import message_class, time_to_seconds
from dva_ros_common.node_params import declare_parameters, given_parameters
from dva_ros_common.node_tools import DATA_DEPTH

POLL_PERIOD = 0.005  # [s] wall time between checks before the start and while held
# [s] wall time one step callback may spend catching up before it returns to the executor, so
# that commands (and everything else) are delivered while a flight runs behind its schedule
CATCH_UP_SLICE = 0.02
# [s] wall time between two reports of rejected commands of one kind: a controller gone wrong
# can send thousands a second, and one report (with the count) per second says as much.
REJECTION_REPORT_PERIOD = 1.0
# [s] wall time between two looks at the publishers of dva/damper_command (a graph query per
# command of a 10 kHz burst would cost more than the command)
GRAPH_PERIOD = 0.05
# [s] wall time the ended flight waits at most for its recorders to say they hold what it sent
# (or, with none, for its readers to acknowledge it): the last block and the end-of-flight
# report. A reader starved of CPU cannot have them sent again by a writer that is gone.
ACK_TIMEOUT = 5.0
#: The graph's name for a publisher whose node's name has not been discovered yet (rmw).
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"
#: The per-block topics besides /clock (the flight condition before its block, the rest after).
DATA_CHANNELS = tuple(c for c in ch.SIMULATOR_BLOCK if c != ch.CLOCK)
DATA_TOPICS = tuple(c.name for c in DATA_CHANNELS)
#: The DVA's parameters (nothing to set with absorber:=none).
ABSORBER_PARAMS = ("absorber_mass", "absorber_stiffness", "absorber_series_stiffness",
                   "absorber_position")


class Simulator(Node):
    """The plant: integrates the wing block by block and publishes what sensors would see."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        params = self._declare_parameters()
        dva = sorted(given_parameters(self) & set(ABSORBER_PARAMS))
        if params["absorber"] == "none" and dva:  # a DVA's value for a wing without one
            raise ValueError(f"parameter '{dva[0]}' sets the DVA, but absorber is 'none': drop "
                             "it or set absorber:=maxwell")
        config = load_runtime_config(params)
        for entry, option in PER_SAMPLE_FILES:
            config = with_per_sample(
                config, entry.source, params[option.simulator], params["wing"],
                lambda path, entry=entry: entry.make_law({"gains_file": str(path)}))
        self.runtime = FlightRuntime(config, compiled=params["stepping"] == "compiled")
        self.finished = Future()
        self._rtf = float(self.get_parameter("real_time_factor").value)
        self._wait_for = int(self.get_parameter("wait_for_subscribers").value)
        self._wait_for_nodes = [n for n in self.get_parameter("wait_for_nodes").value if n]
        self._wait_topics = [topic_count(t) for t in self.get_parameter("wait_for_topics").value
                             if t]
        self._wait_command_pubs = int(self.get_parameter("wait_for_command_publishers").value)
        self._wait_timeout = float(self.get_parameter("wait_timeout").value)
        self._wait_fails = bool(self.get_parameter("wait_timeout_fails").value)
        self._first_input = float(self.get_parameter("first_input_time").value)
        self._first_timeout = float(self.get_parameter("first_command_timeout").value)
        self._first_hold_since: float | None = None
        self.exit_code = 0  # run_node's exit code: FAILED when the flight could not fly
        self.commands_received = 0
        self.commands_after_end = 0  # answers to the last block's input, after the flight
        self._wait_last_answer = bool(self.get_parameter("wait_for_last_answer").value)
        self._ending: tuple[str, str, str] | None = None  # (outcome, level, text) once over
        self._exit_on_end = bool(self.get_parameter("exit_on_end").value)
        # run_node spins until ``done``: the end of the flight, or shutdown without exit_on_end
        self.done = self.finished if self._exit_on_end else None

        self._pub = {c.name: self.create_publisher(message_class(c.type_name), c.name,
                                                   DATA_DEPTH)
                     for c in DATA_CHANNELS}
        self._clock_pub = self.create_publisher(message_class(ch.CLOCK.type_name),
                                                ch.CLOCK.name, 10)
        self._diag_pub = self.create_publisher(message_class(ch.DIAGNOSTICS.type_name),
                                               ch.DIAGNOSTICS.name, 10)
        # The recorders' word that they hold the flight: the node exits on it (_finish)
        self._recorded_sub = self.create_subscription(
            message_class(ch.RECORDED.type_name), ch.RECORDED.name, self._on_recorded, 10)
        self._report_stamp = None  # the end-of-flight report's header stamp
        self._lingering: dict | None = None  # outcome, recorders, deadline timer, heard from
        self.published = dict.fromkeys(DATA_TOPICS, 0)
        # A per-sample law's damper, sample by sample, beside each block it flies.
        if any(not isinstance(law, str) for law in self.runtime.config.per_sample.values()):
            channel = ch.DAMPER_BLOCK
            self._pub[channel.name] = self.create_publisher(
                message_class(channel.type_name), channel.name, DATA_DEPTH)
            self.published[channel.name] = 0
        self._latencies: list[float] = []  # [s] sim time from a command's input to its effect
        self._max_lag = float(self.get_parameter("max_command_lag").value)
        self._condition_sent = -1.0  # [s] sim time of the last block whose condition was sent
        # lockstep: as fast as possible, each block waiting for the answer to the one before
        self._condition_ahead = self._rtf <= 0 and 0 < self._max_lag <= \
            self.runtime.block_duration * (1 + 1e-9)
        self._lag_timeout = float(self.get_parameter("command_wait_timeout").value)
        self._last_command_stamp: float | None = None
        self._lag_since: float | None = None
        self._controller_silent = False
        self.lag_timeouts = 0
        self.flew_ahead = False  # said once: the flight ran ahead of its controller
        self.rejected: dict[str, int] = {}  # rejection reason -> commands rejected
        self._rejections_reported: dict[str, tuple[float, int]] = {}  # reason -> (wall, count)
        self._command_sub = self.create_subscription(DamperCommand, ch.DAMPER_COMMAND.name,
                                                     self._on_command, 10)
        self.commanders = Commanders(self, self._command_sub, params["controller"],
                                     params["strict_commands"], self._diagnose)

        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._started_wall: float | None = None
        self._waiting_since = time.monotonic()
        self._last_status = None
        self._last_mode = DamperMode.CONSTANT
        self._law_label = "per-sample law"  # the last law the commands asked for
        # [s] wall time of the flight in the simulator's arithmetic, in building and sending
        # its messages, and held for the controller (in lockstep: the command's round trip)
        self.timing = {"stepping": 0.0, "publishing": 0.0, "held": 0.0}
        # [s] CPU time of this thread in the first two (the rest of the wall time it waited for
        # the CPU, or for DDS), and of the whole process over the flight
        self.cpu = {"stepping": 0.0, "publishing": 0.0}
        self._cpu_started: float | None = None
        self.start_timing: dict[str, float] = {}  # node_start, graph_wait (below)
        self._held_since: float | None = None
        self.switching_blocks = 0  # blocks flown with a per-sample law
        self._switching_rates: list[float] = []
        # The step timer runs only while the flight does. Before the start and while the flight
        # waits for the controller, a slow timer polls instead: spinning at the step rate (10 kHz
        # as fast as possible) would take CPU from the very nodes the simulator waits for. The
        # command that lets the flight go on steps it at once (_on_command).
        self._timer = self.create_timer(self._period(), self._step, clock=self._wall,
                                        autostart=False)
        self._poll = self.create_timer(POLL_PERIOD, self._step, clock=self._wall)
        self._stepping = False
        # After the publishers: the graph discovers them while this loads what the flight may
        # need in mid-flight (the switching law's compiled loop).
        self.runtime.prepare()
        info = self.runtime.describe()
        self.get_logger().info(
            f"scenario '{info['scenario']}': {info['duration_s']:g} s at "
            f"{info['sample_rate_hz']:g} Hz, U {info['airspeed_min']:.2f}-"
            f"{info['airspeed_max']:.2f} m/s (U_cr without DVA {info['critical_airspeed']:.2f} "
            f"m/s), absorber {info['absorber']}, real-time factor {self._rtf:g}")
        # [s] wall time from the process's start to here (its imports and this set-up), and
        # from here to the flight's start (the rest of the graph starting and matching)
        self._initialised = time.monotonic()
        self.start_timing["node_start"] = process_age()

    # ------------------------------------------------------------------ parameters
    def _declare_parameters(self) -> dict:
        return declare_parameters(self, SPEC)

    def _period(self) -> float:
        block = self.runtime.block_duration
        return block / self._rtf if self._rtf > 0 else 1e-4

    # ------------------------------------------------------------------ callbacks
    def _on_command(self, msg: DamperCommand) -> None:
        if self._ending is not None:  # the flight is over: an answer to its last input
            self.commands_after_end += 1
            stamp = time_to_seconds(msg.header.stamp)
            self._last_command_stamp = max(stamp, self._last_command_stamp or 0.0)
            self._step()
            return
        self.commands_received += 1
        # every command is checked against the flight's commander first, so that one from
        # another node or source is counted whatever else is wrong with it
        if not self.commanders.admit(msg.source, self.runtime.time):
            self._report_rejection(msg, "unexpected_commander")
            if self.commanders.stop_reason is not None:
                self._fail(self.commanders.stop_reason)
            return
        stamp = time_to_seconds(msg.header.stamp)
        if stamp > self.runtime.time + self.runtime.block_duration * (1 + 1e-9):
            # a command answers an input the flight has published: one from beyond the next
            # block is a clock gone wrong or a forgery, and would skew the latencies
            self._report_rejection(msg, "stamp_ahead_of_sim_time")
            return
        result = self.runtime.command(msg.damping, msg.source)
        if result is not None and result.accepted:
            # The command acts from the next block on; its stamp is its input's time.
            self._latencies.append(self.runtime.time - stamp)
            self._check_ahead(stamp)
            self._last_command_stamp = max(stamp, self._last_command_stamp or 0.0)
            self._controller_silent = False
            if not self._stepping and self._started_wall is not None:
                self._step()
        if result is not None and not result.accepted:
            self._report_rejection(msg, result.rejection.value)

    def _report_rejection(self, msg: DamperCommand, reason: str) -> None:
        """Count every rejected command; report each reason at most once a period."""
        count = self.rejected[reason] = self.rejected.get(reason, 0) + 1
        wall = time.monotonic()
        last_wall, last_count = self._rejections_reported.get(reason, (-math.inf, 0))
        if wall - last_wall < REJECTION_REPORT_PERIOD:
            return
        self._rejections_reported[reason] = (wall, count)
        since = count - last_count
        source = loggable(msg.source)  # outside text: escaped and cut
        self._diagnose("warn", f"rejected damper command {msg.damping!r} N s/m from "
                       f"'{source}': {reason}"
                       + (f" ({since} such commands since the last report)" if since > 1 else ""),
                       {"command": msg.damping, "source": source, "reason": reason,
                        "rejected_since_last_report": since, "rejected_total": count})

    def _missing(self) -> list[str]:
        """What the start of the flight still waits for (empty: nothing)."""
        own = {**self._pub, ch.CLOCK.name: self._clock_pub}
        missing = [f"{self._wait_for} subscribers on {t}" for t in self._pub
                   if self._pub[t].get_subscription_count() < self._wait_for]
        missing += [f"node {n}" for n in sorted(set(self._wait_for_nodes)
                                                - set(self.get_node_names()))]
        for topic, count in self._wait_topics:
            have = (own[topic].get_subscription_count() if topic in own
                    else self.count_subscribers(topic))
            if have < count:
                missing.append(f"{count} subscribers on {topic} ({have})")
        if self._command_sub.get_publisher_count() < self._wait_command_pubs:
            missing.append(f"{self._wait_command_pubs} publishers matched on "
                           f"{ch.DAMPER_COMMAND.name}")
        return missing

    def _ready(self) -> bool:
        missing = self._missing()
        if not missing:
            return True
        if time.monotonic() - self._waiting_since > self._wait_timeout:
            if self._wait_fails:
                self._fail(f"the node graph was not complete after {self._wait_timeout:g} s "
                           f"(missing: {'; '.join(missing)}): flight not started")
                return False
            self.get_logger().warning(f"starting without {'; '.join(missing)}")
            return True
        return False

    def _waiting_for_controller(self) -> bool:
        """With ``max_command_lag``, hold the flight until the controller has caught up."""
        if self._max_lag <= 0 or self.runtime.sweeps_damping:
            return False  # (a stepped sweep applies its own c2: no command to wait for)
        if self._last_command_stamp is None:
            return self._waiting_for_first_command()
        if self.runtime.time <= self._last_command_stamp + self._max_lag + 1e-9:
            self._lag_since = None
            return False
        if self._controller_silent:
            return False
        now = time.monotonic()
        if self._lag_since is None:
            self._lag_since = now
        if now - self._lag_since < self._lag_timeout:
            return True
        # The controller fell silent: fly on (the damper's fallback acts) until it speaks again.
        self._lag_since = None
        self._controller_silent = True
        self.lag_timeouts += 1
        self._say_ahead(f"no command for {self._lag_timeout:g} s of wall time "
                        "(command_wait_timeout): flying on without the controller")
        return False

    def _check_ahead(self, stamp: float) -> None:
        """Say it when a command arrives for an input the flight has already flown past by more
        than ``max_command_lag`` and a block: its c2 then acts later than in step."""
        behind = self.runtime.time - stamp
        if behind > max(self._max_lag, 0.0) + self.runtime.block_duration + 1e-9:
            self._say_ahead(f"a command for t = {stamp:.3f} s arrived at t = "
                            f"{self.runtime.time:.3f} s of the flight ({behind:.3f} s behind; "
                            f"max_command_lag {self._max_lag:g} s"
                            + (", so the flight runs free" if self._max_lag <= 0 else "") + ")")

    def _say_ahead(self, what: str) -> None:
        """Once per flight, loudly (log and /diagnostics): the flight is ahead of its
        controller, so the commands act later than the lockstep run_flight keeps, and the
        record depends on how fast this machine is."""
        if self.flew_ahead:
            return
        self.flew_ahead = True
        self._diagnose("warn", f"FLYING AHEAD OF THE CONTROLLER: {what}; its c2 acts later "
                       "than in step, and this flight's record depends on the machine's speed. "
                       "Keep the nodes in step with max_command_lag (config/graph.yaml sets "
                       "it; run_flight does). Said once.", {"event": "flying_ahead"})

    def _waiting_for_first_command(self) -> bool:
        """Hold past the controller's first input until its first command has arrived: a
        start that depended on when discovery completes would make every run differ."""
        if self.runtime.time <= self._first_input + 1e-9:
            return False
        now = time.monotonic()
        if self._first_hold_since is None:
            self._first_hold_since = now
        if self._first_timeout > 0 and now - self._first_hold_since > self._first_timeout:
            self._fail(f"no damper command within {self._first_timeout:g} s (wall) of the "
                       f"first input at t = {self._first_input:g} s: the controller never "
                       "acted; flight stopped")
        return True

    def _step(self) -> None:
        if self.finished.done() or self._lingering is not None:
            return
        if self._ending is not None:
            self._end(*self._ending)
            return
        if self._started_wall is None:
            if not self._ready():
                return
            self._started_wall = time.monotonic()
            self._cpu_started = time.process_time()
            self.start_timing["graph_wait"] = self._started_wall - self._initialised
        began = time.monotonic()
        while True:
            if self._waiting_for_controller():
                if self.finished.done():
                    return
                if self._held_since is None:
                    self._held_since = time.perf_counter()
                self._set_stepping(False)
                return
            if self._sim_time_due() < self.runtime.time - 0.5 * self.runtime.block_duration:
                self._set_stepping(True)  # a paced flight ahead of schedule waits for a tick
                return
            stepped, stepped_cpu = time.perf_counter(), time.thread_time()
            if self._held_since is not None:
                self.timing["held"] += stepped - self._held_since
                self._held_since = None
            self._publish_condition()
            block = self.runtime.step()
            published, published_cpu = time.perf_counter(), time.thread_time()
            if self._condition_ahead and not (block.diverged or self.runtime.done):
                self._publish_condition()  # the next block's
            self._publish(block)
            self.timing["stepping"] += published - stepped
            self.timing["publishing"] += time.perf_counter() - published
            self.cpu["stepping"] += published_cpu - stepped_cpu
            self.cpu["publishing"] += time.thread_time() - published_cpu
            self._check_damper_status()
            if block.diverged:
                self._end("diverged", "error", stop_message(
                    float(block.airspeed[-1]), self.runtime.critical_airspeed, block.t0))
                return
            if self.runtime.done:
                self._end("completed", "ok", "flight completed")
                return
            # A paced flight that fell behind its wall-clock schedule (it waited for the
            # controller, or a tick came late) catches up, so the real-time factor holds on
            # average instead of every wait adding to the flight's wall time; in slices, the
            # next one on the next tick: a machine too busy to keep the pace once kept the
            # callback looping for the whole flight, and no command was ever taken in.
            if not self._behind_schedule() or time.monotonic() - began > CATCH_UP_SLICE:
                break
        # As fast as possible the flight mostly has to wait for the controller right away:
        # pause now rather than on the next tick. A paced flight waits for its tick.
        waiting = self._waiting_for_controller()
        if waiting and self._held_since is None:
            self._held_since = time.perf_counter()  # held from now until the command comes
        self._set_stepping(self._rtf > 0 or not waiting)

    def _sim_time_due(self) -> float:
        """[s] sim time the flight should have reached by now (inf when not paced)."""
        if self._rtf <= 0:
            return math.inf
        return (time.monotonic() - self._started_wall) * self._rtf

    def _behind_schedule(self) -> bool:
        due = self._sim_time_due()
        return math.isfinite(due) and due >= self.runtime.time + self.runtime.block_duration

    def _check_damper_status(self) -> None:
        snapshot = self.runtime.flown_damper  # what the block just published was flown with
        status = snapshot.status
        if status != self._last_status and status in (DamperStatus.FALLBACK_STALE,):
            ended = (f" (the {self._law_label} is disarmed)"
                     if self._last_mode == DamperMode.SWITCHING else "")
            self._diagnose("warn", "no damper command within "
                           f"{self.runtime.config.damper.stale_timeout:g} s: fallback c2 = "
                           f"{snapshot.applied_damping:g} N s/m applied{ended}", {})
        self._last_status = status
        if snapshot.mode != self._last_mode:
            if snapshot.mode != DamperMode.CONSTANT:  # the law the commands ask for
                entry = table.by_source(snapshot.source)
                self._law_label = entry.label if entry is not None else snapshot.source
            if snapshot.mode == DamperMode.SWITCHING:
                self._diagnose("ok", f"{self._law_label} armed in the damper path", {})
            elif snapshot.mode == DamperMode.SWITCHING_REFUSED:
                self._diagnose("warn", f"{self._law_label} refused: "
                               f"{self.runtime.law_problem(snapshot.source)}; holding the "
                               f"commanded c2 = {snapshot.applied_damping:g} N s/m", {})
            elif status != DamperStatus.FALLBACK_STALE:
                self._diagnose("ok", f"{self._law_label} disarmed: c2 = "
                               f"{snapshot.applied_damping:g} N s/m from '{snapshot.source}'",
                               {})
        if snapshot.mode == DamperMode.SWITCHING:
            self.switching_blocks += 1
            self._switching_rates.append(snapshot.switching_rate)
        self._last_mode = snapshot.mode

    def _set_stepping(self, stepping: bool) -> None:
        """Step on the timer, or poll slowly until the flight may go on."""
        if stepping != self._stepping:
            self._stepping = stepping
            (self._poll if stepping else self._timer).cancel()
            (self._timer if stepping else self._poll).reset()

    def _publish_condition(self) -> None:
        """The flight condition of the next block, before the block is flown: the scenario
        fixes it (FlightRuntime.next_condition), so a law of the condition answers while the
        simulator is busy instead of after. In lockstep (``_condition_ahead``) it goes out as
        soon as the block before has been stepped, first of all that block's messages: the law
        answers while the rest of them are sent; otherwise just before its block is stepped.
        Either way its command acts from the block after the one it answers, as before: the
        simulator takes commands only between its steps, and in lockstep the command of the
        block before is what lets the next be flown (the bag's commands replayed give its
        samples bit for bit: test_flight_determinism)."""
        if self._condition_sent == self.runtime.time:
            return  # sent ahead
        self._condition_sent = self.runtime.time
        t0, airspeed, density = self.runtime.next_condition()
        self._pub[ch.FLIGHT_CONDITION.name].publish(
            conversions.flight_condition(t0, airspeed, density))
        self.published[ch.FLIGHT_CONDITION.name] += 1

    def _publish(self, block) -> None:
        # What the controllers read goes first (the damper state, then the accelerations of the
        # spectra; the flight condition went before the block), each message built just before
        # it is sent: a controller computes while the rest of the block is built and sent.
        fs, i0, t0 = self.runtime.sample_rate, block.first_index, block.t0
        self._clock_pub.publish(conversions.clock(block.t_end))
        for channel, make in (
                (ch.DAMPER_STATE, lambda: conversions.damper_state(self.runtime.flown_damper)),
                (ch.ACCELERATION, lambda: conversions.acceleration_block(
                    t0, fs, i0, block.accelerations)),
                (ch.DISPLACEMENT, lambda: conversions.displacement_block(
                    t0, fs, i0, block.displacements)),
                (ch.EXCITATION, lambda: conversions.force_block(t0, fs, i0, block.force))):
            self._pub[channel.name].publish(make())
            self.published[channel.name] += 1
        if block.damper_force is not None:  # a per-sample law flew the block
            self._pub[ch.DAMPER_BLOCK.name].publish(conversions.damper_block(
                t0, fs, i0, self.runtime.flown_damper.source,
                self.runtime.commanded_damping(block), block.damping, block.damper_force))
            self.published[ch.DAMPER_BLOCK.name] += 1

    def _summary(self) -> dict:
        wall = time.monotonic() - (self._started_wall or time.monotonic())
        sim = self.runtime.time
        values = {"sim_time_s": sim, "wall_time_s": wall, "controller_wait_timeouts":
                  self.lag_timeouts,
                  "real_time_factor": sim / wall if wall > 0 else math.inf,
                  **{f"{phase}_wall_s": t for phase, t in self.timing.items()},
                  **{f"{phase}_cpu_s": t for phase, t in self.cpu.items()},
                  **{f"{phase}_wall_s": t for phase, t in self.start_timing.items()},
                  "process_cpu_s": time.process_time() - (self._cpu_started
                                                          or time.process_time()),
                  "critical_airspeed_no_dva": self.runtime.critical_airspeed,
                  "block_duration_s": self.runtime.block_duration,
                  "commands_received": self.commands_received,
                  "commands_accepted": len(self._latencies),
                  "blocks_switching": self.switching_blocks,
                  "switching_rate_mean": (float(np.mean(self._switching_rates))
                                          if self._switching_rates else 0.0),
                  **self.runtime.applied.values()}
        values.update(self.commanders.values())
        values.update({f"published:{t}": n for t, n in self.published.items()})
        # every command heard, the answer to the last block's input included: what a recorder
        # of the flight must hold too (dva_controller's publishers wait for both to match)
        values[f"received:{ch.DAMPER_COMMAND.name}"] = \
            self.commands_received + self.commands_after_end
        values.update({f"rejected:{reason}": n for reason, n in self.rejected.items()})
        if self._latencies:
            latency = np.array(self._latencies)
            values.update(command_latency_median_s=float(np.median(latency)),
                          command_latency_p95_s=float(np.percentile(latency, 95)),
                          command_latency_max_s=float(latency.max()))
        return values

    def _diagnose(self, level: str, text: str, values: dict) -> None:
        # One call site per severity: rclpy refuses a severity change at the same call site.
        if level == "error":
            self.get_logger().error(text)
        elif level == "warn":
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)
        self._diag_pub.publish(conversions.diagnostics(
            self.runtime.time, ch.FLIGHT_DIAGNOSTIC_NAME, ch.SIMULATOR_HARDWARE_ID,
            [(level, text, values)]))

    def _end(self, outcome: str, level: str, text: str) -> None:
        """End the flight with its report, with ``wait_for_last_answer`` once the controller
        has answered the last block's input (in lockstep, as for one more block)."""
        self._ending = (outcome, level, text)
        if self._wait_last_answer and self._waiting_for_controller():
            if not self.finished.done():
                self._set_stepping(False)  # the poll and the answer call this again
            return
        self._report(level, text)
        self._finish(outcome)

    def _fail(self, text: str) -> None:
        if self.finished.done() or self._lingering is not None:
            return
        self._report("error", text)
        self.exit_code = exits.FAILED
        self._finish("failed")

    def _report(self, level: str, text: str) -> None:
        """The end-of-flight report, with the counts the recorders check their bags by."""
        self._report_stamp = conversions.seconds_to_time(self.runtime.time)
        self._diagnose(level, text, self._summary())

    def _finish(self, outcome: str) -> None:
        """End the node once what the flight sent is safe (:meth:`_linger`): at once when every
        recorder in the graph says it holds the flight (``dva/recorded``), at ``ACK_TIMEOUT``
        if one does not; with no recorder, once every reader has acknowledged it."""
        self._timer.cancel()
        self._poll.cancel()
        if self.finished.done() or self._lingering is not None:
            return
        recorders = self._recorded_sub.get_publisher_count()
        if recorders:  # (the report, and so its stamp, went out just before: _report)
            self._lingering = {"outcome": outcome, "recorders": recorders, "heard": set(),
                               "timer": self.create_timer(ACK_TIMEOUT, self._recorders_late,
                                                          clock=self._wall)}
            return
        self._linger()
        self.finished.set_result(outcome)

    def _on_recorded(self, msg) -> None:
        linger = self._lingering
        if linger is None or self.finished.done():
            return
        if msg.header.stamp != self._report_stamp:
            return  # another flight's report (or one before this flight's last)
        linger["heard"].update(s.hardware_id for s in msg.status if s.name == ch.RECORDED_NAME)
        if len(linger["heard"]) >= linger["recorders"]:
            linger["timer"].cancel()
            self.finished.set_result(linger["outcome"])

    def _recorders_late(self) -> None:
        linger = self._lingering
        linger["timer"].cancel()
        if self.finished.done():
            return
        self.get_logger().warning(
            f"{len(linger['heard'])} of {linger['recorders']} recorder(s) said within "
            f"{ACK_TIMEOUT:g} s that they hold the flight's messages")
        self.finished.set_result(linger["outcome"])

    def _linger(self) -> None:
        """Let every reliable reader acknowledge what the flight sent (``ACK_TIMEOUT`` in all):
        a loaded recorder (a batch task) had taken 199 of 200 blocks and no report when the
        simulator exited, and those were then lost for good (docs/reliability.md). A reader
        acknowledges on the writer's heartbeat (Fast DDS: every 3 s), so this takes up to 3 s
        even when every reader holds everything: a recorder's word ends it sooner
        (:meth:`_finish`)."""
        deadline = time.monotonic() + ACK_TIMEOUT
        for publisher in [*self._pub.values(), self._clock_pub, self._diag_pub]:
            left = deadline - time.monotonic()
            if left <= 0 or not publisher.wait_for_all_acked(Duration(seconds=left)):
                self.get_logger().warning(f"not every reader acknowledged the flight's last "
                                          f"messages within {ACK_TIMEOUT:g} s")
                return


class Commanders:
    """Who commands the damper, against the controller the flight was started with.

    The expected commander is the controller's node (by name) and its command sources (the
    controller table's). Every command is checked as it comes: its source, and the nodes
    publishing on ``dva/damper_command`` (the graph, looked at most every
    :data:`GRAPH_PERIOD` of wall time, and the publishers the subscription has matched; a
    command cannot be traced to its publisher, which the DDS message info does not carry
    here). What is foreign is counted by source and by node, reported on /diagnostics once a
    period, and carried in the end-of-flight report. ``strict`` refuses it: a foreign source
    always; a foreign node publishing stops the flight (:attr:`stop_reason`), since none of
    the commands can then be told apart. A controller of '' expects nothing (any commander,
    as before); ``none`` expects no command at all. Without DDS security a node can take the
    expected name: this tells an honest second commander, not an impostor
    (docs/reliability.md)."""

    def __init__(self, node: Node, subscription, controller: str, strict: bool, diagnose):
        self._node, self._subscription, self._diagnose = node, subscription, diagnose
        self.controller, self.strict = controller, bool(strict)
        entry = table.controller(controller) if controller not in ("", table.NONE) else None
        self.sources = set() if entry is None else {entry.source, *entry.sources}
        self.expected_node = None if entry is None else entry.node
        self.foreign_sources: dict[str, int] = {}
        self.foreign_nodes: dict[str, int] = {}
        self._nodes: tuple[str, ...] = ()  # foreign node names in the graph
        self._listed, self._expected_listed = 0, False  # publishers in it, the expected's
        self._looked = -math.inf
        self.stop_reason: str | None = None  # strict: why the flight must stop
        self._reported: dict[str, float] = {}

    def _publishers(self) -> tuple[str, ...]:
        """Publishers of commands other than the expected node's: their node names from the
        graph (cached), and "unnamed publisher" for each further one: a publisher the graph
        lists before its node's name has come (DDS discovers the endpoint and the node apart)
        or that the command subscription has matched before the graph lists it. One such
        publisher is taken for the controller's while its name is not in the graph."""
        now = time.monotonic()
        if now - self._looked >= GRAPH_PERIOD:
            self._looked = now
            topic = self._node.resolve_topic_name(ch.DAMPER_COMMAND.name)
            names = [info.node_name for info in
                     self._node.get_publishers_info_by_topic(topic)]
            self._listed = len(names)
            self._expected_listed = self.expected_node in names
            self._nodes = tuple(sorted(n for n in names
                                       if n not in (self.expected_node, UNKNOWN_NODE)))
        listed_unknown = self._listed - len(self._nodes) - self._expected_listed
        not_listed = self._subscription.get_publisher_count() - self._listed
        unnamed = listed_unknown + max(not_listed, 0) - (
            self.expected_node is not None and not self._expected_listed)
        return self._nodes + ("unnamed publisher",) * max(unnamed, 0)

    def admit(self, source: str, sim_time: float) -> bool:
        """Whether a command of ``source`` may reach the damper (all are counted)."""
        if not self.controller:
            return True
        foreign_source = source not in self.sources
        nodes = self._publishers()
        if foreign_source:
            key = loggable(source)
            self.foreign_sources[key] = self.foreign_sources.get(key, 0) + 1
            self._report(f"source '{key}'", sim_time)
        for name in dict.fromkeys(nodes):
            key = loggable(name)
            self.foreign_nodes[key] = self.foreign_nodes.get(key, 0) + 1
            self._report(f"node '{key}'", sim_time)
        if self.strict and nodes and self.stop_reason is None:
            # no command can be told from the other node's: none is applied, and the flight
            # stops at once, saying why (it cannot count as controlled)
            self.stop_reason = (f"a second commander ({', '.join(dict.fromkeys(nodes))}) "
                                f"publishes on {ch.DAMPER_COMMAND.name} beside "
                                f"{self.expected_node or 'no controller'}: flight stopped "
                                "(strict_commands)")
        return not (self.strict and (foreign_source or nodes))

    def _report(self, who: str, sim_time: float) -> None:
        wall = time.monotonic()
        if wall - self._reported.get(who, -math.inf) < REJECTION_REPORT_PERIOD:
            return
        self._reported[who] = wall
        expected = (f"only {self.expected_node} with source(s) "
                    f"{', '.join(repr(s) for s in sorted(self.sources))}"
                    if self.expected_node else "no commands (controller none)")
        self._diagnose(
            "error", f"damper command from an unexpected commander, {who}: the flight is "
            f"flown with controller {self.controller} ({expected}); "
            + ("refused (strict_commands)" if self.strict else "counted, not refused"),
            {"commander": who, "controller": self.controller})

    @property
    def foreign(self) -> int:
        """Commands from an unexpected source or while an unexpected node published."""
        return max(sum(self.foreign_sources.values()), sum(self.foreign_nodes.values()))

    def values(self) -> dict:
        """For the end-of-flight report."""
        return {"controller": self.controller, "strict_commands": self.strict,
                "commands_foreign": self.foreign,
                "foreign_sources": ", ".join(f"{k} ({n})" for k, n in
                                             sorted(self.foreign_sources.items())),
                "foreign_nodes": ", ".join(f"{k} ({n})" for k, n in
                                           sorted(self.foreign_nodes.items()))}


def process_age() -> float:
    """[s] wall time since this process started (Linux; NaN elsewhere)."""
    try:
        with open("/proc/self/stat") as stat:
            ticks = int(stat.read().rpartition(")")[2].split()[19])  # field 22, starttime
        return time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        return math.nan


def topic_count(entry: str) -> tuple[str, int]:
    """``"TOPIC:N"`` (or ``"TOPIC"``, N = 1) of the ``wait_for_topics`` parameter."""
    name, sep, count = entry.rpartition(":")
    if not sep:
        return entry, 1
    try:
        return name, int(count)
    except ValueError:
        raise ValueError(f"parameter 'wait_for_topics': {entry!r} is not TOPIC or TOPIC:N"
                         ) from None


if __name__ == "__main__":
    sys.exit(main())
