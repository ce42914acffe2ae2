"""``spectrum``: sliding-window scaled magnitude spectra of the wing's accelerations (eq. 7.3).

Every ``hop`` seconds of samples, the last ``window_duration`` seconds of each channel are
analysed at ``frequencies`` (:class:`~aero_dva.control.spectrum.SlidingSpectrum`) and published
as one ``dva_msgs/ScaledSpectrum`` whose stamp is the time of the window's last sample (from the
block header stamps, so sim time when the simulator stamps its blocks with it).

A gap or an out-of-order block (``first_sample_index`` not where the previous block ended), a
block with NaN/inf samples, or a change of ``sample_rate`` drops the window collected so far
and starts a new one; each reset is reported on ``/diagnostics`` (WARN) with its reason and the
sample indices. A window whose band holds no signal (scaling by a zero sum) is not published.

Its parameters (units, defaults, ranges) are the table ``SPEC`` of
:mod:`dva_controller.spectrum_spec`, which the node declares them from and ``spectrum --help``
prints; the spectra's shape rows are shared with the RBF controller
(:mod:`dva_controller.shared_params`).

Subscribes ``wing/acceleration`` (dva_msgs/AccelerationBlock) and ``dva/damper_state``
(dva_msgs/DamperState, for the c2 applied during the window: the spectrum's ``damping`` is the
mean over the window's blocks of the applied c2 of the latest state stamped at or before each
block's start, chosen by stamp so that a re-run on a recorded bag gives the same value; a block
that arrives before its state waits for it: for as long as it takes with
``damper_state_required`` (``run_flight`` and the replay set it: their states are sure to come,
and the c2 then never depends on timing), else at most about ``STATE_WAIT`` s of wall time; see
:mod:`aero_dva.control.spectrum_stream`, which does the node's work without ROS). Publishes
``dva/spectrum`` (dva_msgs/ScaledSpectrum) and ``/diagnostics``. All times honour ``use_sim_time``.
"""
from __future__ import annotations

import sys

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from aero_dva.bag import channels as ch
from aero_dva.control.command_laws import spectrum_shape
from aero_dva.control.spectrum_stream import SpectrumStream
from dva_controller.spectrum_spec import SPEC, main
from dva_msgs.msg import AccelerationBlock, DamperState, ScaledSpectrum
from dva_ros_common import conversions
from dva_ros_common.held_publisher import HeldPublisher
from dva_ros_common.node_params import DATA_DEPTH, declare_parameters
from dva_ros_common.node_tools import InputHealth, Status

# Reader depth: a starved node must not lose blocks from its own queue (KEEP_LAST overwrites the
# oldest): the writers' depth, 5 s of blocks at 10x real time.
QOS_DEPTH = DATA_DEPTH
STATE_WAIT = 1.0  # [s] wall time a block waits for its damper state (1-2 ticks) before it is
# analysed with the last known c2: long for a busy executor, short for a stalled state topic


class SpectrumNode(Node):
    """Turn acceleration blocks into eq. 7.3 spectra over sliding windows."""

    def __init__(self, **kwargs) -> None:
        super().__init__(SPEC.name, **kwargs)
        values = declare_parameters(self, SPEC)
        self.channels, self.frequencies, self.window, self.window_duration = \
            spectrum_shape(values)
        self.hop = float(values["hop"])

        self._stream = SpectrumStream(
            self.channels, self.window_duration, self.hop, self.frequencies, self.window,
            states_required=bool(values["damper_state_required"]))
        self.counts = self._stream.counts
        self._health = InputHealth(self, "window", ch.ACCELERATION.name, self.counts, self._status)

        self._spectrum_pub = HeldPublisher(
            self, ScaledSpectrum, ch.SPECTRUM.name, values["hold_until_subscribers"])
        self.create_subscription(AccelerationBlock, ch.ACCELERATION.name, self._on_block,
                                 QOS_DEPTH)
        self.create_subscription(DamperState, ch.DAMPER_STATE.name, self._on_damper_state,
                                 QOS_DEPTH)
        self._held_at_last_tick: int | None = None
        self._frame_id = ""
        self.create_timer(STATE_WAIT, self._release_stalled,  # wall time, also under sim time
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"spectra of {list(self.channels)} at {self.frequencies.size} frequencies "
            f"({self.frequencies.min():g}..{self.frequencies.max():g} Hz), "
            f"{self.window} window of {self.window_duration:g} s every {self.hop:g} s"
        )

    @property
    def latest_damping(self) -> float:
        """[N s/m] applied c2 of the newest ``dva/damper_state`` (NaN before the first)."""
        return self._stream.latest_damping

    # ------------------------------------------------------------------ callbacks
    def _on_damper_state(self, msg: DamperState) -> None:
        self._stream.damper_state(conversions.time_to_ns(msg.header.stamp),
                                  conversions.applied_damping(msg))
        self._publish(*self._stream.release())

    def _release_stalled(self) -> None:
        """Analyse blocks that waited a whole tick for their damper state (not when the
        states are required: they are then sure to come)."""
        if self._stream.states_required:
            return
        oldest = self._stream.oldest_held_stamp
        if oldest is not None and oldest == self._held_at_last_tick:
            self._publish(*self._stream.release(force=True))
            oldest = self._stream.oldest_held_stamp
        self._held_at_last_tick = oldest

    def _on_block(self, msg: AccelerationBlock) -> None:
        self._health.mark_input()
        try:
            block = conversions.acceleration_samples(msg, self.channels)
        except ValueError as exc:
            index = int(msg.first_sample_index)
            self.counts["blocks"] += 1
            self.counts["rejected"] += 1
            self._health.report(conversions.WARN, "malformed",
                                f"block at index {index} rejected: {exc}", index=index)
            return
        self._frame_id = block.frame_id
        self._publish(*self._stream.block(block.stamp_ns, block.first_sample_index,
                                          block.sample_rate, block.samples))

    def _publish(self, spectra, events) -> None:
        for event in events:
            level = conversions.ERROR if event.level == "error" else conversions.WARN
            self._health.report(level, event.event, event.text, **event.values)
        for item in spectra:
            self._spectrum_pub.publish(conversions.scaled_spectrum_message(
                conversions.ns_to_time(item.stamp_ns), self._frame_id, self.channels,
                item.spectrum, item.hop, item.damping))

    # ------------------------------------------------------------------ diagnostics
    def _status(self) -> Status:
        values = {"damping": self.latest_damping}
        sliding = self._stream.sliding
        if sliding is not None:
            values.update(sample_rate=sliding.sample_rate, expected_index=sliding.expected_index)
        if self._stream.problem is not None:
            return conversions.ERROR, self._stream.problem, values
        return conversions.OK, f"{self.counts['spectra']} spectra published", values


if __name__ == "__main__":
    sys.exit(main())
