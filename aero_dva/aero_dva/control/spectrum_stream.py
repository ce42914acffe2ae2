"""The spectrum node's work without ROS: acceleration blocks and damper states in, eq. 7.3
spectra out, with the same stamps, windows and c2 whether it runs in the node or on a bag.

:class:`SpectrumStream` holds a :class:`~aero_dva.control.spectrum.SlidingSpectrum` per sample
rate and the damper states seen so far. The c2 a block came with is the applied c2 of the
latest damper state stamped at or before the block's first sample (half a sample of slack for
rounding), chosen by stamp rather than by arrival: the simulator's state after block k-1 is
stamped with block k's start, so this is the c2 in force when block k began.

DDS does not order two topics against each other: a replay at 10x on a busy machine can hand
over block k before the state stamped at its start, and a state that a starved reader missed
comes again only at the writer's next heartbeat, seconds later. A block that arrives before
any state stamped at or after its start is therefore held (with the blocks behind it) until
such a state arrives (:meth:`SpectrumStream.release`). With ``states_required`` (the graphs the
project starts, whose damper states are sure to come) that is the only way out: the c2 of
every spectrum is then the same whatever the interleaving and the load, and a re-run on a
recorded bag (``dva replay``, the bag player into a fresh node) gives the recorded spectra
exactly. Without it (a source that may have no states, such as a replayed measurement) the
stream gives up waiting: before the first state after :data:`FIRST_STATE_BLOCKS` blocks (states
count as absent), and when the caller forces it (``release(force=True)``: the node does after
about a second of wall time); then the c2 does depend on timing (three blocks ahead of the
first state change the first spectra's c2: ``tests/unit/aero_dva/control/
test_spectrum_stream.py``).

A spectrum is stamped with the time of its window's last sample, computed from the header
stamp of the block that completed it; its ``damping`` is the mean c2 over the window's blocks,
or the completing block's c2 when some block of the window had none.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

from aero_dva.control.spectrum import ScaledSpectrum, SlidingSpectrum

__all__ = ["SpectrumStream", "StreamEvent", "StreamSpectrum"]

_NS = 1_000_000_000
MAX_HELD_BLOCKS = 200  # a stalled damper-state topic costs at most this many blocks of memory
#: ... when the states are required: the blocks of minutes at 10x real time (about 25 MB of
#: 50-sample blocks), far beyond a heartbeat's resend; more means the states stopped for good.
MAX_HELD_REQUIRED = 20_000
FIRST_STATE_BLOCKS = 2  # blocks held for the first damper state before states count as absent


@dataclass(frozen=True)
class StreamSpectrum:
    """One spectrum to publish.

    Attributes
    ----------
    stamp_ns : int
        [ns] time of the window's last sample.
    spectrum : ScaledSpectrum
    hop : float
        [s] time between window starts.
    damping : float
        [N s/m] c2 applied during the window (see module docstring); NaN if none known.
    first_sample_index, stop_sample_index : int
        Stream indices of the window's first sample and one past its last.
    """

    stamp_ns: int
    spectrum: ScaledSpectrum
    hop: float
    damping: float
    first_sample_index: int
    stop_sample_index: int


@dataclass(frozen=True)
class StreamEvent:
    """Something to report: a reset, a rejected block, an empty window.

    ``event`` names its kind (e.g. ``reset_gap``, ``bad_sample_rate``), ``level`` is "warn"
    or "error", ``values`` are key/values for the diagnostics."""

    event: str
    text: str
    level: str = "warn"
    values: dict = field(default_factory=dict)


class SpectrumStream:
    """Streaming eq. 7.3 spectra of acceleration blocks, with the c2 each window had.

    Parameters
    ----------
    channels : sequence of str
        Names of the blocks' channels, in order (for the messages and reports).
    window_duration, hop : float
        [s] window length and time between window starts.
    frequencies : array_like
        [Hz] frequencies to evaluate.
    window : str
        Window function ("rectangular" or "hann").
    states_required : bool
        Damper states are sure to come: a block waits for its state however late it arrives
        (see the module docstring), never given up by count or by time.
    """

    def __init__(self, channels, window_duration: float, hop: float, frequencies,
                 window: str, *, states_required: bool = False) -> None:
        self.states_required = bool(states_required)
        self.channels = tuple(channels)
        self.window_duration = float(window_duration)
        self.hop = float(hop)
        self.frequencies = np.asarray(frequencies, dtype=float)
        self.window = window
        self.sliding: SlidingSpectrum | None = None
        self.problem: str | None = None  # a persistent input problem (unusable sample rate)
        self._state_stamps: list[int] = []  # [ns] damper states by stamp, ascending
        self._state_values: list[float] = []  # [N s/m] their applied c2
        self._held: list[tuple] = []  # blocks waiting for their damper state, in arrival order
        self._states_absent = False  # blocks came and no damper state: do not wait for one
        self._ready: tuple[list, list] = ([], [])  # analysed, not yet handed out by release
        self.counts = dict.fromkeys(
            ("blocks", "rejected", "resets", "spectra", "empty_windows", "damper_states"), 0)

    @property
    def latest_damping(self) -> float:
        """[N s/m] applied c2 of the newest damper state (NaN before the first)."""
        return self._state_values[-1] if self._state_values else math.nan

    def damper_state(self, stamp_ns: int, applied: float) -> bool:
        """Note a damper state (stamp [ns], applied c2 [N s/m]); False if it is not usable."""
        if not (math.isfinite(applied) and applied >= 0.0):
            return False
        if self._state_stamps and stamp_ns < self._state_stamps[-1]:
            # time went back (a new run, a replay loop): start over; blocks still held belong
            # to the old run: analyse them now with its states, out at the next release
            self._ready = self.release(force=True)
            self._state_stamps.clear()
            self._state_values.clear()
        self._state_stamps.append(int(stamp_ns))
        self._state_values.append(float(applied))
        self._states_absent = False
        self.counts["damper_states"] += 1
        return True

    def damping_at(self, stamp_ns: int, sample_rate: float) -> float:
        """[N s/m] applied c2 of the latest state stamped at or before ``stamp_ns`` (NaN if
        none); older states are dropped (blocks come in time order)."""
        slack = round(0.5 * _NS / sample_rate) if sample_rate > 0 else 0
        i = bisect.bisect_right(self._state_stamps, stamp_ns + slack) - 1
        if i < 0:
            return math.nan
        if i > 0:  # keep the chosen state and what follows it
            del self._state_stamps[:i]
            del self._state_values[:i]
        return self._state_values[0]

    @property
    def held_blocks(self) -> int:
        """Blocks waiting for a damper state stamped at or after their start."""
        return len(self._held)

    @property
    def oldest_held_stamp(self) -> int | None:
        """[ns] header stamp of the oldest held block (None when none is held)."""
        return self._held[0][0] if self._held else None

    def block(self, stamp_ns: int, first_index: int, sample_rate: float,
              samples: np.ndarray) -> tuple[list[StreamSpectrum], list[StreamEvent]]:
        """Add one block (header stamp [ns] = its first sample's time, stream index, rate [Hz],
        samples (channels, n)); return the spectra it completes and what to report. A block
        whose damper state has not arrived yet is held and comes out of :meth:`release`."""
        self.counts["blocks"] += 1
        self._held.append((int(stamp_ns), first_index, sample_rate, samples))
        limit = MAX_HELD_REQUIRED if self.states_required else MAX_HELD_BLOCKS
        return self.release(force=len(self._held) > limit)

    def release(self, force: bool = False) -> tuple[list[StreamSpectrum], list[StreamEvent]]:
        """Process the held blocks whose damper state has arrived (all of them if ``force``:
        those then use the latest state stamped before them); return their spectra and
        events. Call after every damper state, and with ``force`` when states stopped."""
        spectra, events = self._ready
        self._ready = ([], [])
        forced = 0
        while self._held:
            stamp_ns, first_index, sample_rate, samples = self._held[0]
            waits = self._waits_for_state(stamp_ns, sample_rate)
            if waits and not force:
                break
            forced += waits
            self._held.pop(0)
            s, e = self._process(stamp_ns, first_index, sample_rate, samples)
            spectra += s
            events += e
        if forced:
            events.append(StreamEvent(
                "damper_state_missing",
                f"{forced} block(s) analysed without the damper state stamped at their start "
                f"(the latest earlier state's c2 used)",
                "error" if self.states_required else "warn", values={"blocks": forced}))
        return spectra, events

    def _waits_for_state(self, stamp_ns: int, sample_rate: float) -> bool:
        """True while no damper state stamped at or after the block's start has arrived (an
        earlier one could still be on its way). Before the first state a block waits only
        while at most :data:`FIRST_STATE_BLOCKS` are held: the simulator publishes a block's
        state with the block, so more blocks without one mean a source without states (a
        replayed measurement), whose blocks then go out at once with no c2."""
        if not (math.isfinite(sample_rate) and sample_rate > 0.0):
            return False
        if not self._state_stamps:
            if self.states_required:
                return True
            if self._states_absent or len(self._held) > FIRST_STATE_BLOCKS:
                self._states_absent = True
                return False
            return True
        slack = round(0.5 * _NS / sample_rate)
        return self._state_stamps[-1] + slack < stamp_ns

    def _process(self, stamp_ns: int, first_index: int, sample_rate: float,
                 samples: np.ndarray) -> tuple[list[StreamSpectrum], list[StreamEvent]]:
        events: list[StreamEvent] = []
        index = int(first_index)
        if not (math.isfinite(sample_rate) and sample_rate > 0.0):
            self.counts["rejected"] += 1
            return [], [StreamEvent("bad_sample_rate", f"block at index {index} rejected: "
                                    f"sample_rate {sample_rate} Hz", values={"index": index})]
        if self.sliding is None or sample_rate != self.sliding.sample_rate:
            if not self._start_window(sample_rate, index, events):
                return [], events
        damping = self.damping_at(stamp_ns, sample_rate)
        result = self.sliding.push(index, samples, damping=damping)
        if result.reset is not None:
            event = result.reset
            self.counts["resets"] += 1
            events.append(StreamEvent(
                f"reset_{event.reason.value}", event.describe(),
                values=dict(reason=event.reason.value, expected_index=event.expected_index,
                            received_index=event.received_index,
                            dropped_samples=event.dropped_samples)))
        spectra = []
        for window in result.spectra:
            spectrum = window.spectrum
            if not np.all(np.isfinite(spectrum.magnitudes)):
                self.counts["empty_windows"] += 1
                events.append(StreamEvent(
                    "empty_window",
                    f"window {window.first_sample_index}..{window.stop_sample_index - 1} not "
                    f"published: no signal in the band on "
                    f"{[c for c, s in zip(self.channels, spectrum.band_sums) if not s > 0.0]}",
                    values={"first_index": window.first_sample_index}))
                continue
            mean = window.mean_damping
            last = window.stop_sample_index - 1
            spectra.append(StreamSpectrum(
                stamp_ns=stamp_ns + round((last - index) * _NS / sample_rate),
                spectrum=spectrum, hop=self.sliding.hop,
                damping=mean if math.isfinite(mean) else damping,
                first_sample_index=window.first_sample_index,
                stop_sample_index=window.stop_sample_index))
        self.counts["spectra"] += len(spectra)
        return spectra, events

    def _start_window(self, rate: float, index: int, events: list[StreamEvent]) -> bool:
        """(Re)build the sliding window for a sample rate. False: the block is rejected."""
        old = self.sliding
        self.sliding = None
        if old is not None:
            expected = old.expected_index
            dropped = old.reset().dropped_samples
            self.counts["resets"] += 1
            events.append(StreamEvent(
                "reset_sample_rate",
                f"spectrum window reset: sample rate changed from {old.sample_rate:g} to "
                f"{rate:g} Hz at index {index} (expected index {expected}); "
                f"{dropped} samples discarded",
                values=dict(reason="sample_rate", previous_sample_rate=old.sample_rate,
                            sample_rate=rate, expected_index=expected, received_index=index,
                            dropped_samples=dropped)))
        try:
            self.sliding = SlidingSpectrum(len(self.channels), rate,
                                           window_duration=self.window_duration, hop=self.hop,
                                           frequencies=self.frequencies, window=self.window)
        except (TypeError, ValueError) as exc:
            self.problem = f"blocks at {rate:g} Hz cannot be analysed with the parameters: {exc}"
            self.counts["rejected"] += 1
            events.append(StreamEvent("unusable_sample_rate", self.problem, "error",
                                      {"index": index, "sample_rate": rate}))
            return False
        self.problem = None
        return True
