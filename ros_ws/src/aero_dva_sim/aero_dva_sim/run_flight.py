"""``run_flight``: fly one scenario through the node graph and summarise the recorded bag.

Starts the nodes as separate processes, exactly as ``ros2 run`` would (recorder, the chosen
controller's nodes as its entry of the controller table says, :mod:`aero_dva.control.controllers`:
its node, and the spectrum node for a law of spectra; the simulator last), waits for the
simulator to end the flight, stops the others with SIGINT (the controller's nodes first, each
answering what it still has queued, then the recorder, which takes queued messages until it
holds all the simulator counted and closes its bag), then reads the bag back and prints a
summary. Every node uses sim time from the simulator's /clock.

Unless ``--domain-id`` is given, the graph runs on a ROS_DOMAIN_ID reserved for this run, so
several runs (or tests) on one machine do not hear each other, and its nodes discover each
other on this host only (``--discovery``). Its outputs (the bag and ``<bag>_logs``) are this
run's alone; every way it can fail ends in one line and an exit code (``graph_run``).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

from aero_dva import exits
from aero_dva.bag import channels as ch
from aero_dva.control import controllers as table
from aero_dva.control.controllers import BLOCK, CONDITION, NONE, SAMPLE, SPECTRUM, TICK
from aero_dva.flight.flight_limits import DEFAULT_STALE_TIMEOUT
from aero_dva_sim.graph_run import (  # noqa: F401 - die_with_parent: shared
    RunFailed,
    claim_outputs,
    die_with_parent,
    environment,
    node_failure,
    remove_if_empty,
    run_on_domain,
)
from dva_ros_common.ros_domain import DISCOVERY_CHOICES, DISCOVERY_HELP

RECORDER = "mcap_recorder"


def entry_of(name: str) -> table.Controller | None:
    """The controller table's entry of ``--controller name`` (None: ``none``)."""
    return None if name == NONE else table.controller(name)


def spectrum_window() -> float:
    """[s] the spectrum node's default window: a law of spectra's first input ends it."""
    return next(p.default for p in table.SPECTRUM_SHAPE if p.name == "window_duration")


def executable(package: str, name: str) -> str:
    """``<prefix of package>/lib/<package>/<name>``, resolved as ``ros2 run`` does."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        path = Path(get_package_prefix(package)) / "lib" / package / name
    except PackageNotFoundError:
        raise RunFailed(f"package '{package}' not found; source scripts/env.sh (or run "
                        "./run.sh)") from None
    if not os.access(path, os.X_OK):
        raise RunFailed(f"no executable {path}")
    return str(path)


def ros_params(**values) -> list[str]:
    """``-p name:=value`` arguments for a node's ``--ros-args`` (None and "" left out)."""
    out = []
    for key, value in values.items():
        if value is None or value == "":  # rcl cannot parse an empty override
            continue
        text = str(value).lower() if isinstance(value, bool) else str(value)
        out += ["-p", f"{key}:={text}"]
    return out


def build_commands(args, bag: Path) -> dict[str, list[str]]:
    """The processes of the graph, in start order (the simulator last)."""
    sim_time = {"use_sim_time": True}
    commands = {
        RECORDER: [executable("aero_dva_sim", "mcap_recorder"), "--ros-args",
                          *ros_params(output=bag, expect_flight_report=True, **sim_time)],
    }
    # Commands are held until the simulator and the recorder have both matched them.
    commands.update(controller_commands(args, command_readers=2, **sim_time))
    commands["simulator"] = simulator_command(args, others=list(commands))
    return commands


