"""The bag player's parameter table and its executable's entry (``ros2 run aero_dva_sim
bag_player``): ``--help`` and refused arguments are answered from the table before ROS, numpy
or the node (:mod:`aero_dva_sim.bag_player_node`) are imported (docs/performance.md, the
start-up budget).
"""
from __future__ import annotations

from dva_ros_common.node_params import DATA_DEPTH, NodeSpec, Param, node_main

ACK_TIMEOUT = 4.0  # [s] at the end: longest wait for the acknowledgements (ack_timeout)

SPEC = NodeSpec(
    name="bag_player",
    package="aero_dva_sim",
    summary="Publish a recorded bag (rosbag2-layout MCAP, one file or split) into the graph: "
            "the recorded CDR bytes in log-time order, with the recorded timing scaled by "
            "rate, each topic with the QoS recorded in metadata.yaml, /clock from the log "
            "times. Remap topics with --ros-args -r /bag/topic:=/new/topic. A damaged bag "
            "plays every chunk whose CRC holds, with a warning, and exits 1. Reports on "
            "/diagnostics when it ends.",
    params=(
        Param("bag", "", "bag directory (or one .mcap file) to play; required",
              default_text="none (required)"),
        Param("rate", 1.0, "speed relative to the recording (1: recorded timing; 0: as fast "
              "as the player can publish, lossless only for subscribers with deep enough "
              "queues)", "", 0.0, 1.0e6),
        Param("topics", [""], "play only these topics (bag names, with or without the "
              "leading /)", default_text="[] (every topic)"),
        Param("start_offset", 0.0, "skip this much of the bag's start (log time)", "s",
              0.0, 1.0e9),
        Param("duration", 0.0, "play this much log time from start_offset (0: to the end)",
              "s", 0.0, 1.0e9),
        Param("loop", False, "play again from start_offset when the end is reached"),
        Param("clock", True, "publish /clock from the log times (the bag's own /clock is then "
              "not played)"),
        Param("wait_for_subscribers", 0, "before the first message, wait until every played "
              "topic has this many subscribers", "", 0, 1000),
        Param("wait_for_nodes", [""], "... and these nodes are in the graph with all their "
              "subscriptions to played topics matched"),
        Param("wait_for_topics", [""], "... and these topics, not played, have a publisher and "
              "N subscribers in the graph (TOPIC or TOPIC:N, N default 1), e.g. the links "
              "between the nodes the bag is replayed into"),
        Param("wait_timeout", 30.0, "wall time after which playing starts anyway (with a "
              "warning), or fails (wait_timeout_fails)", "s", 0.0, 1.0e6),
        Param("wait_timeout_fails", False, "fail (exit code 3, nothing played) when the graph "
              "is not complete after wait_timeout, instead of playing anyway"),
        Param("delay", 0.5, "wall time from the end of the wait to the first message: DDS "
              "matches the two ends of a topic separately, and a subscriber that has not yet "
              "matched the player drops what it is sent", "s", 0.0, 3600.0),
        Param("qos_depth", DATA_DEPTH, "keep-last depth of a played topic's writer, at least "
              "(a transient-local topic keeps its recorded depth, what a late subscriber gets)",
              "", 1, 100000),
        Param("exit_on_end", True, "stop the node when the bag has been played"),
        Param("ack_timeout", ACK_TIMEOUT, "at the end, wall time the player waits at most for "
              "its subscribers to acknowledge every message (it is gone after, and a "
              "subscriber starved until then loses what it had not acknowledged); "
              "replay_flight sets it long", "s", 0.0, 1.0e6),
    ),
    topics="""
publishes every played topic of the bag (remappable), /clock, /diagnostics (once, at the end)
""",
)


def main(args=None) -> int:
    return node_main(SPEC, "aero_dva_sim.bag_player_node:BagPlayer", args)
