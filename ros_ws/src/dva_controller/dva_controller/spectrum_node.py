"""``spectrum``: sliding-window scaled magnitude spectra of the wing's accelerations (eq. 7.3).

Every ``hop`` seconds of samples, the last ``window_duration`` seconds of each channel are
analysed at ``frequencies`` (:class:`~aero_dva.control.spectrum.SlidingSpectrum`) and published
as one ``dva_msgs/ScaledSpectrum`` whose stamp is the time of the window's last sample (from the
block header stamps, so sim time when the simulator stamps its blocks with it).

A gap or an out-of-order block (``first_sample_index`` not where the previous block ended), a
block with NaN/inf samples, or a change of ``sample_rate`` drops the window collected so far
and starts a new one; each reset is reported on ``/diagnostics`` (WARN) with its reason and the
sample indices. A window whose band holds no signal (scaling by a zero sum) is not published.

Its parameters (units, defaults, ranges) are the table ``SPEC`` below, which the node declares
them from and ``spectrum --help`` prints; the spectra's shape rows are shared with the RBF
controller (:mod:`dva_controller.shared_params`).

Subscribes ``wing/acceleration`` (dva_msgs/AccelerationBlock) and ``dva/damper_state``
(dva_msgs/DamperState, for the c2 applied during the window: the spectrum's ``damping`` is the
mean of the latest applied c2 known when each block arrived, or the latest known value if a
block of the window arrived before any damper state). Publishes ``dva/spectrum``
(dva_msgs/ScaledSpectrum) and ``/diagnostics``. All times honour ``use_sim_time``.
"""
from __future__ import annotations

import math
import sys

import numpy as np
from rclpy.node import Node

from aero_dva.control.spectrum import SlidingSpectrum
from dva_controller import messages
from dva_controller.shared_params import SPECTRUM_SHAPE, checked_channels, checked_frequencies
from dva_msgs.msg import AccelerationBlock, DamperState, ScaledSpectrum
from dva_ros_common import conversions
from dva_ros_common.node_params import NodeSpec, Param, declare_parameters
from dva_ros_common.node_tools import INPUT_HEALTH_PARAMS, InputHealth, Status, run_node

QOS_DEPTH = 100  # blocks of 10-50 ms: a few seconds of slack at 20x real time before a gap

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
        *INPUT_HEALTH_PARAMS,
    ),
    topics="""
subscribes wing/acceleration (dva_msgs/AccelerationBlock)
subscribes dva/damper_state (dva_msgs/DamperState: c2 applied during the window)
publishes dva/spectrum (dva_msgs/ScaledSpectrum), /diagnostics
""",
)