def graph_links(controller: str, others: list[str]) -> list[str]:
    """``TOPIC:N`` entries the simulator waits for before its first block: the recorder and the
    controller's nodes subscribed to what they read, every node to /clock, the recorder to the
    commands (and spectra) it must record from the first one on."""
    entry = entry_of(controller)
    reads = () if entry is None else entry.node_reads
    links = [f"{ch.LAW_INPUTS[kind].name}:2" for kind in reads]
    links.append(f"/clock:{len(others)}")
    if entry is not None:
        links.append(f"{ch.DAMPER_COMMAND.name}:2")
    if entry is not None and SPECTRUM in entry.inputs:
        links.append(f"{ch.SPECTRUM.name}:2")
    return links


def simulator_command(args, others: list[str]) -> list[str]:
    """The simulator's command line: the flight starts once the graph is complete (every node
    up and every link matched, or it fails after --wait-timeout) and holds at the controller's
    first input until its first command has arrived."""
    entry = entry_of(args.controller)
    lag = (0.0 if entry is None else entry.command_lag) if args.max_command_lag is None \
        else args.max_command_lag
    return [
        executable("aero_dva_sim", "simulator"), "--ros-args",
        *ros_params(scenario=args.scenario, wing=args.wing, absorber=args.absorber,
                 real_time_factor=args.real_time_factor, wait_for_subscribers=1,
                 wait_for_nodes="[" + ",".join(others) + "]",
                 wait_for_topics="[" + ",".join(f'"{t}"' for t in graph_links(
                     args.controller, others)) + "]",
                 wait_for_command_publishers=0 if entry is None else 1,
                 wait_timeout=args.wait_timeout, wait_timeout_fails=True,
                 max_command_lag=lag,
                 first_input_time=first_input_time(args),
                 first_command_timeout=args.wait_timeout,
                 command_wait_timeout=args.command_wait_timeout,
                 # a law of flight conditions answers the last block too: the flight's report
                 # counts that answer, and the recorder waits for it (no margin at the stop)
                 wait_for_last_answer=entry is not None and entry.inputs[0] == CONDITION,
                 damper_timeout=1e9 if entry is None else args.damper_timeout,
                 controller=args.controller,
                 strict_commands=getattr(args, "strict_commands", True),
                 **per_sample_params(args)),
    ]


def first_input_time(args) -> float:
    """[s] sim time of the controller's first input: the flight flies the block holding that
    sample, then holds until the first command has come, which then acts from the next block
    on (as in process, docs/evaluation.md). A law of spectra's first input is the last sample
    of its first 2 s spectrum window. A law on a timer (the fixed controller, the switching
    supervisor) commands on the flight's clock, first at 1/rate, which the clock reaches only
    after the sample before it: that sample. (The window's end itself, 2 s, let the flight fly
    one more block before it held; 0 for the timers held blocks shorter than their period at
    the first block's end, for a command that could never come.) A law of flight conditions
    answers each block: its first input is the first block's."""
    entry = entry_of(args.controller)
    if entry is None or entry.inputs[0] not in (SPECTRUM, TICK):
        return 0.0
    from aero_dva import data_files
    from aero_dva.flight.scenario_io import load_scenario

    path = args.scenario or data_files.data_file("scenario_ramp.yaml")
    sample = 1.0 / load_scenario(path).sample_rate
    first = spectrum_window() if entry.inputs[0] == SPECTRUM else 1.0 / table.flight_rate(entry)
    return first - sample


def per_sample_params(args) -> dict:
    """The simulator's damper-path parameters for a per-sample law: its files (the package's
    by default), the damper's lag and the sensor noise of its observer (as the law was
    designed, by default)."""
    lag = getattr(args, "damper_time_constant", None)
    noise = getattr(args, "sensor_noise", None)
    entry = entry_of(args.controller)
    if entry is None or entry.runs != SAMPLE:
        return {} if lag is None else {"damper_time_constant": lag}
    out = {o.simulator: option_value(args, o) for o in entry.options if o.simulator}
    out["damper_time_constant"] = entry.damper_lag if lag is None else lag
    out["damper_sensor_noise"] = entry.sensor_noise if noise is None else noise
    return out


