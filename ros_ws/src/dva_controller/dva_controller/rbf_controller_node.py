"""``rbf_controller``: c2 from the scaled vibration spectra with an RBF network (study sec. 7.2).

For each ``dva/spectrum`` message the network's input is the scaled magnitudes, channel-major,
followed by the current c2 (the spectrum's ``damping`` field, the c2 applied during the
window); ``network.predict`` of it, clamped to ``[damping_min, damping_max]``, is published as
``dva/damper_command`` (source "rbf_network").

The network file (.npz, :func:`aero_dva.control.rbf_io.load_rbf_network`, no pickle) is checked
at start-up: its input dimension must be ``len(channels) * len(frequencies) + 1`` and its input
names and units those of :func:`aero_dva.control.rbf_network.spectrum_input_names` for the
``channels`` and ``frequencies`` parameters. A missing, corrupt or mismatched file stops the
node with a one-line error naming the file (exit code 2).

Each spectrum is checked against what the network was trained on: channel names and order,
frequencies, scaling "band_sum", window function and window duration. A spectrum that does not
match, or holds NaN/inf magnitudes or a missing/negative c2, gives no command and is reported on
``/diagnostics``.

Its parameters (units, defaults, ranges) are the table ``SPEC`` below, which the node declares
them from and ``rbf_controller --help`` prints; the spectra's shape rows are the spectrum
node's own (:mod:`dva_controller.shared_params`).

Subscribes ``dva/spectrum`` (dva_msgs/ScaledSpectrum); publishes ``dva/damper_command``
(dva_msgs/DamperCommand) and ``/diagnostics``. A command carries the stamp of the spectrum it
was computed from (the time of the window's last sample; the DamperCommand convention).
"""
from __future__ import annotations

import math
import sys

import numpy as np
from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva.control.command_laws import RBFLaw
from aero_dva.control.rbf_io import load_rbf_network
from aero_dva.control.rbf_network import RBFNetwork, spectrum_input_names
from dva_controller.shared_params import (
    DAMPER_RANGE,
    SPECTRUM_SHAPE,
    damping_range,
    spectrum_shape,
)
from dva_msgs.msg import DamperCommand, ScaledSpectrum
from dva_ros_common import conversions
from dva_ros_common.held_publisher import HOLD_PARAM, HeldPublisher
from dva_ros_common.node_params import NodeSpec, Param, declare_parameters
from dva_ros_common.node_tools import INPUT_HEALTH_PARAMS, InputHealth, Status, run_node

FREQUENCY_TOLERANCE = 1.0e-6  # [Hz] spectrum frequencies must match the training ones this well
DURATION_TOLERANCE = 1.0e-6  # [s]
#: Hidden activations below this everywhere mean the input is far from every training centre.
FAR_ACTIVATION = 1.0e-3

SPEC = NodeSpec(
    name="rbf_controller",
    package="dva_controller",
    summary="Command c2 from each scaled vibration spectrum with a trained RBF network (section "
            "7.2 of Zhang (2006)). The spectra's shape below must be the one the network was "
            "trained on (the file's input names are checked at start-up); commands are clamped "
            "to the damper's range.",
    params=(
        Param("network_file", "", "trained RBF network (.npz, dva train rbf); required",
              default_text="none (required)"),
        *SPECTRUM_SHAPE,
        *DAMPER_RANGE,
        *INPUT_HEALTH_PARAMS,
        HOLD_PARAM,
    ),
    topics="""
subscribes dva/spectrum (dva_msgs/ScaledSpectrum)
publishes dva/damper_command (dva_msgs/DamperCommand, source "rbf_network"), /diagnostics
""",
)


def check_network_inputs(
    network: RBFNetwork, path: str, channels: tuple[str, ...], frequencies: np.ndarray
) -> None:
    """Raise ValueError unless the network's inputs are the spectrum inputs of the parameters."""
    names, units = spectrum_input_names(channels, frequencies)
    if network.input_names != names:
        diff = [(i, a, b) for i, (a, b) in enumerate(zip(network.input_names, names)) if a != b]
        i, got, want = diff[0]
        raise ValueError(
            f"RBF network file {path!r}: input {i} is {got!r} but channels {list(channels)} "
            f"and frequencies {frequencies.tolist()} Hz give {want!r} "
            f"({len(diff)} of {len(names)} input names differ)"
        )
    if network.input_units != units:
        raise ValueError(
            f"RBF network file {path!r}: input units {list(network.input_units)} are not "
            f"{list(units)}"
        )


