"""The topics of the node graph: names and message types, in one place for every user.

The simulator, controllers and recorder (ROS nodes), the batch recorder, the flight-log
reader and the ``dva`` tools all take topic names and types from here. A name without a
leading "/" is relative: in the graph it lands under the node's namespace (``"wing1"`` ->
``/wing1/wing/acceleration``); a bag stores it absolute (:func:`absolute`). Also here: the
diagnostics conventions the simulator and the batch recorder share. Pure constants: no
imports beyond the standard library.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "ACCELERATION",
    "CLOCK",
    "DAMPER_BLOCK",
    "DAMPER_COMMAND",
    "DAMPER_STATE",
    "DIAGNOSTICS",
    "DIAGNOSTIC_LEVELS",
    "DISPLACEMENT",
    "EXCITATION",
    "FLIGHT_CONDITION",
    "FLIGHT_DIAGNOSTIC_NAME",
    "LAW_INPUTS",
    "RECORDED",
    "RECORDED_NAME",
    "SIMULATOR_BLOCK",
    "SIMULATOR_HARDWARE_ID",
    "SPECTRUM",
    "WING_FRAME",
    "Channel",
    "absolute",
    "diagnostic_text",
]


@dataclass(frozen=True)
class Channel:
    """A topic: ``name`` as the nodes use it (relative unless it starts with "/") and its
    message ``type_name`` (``pkg/msg/Type``)."""

    name: str
    type_name: str

    def absolute(self, namespace: str = "") -> str:
        """The fully qualified name under ``namespace`` (as a bag records it)."""
        return absolute(self.name, namespace)


CLOCK = Channel("/clock", "rosgraph_msgs/msg/Clock")
ACCELERATION = Channel("wing/acceleration", "dva_msgs/msg/AccelerationBlock")
DISPLACEMENT = Channel("wing/displacement", "dva_msgs/msg/DisplacementBlock")
EXCITATION = Channel("wing/excitation", "dva_msgs/msg/ForceBlock")
FLIGHT_CONDITION = Channel("flight/condition", "dva_msgs/msg/FlightCondition")
DAMPER_STATE = Channel("dva/damper_state", "dva_msgs/msg/DamperState")
DAMPER_COMMAND = Channel("dva/damper_command", "dva_msgs/msg/DamperCommand")
SPECTRUM = Channel("dva/spectrum", "dva_msgs/msg/ScaledSpectrum")
#: A per-sample law's damper, sample by sample, beside each block it flew (not every block).
DAMPER_BLOCK = Channel("dva/damper_block", "dva_msgs/msg/DamperBlock")
DIAGNOSTICS = Channel("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")
#: A recorder's word that it holds every message a flight report counts (not recorded): the
#: simulator exits on it rather than on DDS acknowledgements, which wait for a heartbeat.
RECORDED = Channel("dva/recorded", "diagnostic_msgs/msg/DiagnosticArray")

#: The topic of each input a control law reads (aero_dva.control.controllers: CONDITION, ...).
LAW_INPUTS = {"condition": FLIGHT_CONDITION, "spectrum": SPECTRUM, "displacement": DISPLACEMENT,
              "damper_state": DAMPER_STATE, "acceleration": ACCELERATION}

#: What the simulator publishes per block of samples, in its publish order.
SIMULATOR_BLOCK = (CLOCK, ACCELERATION, DISPLACEMENT, EXCITATION, FLIGHT_CONDITION,
                   DAMPER_STATE)

#: ``header.frame_id`` of the wing's acceleration and displacement blocks (others leave it "").
WING_FRAME = "wing"
#: ``diagnostic_msgs/DiagnosticStatus`` levels by name.
DIAGNOSTIC_LEVELS = {"ok": 0, "warn": 1, "error": 2, "stale": 3}
#: Name and hardware_id of the simulator's "flight completed / diverged" status.
FLIGHT_DIAGNOSTIC_NAME = "simulator: flight"
SIMULATOR_HARDWARE_ID = "aero_dva_sim"
#: Name of the status on :data:`RECORDED` (its hardware_id: the recorder's node; its stamp: the
#: flight report's).
RECORDED_NAME = "mcap_recorder: flight recorded"


def absolute(name: str, namespace: str = "") -> str:
    """``name`` resolved under ``namespace`` ("" = none), as a bag records it."""
    if not isinstance(namespace, str):
        raise TypeError(f"namespace must be a string, got {type(namespace).__name__}")
    if name.startswith("/"):
        return name
    prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
    return f"{prefix}/{name}"


def diagnostic_text(value) -> str:
    """A diagnostic key-value's text: floats as ``%.9g`` ("nan" for NaN), others ``str``."""
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.9g}"
    return str(value)