def option_value(args, option: table.Option):
    """The value of a controller's option in ``args``, or its package file, or None."""
    value = getattr(args, option.name, None)
    if value is None and option.default_file:
        from aero_dva.data_files import data_file

        value = str(data_file(option.default_file))
    return value


def recorder_child() -> None:
    """In the recorder's child before exec: :func:`die_with_parent`, and the batch scheduling
    class (``SCHED_BATCH``, no privilege needed): the recorder is woken by every message of
    every block, and a woken normal task preempts the running one, here the simulator or the
    controller, whose round trip is the flight's pace. As a batch task it takes the CPU they
    leave (the other core, the pauses); its readers keep 1000 messages per topic meanwhile."""
    die_with_parent()
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError):
        pass  # not Linux: the recorder runs as a normal task


def stop_process(process: subprocess.Popen, timeout: float) -> int:
    """SIGINT, then SIGKILL after ``timeout`` [s]; the exit code."""
    return stop_processes([process], timeout)[0]


def stop_processes(group: list[subprocess.Popen], timeout: float) -> list[int]:
    """SIGINT to every process of ``group`` at once, SIGKILL to those still running after
    ``timeout`` [s]; their exit codes."""
    for process in group:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout
    for process in group:
        try:
            process.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return [process.returncode for process in group]


def stop_graph(processes: dict[str, subprocess.Popen], timeout: float = 15.0) -> dict[str, int]:
    """Stop the nodes, the exit code of each: the simulator (if it still runs), then the
    controller's nodes together, each answering the inputs it still has queued, then the
    recorder, which takes what is queued until it holds every message the simulator counted
    (it says so on closing). No fixed margin: each stop waits for the one before it."""
    order = [["simulator"], [n for n in processes if n not in ("simulator", RECORDER)],
             [RECORDER]]
    codes = {}
    for names in order:
        names = [n for n in names if n in processes]
        codes.update(zip(names, stop_processes([processes[n] for n in names], timeout)))
    return {name: codes[name] for name in processes}


def wait_for_exit(processes: list[subprocess.Popen], timeout: float) -> None:
    """Return when one of ``processes`` has exited, or after ``timeout`` [s]."""
    if any(p.poll() is not None for p in processes):
        return
    try:
        fds = [os.pidfd_open(p.pid) for p in processes]
    except (AttributeError, OSError):  # no pidfd (not Linux 5.3+): look again shortly
        time.sleep(min(timeout, 0.01))
        return
    try:
        select.select(fds, [], [], timeout)
    finally:
        for fd in fds:
            os.close(fd)


def _wait_for_flight(processes: dict[str, subprocess.Popen], timeout: float,
                     logs: Path) -> None:
    """Wait for the simulator to end the flight. Any other node that exits before it (a
    controller refusing its file, a recorder that cannot write) fails the run at once: the
    flight would otherwise go on with the damper's fallback under the controller's name."""
    deadline = time.monotonic() + timeout
    simulator = processes["simulator"]
    while simulator.poll() is None:
        for name, process in processes.items():
            if name != "simulator" and process.poll() is not None:
                raise node_failure(name, process.returncode, logs / f"{name}.log",
                                   "before the flight ended")
        if time.monotonic() > deadline:
            raise RunFailed(f"the flight took longer than {timeout} s (--timeout); node logs "
                            f"in {logs}")
        wait_for_exit(list(processes.values()), min(1.0, max(0.0, deadline - time.monotonic())))


