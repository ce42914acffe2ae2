"""``replay_flight``: re-run a controller on a recorded flight through the node graph, open loop.

Starts, as ``ros2 run`` would and as separate processes on sim time: ``mcap_recorder`` (the new
bag), the controller (with ``spectrum`` before it for the RBF network), then ``bag_player``,
which waits for them and plays the recorded controller inputs (``wing/acceleration``,
``dva/damper_state``, ``flight/condition``) with ``/clock`` from the log times. When the bag has
been played, this process waits until the graph's outputs (spectra, commands) have all gone by
(as many as ``--expect-spectra`` / ``--expect-commands`` say, else until none came for
:data:`QUIET` seconds), then stops the recorder (it closes its bag) and the others with SIGINT.
``dva replay`` runs this and compares the new spectra and commands with the recorded ones.

Unless ``--domain-id`` is given, the graph runs on a ROS_DOMAIN_ID reserved for this run, on
this host only (``--discovery``); every way it can fail ends in one line and an exit code
(``graph_run``).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

from aero_dva import exits
from aero_dva.bag import channels as ch
from aero_dva.control import controllers as table
from aero_dva.control.controllers import BLOCK, CONDITION, SPECTRUM
from aero_dva_sim.graph_run import (
    RunFailed,
    claim_outputs,
    die_with_parent,
    environment,
    node_failure,
    remove_if_empty,
    run_on_domain,
)
from aero_dva_sim.run_flight import (
    controller_commands,
    controller_files_given,
    damping_in_range,
    executable,
    ros_params,
    stop_process,
)
from dva_ros_common.ros_domain import DISCOVERY_CHOICES, DISCOVERY_HELP
from dva_ros_common.shared_memory import clear_dead_ports

INPUTS = tuple(c.absolute() for c in (ch.ACCELERATION, ch.DAMPER_STATE, ch.FLIGHT_CONDITION))
DEFAULT_RATE = 10.0  # x recorded speed; docs/replay.md: what the graph keeps up with here


QUIET = 2.0  # [s] wall time without a new output after which an unbounded replay is done
OUTPUT_WAIT = 60.0  # [s] wall time at most for the outputs after the bag has been played


def watched_channels(controller: str) -> list[ch.Channel]:
    """The outputs :class:`OutputWatch` counts: a controller's commands follow its inputs one
    for one, a law of spectra's after the spectra (a law on its own timer, such as the fixed
    controller, answers no input: nothing to wait for)."""
    kind = table.controller(controller).inputs[0]
    if kind == SPECTRUM:
        return [ch.SPECTRUM, ch.DAMPER_COMMAND]
    return [ch.DAMPER_COMMAND] if kind == CONDITION else []


def build_commands(args, inputs: list[str]) -> dict[str, list[str]]:
    """The processes of the replay graph, in start order (the player last)."""
    sim_time = {"use_sim_time": True}
    commands = {
        "mcap_recorder": [executable("aero_dva_sim", "mcap_recorder"), "--ros-args",
                          *ros_params(output=args.out, **sim_time),
                          "-p", "exclude:=[/rosout,/parameter_events]"],
    }
    # The commands are held until the recorder and this process's watch have matched them
    # (the spectra until the network, the recorder and the watch have).
    watch = 1 if watched_channels(args.controller) else 0
    commands.update(controller_commands(args, command_readers=1 + watch,
                                        spectrum_readers=2 + watch,
                                        damper_states=ch.DAMPER_STATE.absolute() in inputs,
                                        **sim_time))
    others = list(commands)
    # The links between the nodes must be up before the first message, not only the nodes:
    # the spectra reach the network and the recorder, the commands the recorder (and both the
    # watch).
    links = [f"{ch.DAMPER_COMMAND.absolute()}:{1 + watch}"]
    if SPECTRUM in table.controller(args.controller).inputs:
        links.insert(0, f"{ch.SPECTRUM.absolute()}:{2 + watch}")
    commands["bag_player"] = [
        executable("aero_dva_sim", "bag_player"), "--ros-args",
        *ros_params(bag=args.bag, rate=args.rate, wait_for_subscribers=1,
                 wait_for_nodes="[" + ",".join(others) + "]",
                 wait_for_topics="[" + ",".join(f'"{t}"' for t in links) + "]", delay=1.0,
                 topics="[" + ",".join(inputs) + "]", wait_timeout=60.0,
                 wait_timeout_fails=True,
                 # the player's writers resend what a starved node missed only while they
                 # exist: it stays until all is acknowledged (the outputs' own bound)
                 ack_timeout=OUTPUT_WAIT),
    ]
    return commands


class OutputWatch:
    """Counts the graph's outputs on ``channels`` as they go by, on the replay's ROS domain.

    The replay is over when its outputs are, not after a fixed time: on a busy machine the
    spectrum node and the controller can be seconds behind the player.
    """

    def __init__(self, domain: int, channels: list[ch.Channel]):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from dva_ros_common.conversions import message_class

        self.counts = {channel.absolute(): 0 for channel in channels}
        self.last = time.monotonic()  # wall time of the last output (or of the start)
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = Node("replay_watch", context=self.context)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for channel in channels:
            topic = channel.absolute()
            self.node.create_subscription(message_class(channel.type_name), topic,
                                          lambda _msg, topic=topic: self._seen(topic), qos)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def _seen(self, topic: str) -> None:
        self.counts[topic] += 1
        self.last = time.monotonic()

    def spin(self, seconds: float) -> None:
        self.executor.spin_once(timeout_sec=seconds)

    def wait_for_outputs(self, expected: dict[str, int], quiet: float, timeout: float) -> bool:
        """Spin until every topic of ``expected`` has its count (the others: until no output
        came for ``quiet`` s); False when ``timeout`` [s] ran out first."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            counted = all(self.counts[t] >= n for t, n in expected.items())
            unbounded = [t for t in self.counts if t not in expected]
            if counted and (not unbounded or time.monotonic() - self.last >= quiet):
                return True
            self.spin(0.05)
        return False

    def close(self) -> None:
        import rclpy

        from dva_ros_common.node_tools import close_executor

        close_executor(self.executor)
        rclpy.try_shutdown(context=self.context)