class SpectrumNode(Node):
    """Turn acceleration blocks into eq. 7.3 spectra over sliding windows."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        self.channels = checked_channels(values["channels"])
        self.frequencies = checked_frequencies(values["frequencies"])
        self.window = str(values["window"])
        self.window_duration = float(values["window_duration"])
        self.hop = float(values["hop"])

        self._sliding: SlidingSpectrum | None = None
        self._problem: str | None = None  # a persistent input problem for the status
        self._damping = math.nan  # latest applied c2 [N s/m]
        self.counts = dict.fromkeys(
            ("blocks", "rejected", "resets", "spectra", "empty_windows", "damper_states"), 0
        )
        self._health = InputHealth(self, "window", "wing/acceleration", self.counts, self._status)

        self._spectrum_pub = self.create_publisher(ScaledSpectrum, "dva/spectrum", 10)
        self.create_subscription(AccelerationBlock, "wing/acceleration", self._on_block, QOS_DEPTH)
        self.create_subscription(DamperState, "dva/damper_state", self._on_damper_state, 10)
        self.get_logger().info(
            f"spectra of {list(self.channels)} at {self.frequencies.size} frequencies "
            f"({self.frequencies.min():g}..{self.frequencies.max():g} Hz), "
            f"{self.window} window of {self.window_duration:g} s every {self.hop:g} s"
        )

    @property
    def latest_damping(self) -> float:
        """[N s/m] latest applied c2 from ``dva/damper_state`` (NaN before the first)."""
        return self._damping

    # ------------------------------------------------------------------ callbacks
    def _on_damper_state(self, msg: DamperState) -> None:
        value = messages.applied_damping(msg)
        if math.isfinite(value) and value >= 0.0:
            self._damping = value
            self.counts["damper_states"] += 1

    def _on_block(self, msg: AccelerationBlock) -> None:
        self.counts["blocks"] += 1
        self._health.mark_input()
        index = int(msg.first_sample_index)
        try:
            block = messages.acceleration_samples(msg, self.channels)
        except ValueError as exc:
            self._reject("malformed", f"block at index {index} rejected: {exc}", index=index)
            return
        rate = block.sample_rate
        if not (math.isfinite(rate) and rate > 0.0):
            self._reject(
                "bad_sample_rate",
                f"block at index {index} rejected: sample_rate {rate} Hz",
                index=index,
            )
            return
        if self._sliding is None or rate != self._sliding.sample_rate:
            if not self._start_window(rate, index):
                return
        result = self._sliding.push(index, block.samples, damping=self._damping)
        if result.reset is not None:
            event = result.reset
            self.counts["resets"] += 1
            self._health.report(
                conversions.WARN,
                f"reset_{event.reason.value}",
                event.describe(),
                reason=event.reason.value,
                expected_index=event.expected_index,
                received_index=event.received_index,
                dropped_samples=event.dropped_samples,
            )
        for window in result.spectra:
            self._publish(block, window)

    def _start_window(self, rate: float, index: int) -> bool:
        """(Re)build the sliding window for a sample rate; report why. False: block rejected."""
        old = self._sliding
        self._sliding = None
        if old is not None:
            expected = old.expected_index
            dropped = old.reset().dropped_samples
            self.counts["resets"] += 1
            self._health.report(
                conversions.WARN,
                "reset_sample_rate",
                f"spectrum window reset: sample rate changed from {old.sample_rate:g} to "
                f"{rate:g} Hz at index {index} (expected index {expected}); "
                f"{dropped} samples discarded",
                reason="sample_rate",
                previous_sample_rate=old.sample_rate,
                sample_rate=rate,
                expected_index=expected,
                received_index=index,
                dropped_samples=dropped,
            )
        try:
            self._sliding = SlidingSpectrum(
                len(self.channels),
                rate,
                window_duration=self.window_duration,
                hop=self.hop,
                frequencies=self.frequencies,
                window=self.window,
            )
        except (TypeError, ValueError) as exc:
            self._problem = f"blocks at {rate:g} Hz cannot be analysed with the parameters: {exc}"
            self._reject(
                "unusable_sample_rate",
                self._problem,
                level=conversions.ERROR,
                index=index,
                sample_rate=rate,
            )
            return False
        self._problem = None
        return True

    def _publish(self, block: messages.AccelerationSamples, window) -> None:
        spectrum = window.spectrum
        if not np.all(np.isfinite(spectrum.magnitudes)):
            empty = [c for c, s in zip(self.channels, spectrum.band_sums) if not s > 0.0]
            self.counts["empty_windows"] += 1
            self._health.report(
                conversions.WARN,
                "empty_window",
                f"window {window.first_sample_index}..{window.stop_sample_index - 1} not "
                f"published: no signal in the band on {empty}",
                first_index=window.first_sample_index,
            )
            return
        damping = window.mean_damping
        if not math.isfinite(damping):
            damping = self._damping
        stamp = conversions.ns_to_time(block.sample_time_ns(window.stop_sample_index - 1))
        self._spectrum_pub.publish(
            messages.scaled_spectrum_message(
                stamp, block.frame_id, self.channels, spectrum, self._sliding.hop, damping
            )
        )
        self.counts["spectra"] += 1

    # ------------------------------------------------------------------ diagnostics
    def _reject(self, event: str, text: str, level: int = conversions.WARN, **values) -> None:
        self.counts["rejected"] += 1
        self._health.report(level, event, text, **values)

    def _status(self) -> Status:
        values = {"damping": self._damping}
        if self._sliding is not None:
            values.update(sample_rate=self._sliding.sample_rate,
                          expected_index=self._sliding.expected_index)
        if self._problem is not None:
            return conversions.ERROR, self._problem, values
        return conversions.OK, f"{self.counts['spectra']} spectra published", values


def main(args=None) -> int:
    return run_node(SpectrumNode, SPEC, args)


if __name__ == "__main__":
    sys.exit(main())