def run(args) -> dict:
    """Run the graph; return the summary as a dict (raises RunFailed, OSError or ValueError on
    failure, said by run_on_domain)."""
    from aero_dva.bag.flight_log_io import load_flight_log
    from aero_dva.bag.flight_summary import summarize

    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    scenario_name = Path(args.scenario).stem if args.scenario else "ramp"
    name = getattr(args, "name", None) or f"{scenario_name}_{args.controller}"
    bag, logs = claim_outputs(args.output, f"runs/{name}_{stamp}")
    args.run_name = bag
    try:
        commands = build_commands(args, bag)
    except BaseException:
        remove_if_empty(logs, bag)  # nothing was started: leave nothing behind
        raise
    env = environment(args.domain_id)
    processes: dict[str, subprocess.Popen] = {}
    started = time.monotonic()
    ended = False
    try:
        for name, argv in commands.items():
            with open(logs / f"{name}.log", "wb") as log:
                processes[name] = subprocess.Popen(
                    argv, env=env, stdout=log, stderr=subprocess.STDOUT,
                    preexec_fn=recorder_child if name == RECORDER else die_with_parent)
        _wait_for_flight(processes, args.timeout, logs)
        ended = True
    finally:
        flown = time.monotonic()
        codes = stop_graph(processes)
        mark_unfinished(bag, ended, codes.get("simulator"), *sys.exc_info()[:2])
    stopped = time.monotonic()
    wall = stopped - started
    if codes.get("simulator") not in (0, None):
        raise node_failure("simulator", codes["simulator"], logs / "simulator.log",
                           "before the flight ended")
    try:
        log = load_flight_log(bag)
    except (OSError, ValueError) as exc:  # the bag this run recorded: not the user's input
        raise RunFailed(f"the recorded bag does not read back: {exc}") from None
    summary = summarize(log).to_dict()
    final = next((d["values"] for d in reversed(log.diagnostics)
                  if d["name"] == "simulator: flight" and "wall_time_s" in d["values"]), {})
    flight_wall = float(final.get("wall_time_s", "nan"))
    summary.update(controller=args.controller, bag=str(bag), node_logs=str(logs),
                   wall_time=wall, exit_codes=codes,
                   flight_wall_time=flight_wall,
                   # [s] wall time of each phase: the nodes' start up to the flight's (the
                   # simulator's end-of-flight report and exit included), stopping the graph
                   # once the simulator had exited, reading the bag back into this summary
                   phase_wall_times={k: None if math.isnan(v) else v for k, v in {
                       "start": flown - started - flight_wall, "flight": flight_wall,
                       "stop": stopped - flown, "summary": time.monotonic() - stopped}.items()},
                   command_latency_median=float(final.get("command_latency_median_s", "nan")))
    summary.update(applied_control(args, final, bag))
    return {k: (None if isinstance(v, float) and math.isnan(v) else v)
            for k, v in summary.items()}


def mark_unfinished(bag: Path, ended: bool, simulator_code, exc_type, exc) -> None:
    """Mark the recorder's (closed) bag as a recording stopped before its end when the flight
    did not end (interrupted, timed out, a node failed) or the simulator did not exit 0: its
    metadata.yaml then says why, ``dva bag info`` says "interrupted", and the bag cannot pass
    for a whole flight."""
    from aero_dva.bag.writer import interruption_reason, mark_interrupted

    if ended and simulator_code in (0, None):
        return
    if not ended:
        reason = interruption_reason(exc_type, exc) if exc_type is not None else \
            "stopped before its end"
    else:
        reason = f"stopped before its end: the simulator exited with {simulator_code}"
    mark_interrupted(bag, reason)


