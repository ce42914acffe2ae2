"""The spectrum node's parameter table and its executable's entry (``ros2 run dva_controller
spectrum``): ``--help`` and refused arguments are answered from the table before ROS, numpy or
the node (:mod:`dva_controller.spectrum_node`) are imported (docs/performance.md, the
start-up budget). The spectra's shape rows are shared with a law of spectra
(:mod:`dva_controller.shared_params`).
"""
from __future__ import annotations

from dva_controller.shared_params import SPECTRUM_SHAPE
from dva_ros_common.node_params import (
    HOLD_PARAM,
    INPUT_HEALTH_PARAMS,
    NodeSpec,
    Param,
    node_main,
)

SPEC = NodeSpec(
    name="spectrum",
    package="dva_controller",
    summary="Sliding-window scaled magnitude spectra of the wing's accelerations (eq. 7.3 of "
            "Zhang (2006)): every hop, the last window of each channel at the chosen "
            "frequencies, each channel divided by its sum over the band.",
    params=(
        *SPECTRUM_SHAPE,
        Param("hop", 0.1, "time between window starts; a whole number of samples", "s",
              1.0e-3, 3600.0),
        Param("damper_state_required", False, "every block waits for the damper state "
              "stamped at its start however late it comes, so its c2 never depends on "
              "timing (run_flight and the replay set it); false: it waits about 1 s of wall "
              "time, and without any state the blocks go out with no c2"),
        *INPUT_HEALTH_PARAMS,
        HOLD_PARAM,
    ),
    topics="""
subscribes wing/acceleration (dva_msgs/AccelerationBlock)
subscribes dva/damper_state (dva_msgs/DamperState: c2 applied during the window)
publishes dva/spectrum (dva_msgs/ScaledSpectrum), /diagnostics
""",
)


def main(args=None) -> int:
    # On SIGINT/SIGTERM, analyse the blocks still queued before stopping.
    return node_main(SPEC, "dva_controller.spectrum_node:SpectrumNode", args,
                     drain=lambda node: node.counts["blocks"] + node.counts["damper_states"])