class RBFController(Node):
    """Command c2 from each scaled spectrum with a trained RBF network."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        self.channels, self.frequencies, self.window, self.window_duration = \
            spectrum_shape(values)
        low, high = damping_range(float(values["damping_min"]), float(values["damping_max"]))
        self.damping_range = (low, high)
        path = str(values["network_file"])
        if not path:
            raise ValueError("parameter 'network_file' is required (a trained RBF network .npz)")
        dim = len(self.channels) * self.frequencies.size + 1
        self.network = load_rbf_network(path, expected_input_dim=dim)  # RBFFileError names it
        check_network_inputs(self.network, path, self.channels, self.frequencies)
        self.law = RBFLaw(self.network, self.damping_range)

        self.counts = dict.fromkeys(("spectra", "rejected", "commands", "far_inputs"), 0)
        self.last_command = math.nan
        self.last_activation = math.nan
        self._health = InputHealth(self, "rbf network", ch.SPECTRUM.name, self.counts,
                                   self._status)

        self._command_pub = HeldPublisher(
            self, DamperCommand, ch.DAMPER_COMMAND.name, values["hold_until_subscribers"])
        self.create_subscription(ScaledSpectrum, ch.SPECTRUM.name, self._on_spectrum, 10)
        self.get_logger().info(
            f"RBF network {path}: {self.network.n_neurons} neurons, {dim} inputs "
            f"({list(self.channels)} x {self.frequencies.size} frequencies + c2); "
            f"commands clamped to [{low:g}, {high:g}] N s/m"
        )

    def mismatch(self, spectrum: conversions.SpectrumInput) -> str | None:
        """Why a spectrum is not an input of this network (None if it is)."""
        if spectrum.channel_names != self.channels:
            return f"channels {list(spectrum.channel_names)}, network has {list(self.channels)}"
        freqs = spectrum.frequencies
        if freqs.shape != self.frequencies.shape or not np.allclose(
            freqs, self.frequencies, rtol=0.0, atol=FREQUENCY_TOLERANCE
        ):
            return (
                f"{freqs.size} frequencies {freqs.tolist()} Hz, network has "
                f"{self.frequencies.size} ({self.frequencies.tolist()} Hz)"
            )
        if spectrum.scaling != ScaledSpectrum.SCALING_BAND_SUM:
            wanted = ScaledSpectrum.SCALING_BAND_SUM
            return f"scaling {spectrum.scaling!r}, network needs {wanted!r}"
        if spectrum.window_function != self.window:
            return f"window {spectrum.window_function!r}, network has {self.window!r}"
        if abs(spectrum.window_duration - self.window_duration) > DURATION_TOLERANCE:
            return (
                f"window duration {spectrum.window_duration:g} s, network has "
                f"{self.window_duration:g} s"
            )
        if not np.all(np.isfinite(spectrum.magnitudes)):
            return "magnitudes hold NaN or inf"
        if not (math.isfinite(spectrum.damping) and spectrum.damping >= 0.0):
            return f"current c2 (damping) is {spectrum.damping}, not a finite value >= 0"
        return None

    def command_for(self, spectrum: conversions.SpectrumInput) -> tuple[float, float]:
        """Clamped network output [N s/m] and the largest hidden activation for a spectrum."""
        return self.law.command(spectrum.magnitudes, spectrum.damping)

    def _on_spectrum(self, msg: ScaledSpectrum) -> None:
        self.counts["spectra"] += 1
        self._health.mark_input()
        try:
            spectrum = conversions.spectrum_input(msg)
            problem = self.mismatch(spectrum)
        except ValueError as exc:
            spectrum, problem = None, str(exc)
        if problem is None:
            c2, activation = self.command_for(spectrum)
            if not math.isfinite(c2):
                problem = f"the network's output is {c2}"
        if problem is not None:
            self.counts["rejected"] += 1
            self._health.report(conversions.WARN, "rejected_spectrum",
                                f"spectrum ignored: {problem}")
            return
        self.last_activation = activation
        if activation < FAR_ACTIVATION:
            self.counts["far_inputs"] += 1
        stamp_ns = spectrum.stamp_ns
        self._command_pub.publish(
            conversions.damper_command(
                conversions.ns_to_time(stamp_ns), c2, DamperCommand.SOURCE_RBF_NETWORK
            )
        )
        self.last_command = c2
        self.counts["commands"] += 1

    def _status(self) -> Status:
        values = {"last_command": self.last_command, "largest_activation": self.last_activation}
        if self.last_activation < FAR_ACTIVATION:
            text = (
                f"last input is far from every training centre (largest activation "
                f"{self.last_activation:.2g}): the output is close to the bias"
            )
            return conversions.WARN, text, values
        return conversions.OK, f"last command {self.last_command:.6g} N s/m", values


def main(args=None) -> int:
    return run_node(RBFController, SPEC, args)


if __name__ == "__main__":
    sys.exit(main())