def applied_control(args, final: dict, bag: Path) -> dict:
    """What the flight was flown with, from the simulator's end-of-flight report in the bag:
    blocks on the controller's, the start-up and the fallback c2, commands received, expected
    and recorded, and ``control_problem``: why the flight must not count as controlled."""
    from aero_dva.bag.reader import bag_topics
    from aero_dva.flight.applied_control import control_problem

    counts = {name: info.message_count for name, info in bag_topics(bag).items()}
    blocks = int(final.get("blocks", 0))
    block_duration = float(final.get("block_duration_s", 0.0))
    out = {key: int(final.get(key, 0)) for key in (
        "blocks", "blocks_controlled", "blocks_startup", "blocks_fallback",
        "commands_received", "commands_accepted", "controller_wait_timeouts",
        "blocks_switching")}
    out["switching_rate_mean"] = float(final.get("switching_rate_mean", 0.0))
    out.update(bag_completeness(final, counts))
    out.update(
        commands_expected=table.expected_commands(entry_of(args.controller), blocks,
                                                  block_duration,
                                                  counts.get(ch.SPECTRUM.absolute(), 0)),
        commands_recorded=counts.get(ch.DAMPER_COMMAND.absolute(), 0),
        control_problem=None if args.controller == NONE else control_problem(
            blocks, out["blocks_controlled"], out["blocks_fallback"], args.max_fallback_share))
    out.update(commanders(final))
    # the commander first: it explains the rest (its c2, not the controller's, flew)
    problems = [p for p in (out["commander_problem"], out["control_problem"]) if p]
    out["control_problem"] = "; ".join(problems) or None
    return out


def commanders(final: dict) -> dict:
    """Who commanded the damper, from the simulator's end-of-flight report: the commands from
    a node or source other than the controller's (``commands_foreign``, by node and source),
    whether they were refused (``strict_commands``), and ``commander_problem``: a flight with
    a second commander does not count as controlled, refused or not."""
    foreign = int(final.get("commands_foreign", 0))
    nodes, sources = final.get("foreign_nodes", ""), final.get("foreign_sources", "")
    strict = str(final.get("strict_commands", "False")) == "True"
    problem = None
    if foreign:
        who = "; ".join(part for part in (f"nodes {nodes}" if nodes else "",
                                          f"sources {sources}" if sources else "") if part)
        problem = (f"{foreign} damper commands came from an unexpected commander ({who}), "
                   + ("refused" if strict else "applied: its c2 flew"))
    return {"commands_foreign": foreign, "foreign_nodes": nodes or None,
            "foreign_sources": sources or None, "strict_commands": strict,
            "commander_problem": problem}


def bag_completeness(final: dict, counts: dict) -> dict:
    """Whether the bag holds every data message the simulator published: ``end_report_recorded``
    (the simulator's end-of-flight report, which carries its counts, is in the bag),
    ``data_published``, ``data_recorded`` and ``data_missing`` (None without the report).
    A recorder starved of CPU can lose the last messages a writer sent before it exited; a
    flight's divergence is judged from its last seconds, so such a bag must not pass as whole."""
    data = [c for c in ch.SIMULATOR_BLOCK if c != ch.CLOCK] + [ch.DAMPER_BLOCK]
    recorded = sum(counts.get(c.absolute(), 0) for c in data)
    if not final:
        return {"end_report_recorded": False, "data_published": None,
                "data_recorded": recorded, "data_missing": None}
    published = sum(int(final.get(f"published:{c.name}", 0)) for c in data)
    return {"end_report_recorded": True, "data_published": published,
            "data_recorded": recorded, "data_missing": max(0, published - recorded)}