def run(args) -> dict:
    """Run the replay graph; return a summary (raises SystemExit on failure)."""
    from aero_dva.bag.reader import bag_topics

    present = bag_topics(args.bag)
    inputs = [t for t in INPUTS if t in present]
    if not inputs:
        raise RunFailed(f"bag {args.bag} holds none of {list(INPUTS)}", exits.BAD_INPUT)
    out, logs = claim_outputs(args.out, "", option="--out")
    args.out = str(out)
    args.run_name = out
    env = environment(args.domain_id)
    # Its watch is a DDS participant of its own (the nodes clear such files in run_node).
    clear_dead_ports("replay_flight:")
    processes: dict[str, subprocess.Popen] = {}
    started = time.monotonic()
    try:
        commands = build_commands(args, inputs)
        watch = OutputWatch(args.domain_id, watched_channels(args.controller))
    except BaseException:
        remove_if_empty(logs, out)  # nothing was started: leave nothing behind
        raise
    expected = {t: n for t, n in ((ch.SPECTRUM.absolute(), args.expect_spectra),
                                  (ch.DAMPER_COMMAND.absolute(), args.expect_commands))
                if n is not None and t in watch.counts}
    complete = True
    try:
        for name, argv in commands.items():
            with open(logs / f"{name}.log", "wb") as log:
                processes[name] = subprocess.Popen(argv, env=env, stdout=log,
                                                   stderr=subprocess.STDOUT,
                                                   preexec_fn=die_with_parent)
        deadline = time.monotonic() + args.timeout
        while processes["bag_player"].poll() is None:
            if time.monotonic() > deadline:
                raise RunFailed(f"playing took longer than {args.timeout} s (--timeout); node "
                                f"logs in {logs}")
            for name, process in processes.items():
                if name != "bag_player" and process.poll() is not None:
                    raise node_failure(name, process.returncode, logs / f"{name}.log",
                                       "before the bag was played")
            watch.spin(0.05)
        if processes["bag_player"].returncode == 0:
            complete = watch.wait_for_outputs(expected, QUIET, OUTPUT_WAIT)
    finally:
        # the recorder first, while the nodes whose messages it drains are still up
        order = ["mcap_recorder", *(n for n in reversed(processes) if n != "mcap_recorder")]
        codes = {name: stop_process(processes[name], timeout=15.0)
                 for name in order if name in processes}
        watch.close()
    player = codes.get("bag_player")
    if player not in (exits.DONE, exits.PARTIAL):  # PARTIAL: a damaged bag, played in part
        raise node_failure("bag_player", player, logs / "bag_player.log", "")
    try:
        counts = {name: info.message_count for name, info in bag_topics(out).items()}
    except (OSError, ValueError) as exc:  # the bag this run recorded: not the user's input
        raise RunFailed(f"the recorded bag does not read back: {exc}") from None
    return {"bag": str(out), "node_logs": str(logs), "played": inputs, "rate": args.rate,
            "wall_time": time.monotonic() - started, "exit_codes": codes, "counts": counts,
            "outputs_seen": dict(watch.counts), "outputs_complete": complete,
            "played_all": player == exits.DONE}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="replay_flight",
        description="Re-run a controller on a recorded flight through the ROS 2 node graph "
                    "(bag_player -> [spectrum ->] controller -> mcap_recorder, open loop) and "
                    "record its spectra and commands as a new bag. `dva replay` compares them "
                    "with the recorded ones.",
        epilog=exits.help_text().replace("Exit codes: ", "Exit codes (also exit_code in "
                                         "--json): ", 1) + " 1 here: the bag was damaged and "
               "played in part, or the graph's outputs did not all come.")
    parser.add_argument("bag", help="recorded flight (bag directory or .mcap file)")
    laws = table.controllers((BLOCK,))
    parser.add_argument("--controller", choices=[c.name for c in laws], required=True,
                        help="the block-rate law to re-run: "
                             + "; ".join(f"{c.name}: {c.label}" for c in laws))
    table.add_options(parser, laws)
    parser.add_argument("--out", required=True,
                        help="bag directory to create, with the node logs in <out>_logs; "
                             "refused if either exists")
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE,
                        help=f"playing speed, x recorded (default {DEFAULT_RATE:g})")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID (default: one reserved for this run)")
    parser.add_argument("--discovery", choices=tuple(DISCOVERY_CHOICES), default=None,
                        help=DISCOVERY_HELP)
    parser.add_argument("--timeout", type=float, default=600.0,
                        help="[s] wall time allowed for playing (default 600)")
    parser.add_argument("--expect-spectra", type=int, default=None, metavar="N",
                        help="spectra the graph will publish (a law of spectra): wait for them "
                             "after playing (default: until none came for 2 s)")
    parser.add_argument("--expect-commands", type=int, default=None, metavar="N",
                        help="commands the controller will publish (a law of inputs): likewise")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not controller_files_given("replay_flight", args) or \
            not damping_in_range("replay_flight", args):
        return 2
    if not args.rate > 0:
        print("replay_flight: error: --rate must be > 0 (the graph must keep up)",
              file=sys.stderr)
        return 2
    summary, code = run_on_domain("replay_flight", run, args)
    if summary is None:
        if args.json:
            print(json.dumps({"exit_code": code, "error": args.failure,
                              "bag": None if args.run_name is None else str(args.run_name)}))
        return code
    complete = summary["played_all"] and summary["outputs_complete"]
    code = exits.DONE if complete else exits.PARTIAL
    summary["exit_code"] = code
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print("\n".join(f"{k:12s} {v}" for k, v in summary.items()))
    if not complete:
        print("replay_flight: " + ("the bag was damaged and played in part" if not
                                   summary["played_all"] else "the graph's outputs did not "
                                   f"all come within {OUTPUT_WAIT:g} s")
              + f"; see {summary['node_logs']} (run {summary['bag']})", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
