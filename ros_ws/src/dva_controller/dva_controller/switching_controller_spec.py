"""The parameter tables of the per-sample laws' supervisor nodes (one per per-sample law of the
controller table) and the entry of their executables (``switching_controller``,
``clipped_optimal_controller``): ``--help`` and refused arguments are answered from the table
before ROS, numpy or the node (:mod:`dva_controller.switching_controller_node`) are imported
(docs/performance.md, the start-up budget).
"""
from __future__ import annotations

import sys
from pathlib import Path

from aero_dva.control import controllers as table
from aero_dva.control.controllers import SAMPLE, controller
from dva_controller.shared_params import param
from dva_ros_common.node_params import HOLD_PARAM, NodeSpec, node_main


def node_spec(entry) -> NodeSpec:
    """The supervisor node of the per-sample law ``entry``: its parameters, its topics."""
    return NodeSpec(
        name=entry.node,
        package="dva_controller",
        summary=entry.summary,
        params=(*(param(row) for row in entry.params), HOLD_PARAM),
        topics=f"""
publishes dva/damper_command (dva_msgs/DamperCommand, source "{entry.source}" or
  "{entry.sources[0]}"), /diagnostics (each fallback and its reason)
subscribes wing/displacement (burst detector), dva/damper_state (whether the damper runs the law)
""",
    )


#: The switching law's entry of the controller table and its node's parameters.
ENTRY = controller("switching")
SPEC = node_spec(ENTRY)


def main(args=None) -> int:
    """The supervisor of the per-sample law whose node this executable is."""
    argv = list(sys.argv if args is None else args)
    entry = table.by_node(Path(argv[0]).name)
    if entry is None or entry.runs != SAMPLE:
        print(f"{Path(argv[0]).name}: error: no per-sample law of the controller table has "
              f"this node; they are {', '.join(c.node for c in table.controllers((SAMPLE,)))}",
              file=sys.stderr)
        return 2
    return node_main(node_spec(entry), "dva_controller.switching_controller_node:Supervisor",
                     argv, node_args=(entry.name,), own_process=args is None)