def _format(summary: dict) -> str:
    def number(key, fmt):
        value = summary.get(key)
        return "n/a" if value is None else format(value, fmt)

    diverged = summary["divergence_airspeed"] is not None
    low, high = summary.get("rms_range") or (math.nan, math.nan)
    span = f"{low:.2f}-{high:.2f} U_cr"
    lines = [
        f"controller           {summary['controller']}",
        f"flown                {number('duration', '.2f')} s of sim time in "
        f"{number('flight_wall_time', '.1f')} s wall "
        f"({summary['duration'] / (summary['flight_wall_time'] or math.inf):.1f}x real time; "
        f"{summary['wall_time']:.1f} s with starting and stopping the nodes)",
        f"command latency      {number('command_latency_median', '.3f')} s sim time from a "
        "sample to its command acting (median)",
        f"airspeed             {number('airspeed_start', '.1f')} -> "
        f"{number('airspeed_end', '.1f')} m/s (U_cr without DVA "
        f"{number('critical_airspeed', '.2f')} m/s)",
        "divergence           " + (
            f"at {number('divergence_airspeed', '.1f')} m/s = "
            f"{number('divergence_ratio', '.3f')} U_cr" if diverged
            else "none within the flight"),
        f"leading-edge RMS     {number('leading_edge_rms', '.3e')} m over {span} (the range "
        "dva evaluate compares controllers over)",
        f"mean applied c2      {number('mean_damping', '.0f')} N s/m over {span}",
        f"  before divergence  leading-edge RMS "
        f"{number('leading_edge_rms_before_divergence', '.3e')} m over what the flight flew "
        "before it (not comparable between flights)",
        *([f"{entry_of(summary['controller']).label:21s}"
           f"{summary.get('blocks_switching', 0)} blocks, "
           f"{number('switching_rate_mean', '.1f')} switches/s (mean over them)"]
          if summary["controller"] != NONE
          and entry_of(summary["controller"]).runs == SAMPLE else []),
        f"c2 applied from      the controller in {summary['blocks_controlled']} of "
        f"{summary['blocks']} blocks, start-up {summary['blocks_startup']}, fallback "
        f"{summary['blocks_fallback']}",
        f"commands             {summary['commands_received']} received of "
        + (f"at most {summary['commands_expected']} (a timer on sim time fires once per clock "
           "step it sees: fewer when the node lags)"
           if summary["controller"] != NONE and entry_of(summary["controller"]).inputs[0] == TICK
           else f"{summary['commands_expected']} expected")
        + f", {summary['commands_recorded']} recorded",
        "commanders           " + (
            f"{summary['commands_foreign']} commands from unexpected commanders ("
            + "; ".join(p for p in (summary.get("foreign_nodes") and
                                    f"nodes {summary['foreign_nodes']}",
                                    summary.get("foreign_sources") and
                                    f"sources {summary['foreign_sources']}") if p)
            + ("), refused" if summary.get("strict_commands") else "), applied")
            if summary.get("commands_foreign") else "only the controller's node and sources"),
        "bag data             " + (
            f"{summary['data_recorded']} of the {summary['data_published']} messages the "
            f"simulator published ({summary['data_missing']} missing)"
            if summary.get("end_report_recorded") else
            f"{summary.get('data_recorded')} messages; the simulator's end-of-flight report is "
            "missing (the bag may lack its last messages)"),
        f"bag (MCAP)           {summary['bag']}",
        f"node logs            {summary['node_logs']}",
    ]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="run_flight",
        description="Fly a scenario through the ROS 2 node graph (simulator, controller, "
                    "recorder as separate processes), record it to MCAP and print a summary.",
        epilog=exits.help_text().replace("Exit codes: ", "Exit codes (also exit_code in "
                                         "--json): ", 1))
    parser.add_argument("--scenario", default="",
                        help="scenario YAML (default: the package's scenario_ramp.yaml, "
                             "0.8 -> 1.2 U_cr in 30 s); at most 20,000,000 samples "
                             "(duration x sample rate, 100..20000 Hz)")
    parser.add_argument("--wing", default="", help="wing YAML (default: the chapter-6 wing)")
    parser.add_argument("--absorber", choices=("maxwell", "none"), default="maxwell")
    parser.add_argument("--strict-commands", action=argparse.BooleanOptionalAction,
                        default=True,
                        help="refuse damper commands from any node but the controller's, or "
                             "of another source than its (default; --no-strict-commands "
                             "applies them). Either way they are counted and reported, and a "
                             "flight that had them fails (exit 1)")
    flown = table.controllers((BLOCK, SAMPLE))
    parser.add_argument("--controller", choices=(*(c.name for c in flown), NONE),
                        default="fixed",
                        help="who commands c2 (default: fixed): "
                             + "; ".join(f"{c.name}: {c.label}" for c in flown)
                             + f"; {NONE}: nothing (the damper holds its start-up c2)")
    table.add_options(parser, flown)
    lags = ", ".join(f"{c.damper_lag:g} with --controller {c.name}" for c in flown
                     if c.damper_lag is not None)
    parser.add_argument("--damper-time-constant", type=float, default=None,
                        help=f"[s] the damper's first-order lag (default: {lags}, as designed; "
                             "else the simulator's 0)")
    noises = ", ".join(f"{c.sensor_noise:g} with --controller {c.name}" for c in flown
                       if c.runs == SAMPLE)
    parser.add_argument("--sensor-noise", type=float, default=None, metavar="FRACTION",
                        help="noise on a per-sample law's measurements, std over each one's "
                             f"RMS at U_cr (default: {noises}, as designed)")
    parser.add_argument("--real-time-factor", type=float, default=20.0,
                        help="sim seconds per wall second; 0 = as fast as possible (default 20)")
    parser.add_argument("--max-command-lag", type=float, default=None,
                        help="[s] sim time the flight may run ahead of the newest command's "
                             "input (default per controller: "
                             + ", ".join(f"{c.name} {c.command_lag:g}" for c in flown)
                             + "; 0 = free running)")
    parser.add_argument("--damper-timeout", type=float, default=DEFAULT_STALE_TIMEOUT,
                        help="[s] sim time without commands before the fallback c2 applies "
                             f"(default {DEFAULT_STALE_TIMEOUT:g})")
    parser.add_argument("--max-fallback-share", type=float, default=0.02,
                        help="fail (exit 1) when more than this share of the blocks ran on the "
                             "fallback c2 (default 0.02); a flight whose controller never acted "
                             "always fails")
    parser.add_argument("--wait-timeout", type=float, default=60.0,
                        help="[s] wall time allowed for the graph to come up and for the first "
                             "command; the run fails after it (default 60)")
    parser.add_argument("--command-wait-timeout", type=float, default=10.0,
                        help="[s] wall time the flight waits for a late command before flying "
                             "on with the damper's fallback (default 10)")
    parser.add_argument("--output", default=None,
                        help="bag directory to create, with the node logs in <output>_logs; "
                             "refused if either exists (default runs/<scenario>_<controller>_"
                             "<UTC time>, or the first free <that>_N)")
    parser.add_argument("--name", default=None,
                        help="the default bag's name before its UTC time: runs/<name>_<UTC "
                             "time> (default <scenario>_<controller>; not with --output)")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID (default: one reserved for this run)")
    parser.add_argument("--discovery", choices=tuple(DISCOVERY_CHOICES), default=None,
                        help=DISCOVERY_HELP)
    parser.add_argument("--timeout", type=float, default=600.0,
                        help="[s] wall time allowed for the flight (default 600)")
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    return parser


