"""The recorder's parameter table and its executable's entry (``ros2 run aero_dva_sim
mcap_recorder``): ``--help`` and refused arguments are answered from the table before ROS or
the node (:mod:`aero_dva_sim.mcap_recorder_node`) are imported (docs/performance.md, the
start-up budget).
"""
from __future__ import annotations

from dva_ros_common.node_params import NodeSpec, Param, node_main

SPEC = NodeSpec(
    name="mcap_recorder",
    package="aero_dva_sim",
    summary="Record topics to a rosbag2-layout MCAP bag, like `ros2 bag record -s mcap`: "
            "topics are discovered while the node runs and recorded as serialized CDR, "
            "untouched, with their schemas and the QoS their publishers offer. On SIGINT or "
            "SIGTERM the bag is closed cleanly (MCAP footer and metadata.yaml).",
    params=(
        Param("output", "", "bag directory to create; it must not exist or be empty (nothing "
              "is overwritten)", default_text="bags/run_<UTC time>, or the first free _N"),
        Param("topics", [""], "record only these topics (resolved in the node's namespace)",
              default_text="[] (every topic)"),
        Param("exclude", [""], "never record these topics"),
        Param("discovery_period", 0.1, "wall time between looks for new topics", "s",
              1.0e-3, 60.0),
        Param("expect_flight_report", False, "on SIGINT/SIGTERM, take queued messages until "
              "the simulator's end-of-flight report has come too (at most 5 s), not only until "
              "none has come for 50 ms: a recorder starved of CPU can hold the flight's last "
              "block and report unread when it is stopped (run_flight sets it: its simulator "
              "always sends one)"),
        Param("flush_period", 1.0, "wall time between flushes of the MCAP chunk (bounds what a "
              "crash can lose)", "s", 1.0e-3, 3600.0),
        Param("max_message_bytes", 2**20, "larger messages are not recorded (counted and "
              "said once a second per topic): a message that large is none of the project's "
              "(a block of 20,000 samples is 480 KiB) and would make chunks past what the "
              "readers hold", "bytes", 1024, 8 * 2**20),
    ),
    topics="subscribes every matching topic (raw CDR); writes <output>/<name>_0.mcap and "
           "metadata.yaml",
)


def main(args=None) -> int:
    # On SIGINT/SIGTERM, record what is still queued before closing the bag: every message the
    # simulator counted, once its report is in.
    return node_main(SPEC, "aero_dva_sim.mcap_recorder_node:McapRecorder", args,
                     drain=lambda node: node.received, complete=lambda node: node.complete())
