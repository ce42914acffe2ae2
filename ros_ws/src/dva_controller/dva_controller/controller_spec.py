"""The controller node's parameter table for each block-rate law of the controller table, and the
entry of its executables (``controller NAME`` and the laws' aliases, ``fixed_controller`` and
the like): ``--help``, the usage and refused arguments are answered from the table before ROS,
numpy or the node (:mod:`dva_controller.controller_node`) are imported (docs/performance.md,
the start-up budget).
"""
from __future__ import annotations

import sys
from pathlib import Path

from aero_dva import exits
from aero_dva.bag import channels as ch
from aero_dva.control import controllers as table
from aero_dva.control.controllers import BLOCK, CONDITION, SPECTRUM, Controller
from dva_controller.shared_params import param
from dva_ros_common.node_params import (
    HOLD_PARAM,
    INPUT_HEALTH_PARAMS,
    NODE_STOP,
    NodeSpec,
    node_main,
)

PACKAGE = "dva_controller"
GENERIC = "controller"  # the executable that takes the law's name first
#: What the node reads from topics (its timer is the other input a law may read).
TOPIC_KINDS = (CONDITION, SPECTRUM)


def node_spec(entry: Controller) -> NodeSpec:
    """The node's parameter table and help for ``entry``'s law."""
    topics = [k for k in entry.inputs if k in TOPIC_KINDS]
    lines = [f"subscribes {ch.LAW_INPUTS[k].name} ({_type(ch.LAW_INPUTS[k])})" for k in topics]
    lines.append(f"publishes {ch.DAMPER_COMMAND.name} ({_type(ch.DAMPER_COMMAND)}, source "
                 f"\"{entry.source}\")" + (", /diagnostics" if topics else ""))
    return NodeSpec(name=entry.node, package=PACKAGE, summary=entry.summary,
                    params=(*(param(p) for p in entry.params),
                            *(INPUT_HEALTH_PARAMS if topics else ()), HOLD_PARAM),
                    topics="\n".join(lines))


def _type(channel: ch.Channel) -> str:
    return channel.type_name.replace("/msg/", "/")


def _usage() -> str:
    laws = ", ".join(table.names((BLOCK,))) or "none"
    return (f"usage: ros2 run {PACKAGE} {GENERIC} NAME [-h] [--ros-args ...]\n\n"
            "Run the block-rate control law NAME of the controller table in a node (its "
            "parameters: NAME --help).\n"
            f"laws: {laws}\n\n{exits.help_text()} {NODE_STOP}\n")


def main(args=None) -> int:
    """The node of the law its executable is the alias of, or of the name that follows
    ``controller``."""
    argv = list(sys.argv if args is None else args)
    entry = table.by_node(Path(argv[0]).name)
    if entry is None or entry.runs != BLOCK:
        rest = argv[1:]
        if not rest or rest[0] in ("-h", "--help"):
            sys.stdout.write(_usage())
            for problem in table.load_problems():
                print(f"{GENERIC}: warning: {problem}", file=sys.stderr)
            return 0 if rest else 2
        try:
            entry = table.controller(rest[0])
        except ValueError as exc:
            print(f"{GENERIC}: error: {exc}", file=sys.stderr)
            return 2
        if entry.runs != BLOCK:
            print(f"{GENERIC}: error: controller {entry.name!r} does not run in a controller "
                  f"node (it runs {entry.runs}-wise)", file=sys.stderr)
            return 2
        del argv[1]
    # On SIGINT/SIGTERM, answer the inputs still queued (the last block's) before stopping.
    return node_main(node_spec(entry), "dva_controller.controller_node:ControllerNode", argv,
                     node_args=(entry.name,), drain=lambda node: node.taken(),
                     own_process=args is None)