def controller_commands(args, command_readers: int = 0, spectrum_readers: int = 2,
                        damper_states: bool = True, **params) -> dict[str, list[str]]:
    """Node name -> command line of the controller nodes ``args.controller`` needs (its
    helpers, such as the spectrum node for a law of spectra, then its own; none: no node),
    each with the ROS parameters ``params``. Its options in ``args`` set its parameters. With
    ``command_readers``, the controller holds its first commands until that many subscribers
    have matched them (the spectrum node its spectra until ``spectrum_readers`` have: the law
    and the recorder). ``damper_states``: the graph's damper states are sure to come (the
    simulator's, or a bag's played), so the spectrum node waits for each block's however late
    it is, and its spectra do not depend on the load."""
    entry = entry_of(args.controller)
    if entry is None:
        return {}

    def node(name, *law, **own):
        return [executable("dva_controller", name), *law, "--ros-args",
                *ros_params(**own, **params)]

    out = {helper: node(helper, **({"hold_until_subscribers": spectrum_readers}
                                   if command_readers else {}),
                        **({"damper_state_required": damper_states}
                           if helper == "spectrum" else {}))
           for helper in entry.helpers}
    own = {o.param: getattr(args, o.name, None) for o in entry.options}
    own.update(entry.flight_values)
    if any(p.name == "wing" for p in entry.params):  # a law made for the wing it flies
        own["wing"] = getattr(args, "wing", "")
    if command_readers:
        own["hold_until_subscribers"] = command_readers
    # The project's laws keep their own executables; another package's runs in the generic
    # node, named first.
    law = () if entry.runs != BLOCK or not entry.origin else (entry.name,)
    out[entry.node] = node("controller" if law else entry.node, *law, **own)
    return out


def controller_files_given(prog: str, args) -> bool:
    """A controller's required options (--schedule, --network) must be given; False (and the
    error said) when one is missing."""
    entry = entry_of(args.controller)
    for option in () if entry is None else entry.options:
        if option.required and not getattr(args, option.name, None):
            print(f"{prog}: error: --controller {entry.name} needs --{option.name} FILE",
                  file=sys.stderr)
            return False
    return True


def per_sample_law_readable(prog: str, args) -> bool:
    """A per-sample law's files given as options must load and check (the nodes would only
    fall back to the safe c2); False (and the error said) when they do not."""
    entry = entry_of(getattr(args, "controller", NONE))
    if entry is None or entry.runs != SAMPLE or \
            not any(getattr(args, o.name, None) for o in entry.options if o.kind == "file"):
        return True
    try:
        entry.make_law({o.param: getattr(args, o.name, None) for o in entry.options
                        if getattr(args, o.name, None) is not None})
    except ValueError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return False
    return True


def damping_in_range(prog: str, args) -> bool:
    """--damping inside the damper's range (the simulator's default): a c2 the damper
    would clip or reject is refused at the door; False (and the error said) when it is not."""
    if getattr(args, "damping", None) is None:
        return True
    from aero_dva.flight.damper import damping_problem

    problem = damping_problem(args.damping, "--damping")
    if problem is not None:
        print(f"{prog}: error: {problem}", file=sys.stderr)
        return False
    return True


def sensor_noise_usable(prog: str, args) -> bool:
    """--sensor-noise: a fraction in [0, 10], for a per-sample law only; False (and the error
    said) otherwise."""
    noise = getattr(args, "sensor_noise", None)
    if noise is None:
        return True
    entry = entry_of(args.controller)
    if entry is None or entry.runs != SAMPLE:
        print(f"{prog}: error: --sensor-noise acts on a per-sample law's observer; "
              f"--controller {args.controller} has none", file=sys.stderr)
        return False
    if not (math.isfinite(noise) and 0.0 <= noise <= 10.0):
        print(f"{prog}: error: --sensor-noise must be a fraction in [0, 10], got {noise}",
              file=sys.stderr)
        return False
    return True


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not controller_files_given("run_flight", args) or \
            not per_sample_law_readable("run_flight", args) or \
            not sensor_noise_usable("run_flight", args) or \
            not damping_in_range("run_flight", args):
        return 2
    if args.name and (args.output or Path(args.name).name != args.name):
        print("run_flight: error: --name is a plain name (no folder) and goes without "
              "--output", file=sys.stderr)
        return 2
    summary, code = run_on_domain("run_flight", run, args)
    if summary is None:
        if args.json:
            print(json.dumps({"exit_code": code, "error": args.failure,
                              "bag": _text(args.run_name)}))
        return code
    code = exits.PARTIAL if summary.get("control_problem") else exits.DONE
    summary["exit_code"] = code
    print(json.dumps(summary, indent=2) if args.json else _format(summary))
    if summary.get("control_problem"):
        print(f"run_flight: error: flight not counted as controlled by "
              f"'{args.controller}': {summary['control_problem']} (run {summary['bag']})",
              file=sys.stderr)
    return code


def _text(value) -> str | None:
    return None if value is None else str(value)


if __name__ == "__main__":
    sys.exit(main())
