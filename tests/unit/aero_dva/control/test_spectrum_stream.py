"""The spectrum node's work without ROS: windows, stamps, and the c2 chosen by stamp."""
from __future__ import annotations

import math

import numpy as np
import pytest

from aero_dva.control.spectrum import scaled_spectrum
from aero_dva.control.spectrum_stream import SpectrumStream

FS = 1000.0
BLOCK = 50
T0 = 7_000_000_000  # [ns] time of sample 0
FREQS = np.arange(5.0, 21.0)


def _stamp(index: int) -> int:
    return T0 + round(index * 1e9 / FS)


def _signals(n: int) -> np.ndarray:
    t = np.arange(n) / FS
    rng = np.random.default_rng(3)
    return np.vstack([np.sin(2 * np.pi * 12 * t), np.cos(2 * np.pi * 7 * t)]) \
        + 0.1 * rng.standard_normal((2, n))


def _stream(hop: float = 0.5) -> SpectrumStream:
    return SpectrumStream(("plunge", "pitch"), 2.0, hop, FREQS, "rectangular")


def _feed(stream, samples, applied, states_first: bool):
    """Blocks with the simulator's damper state of each (stamped at its start, its c2); with
    ``states_first`` the state of block k + 1 arrives before block k (too new for it)."""
    out = []
    starts = list(range(0, samples.shape[1], BLOCK))
    if states_first:
        stream.damper_state(_stamp(0), applied(0))
    for k, start in enumerate(starts):
        if states_first and k + 1 < len(starts):
            stream.damper_state(_stamp(start + BLOCK), applied(k + 1))
        spectra, events = stream.block(_stamp(start), start, FS, samples[:, start:start + BLOCK])
        assert not events
        out += spectra
        if not states_first:
            stream.damper_state(_stamp(start), applied(k))
            spectra, events = stream.release()
            assert not events
            out += spectra
    return out


def test_windows_stamps_and_magnitudes_are_the_pure_function_of_the_window():
    samples = _signals(4000)
    spectra = _feed(_stream(), samples, lambda k: 800.0, states_first=False)
    assert len(spectra) == 5  # windows starting at 0, 0.5, ..., 2.0 s
    for i, s in enumerate(spectra):
        first = 500 * i
        assert (s.first_sample_index, s.stop_sample_index) == (first, first + 2000)
        assert s.stamp_ns == _stamp(first + 1999)  # the window's last sample
        expected = scaled_spectrum(samples[:, first:first + 2000], FS, FREQS)
        np.testing.assert_allclose(s.spectrum.magnitudes, expected.magnitudes, rtol=1e-12)
        assert s.hop == 0.5
    assert all(s.damping == 800.0 for s in spectra)  # the first block waited for its c2


def test_c2_is_chosen_by_stamp_whatever_the_arrival_order():
    """Block k uses the state stamped at its start (the c2 it was flown with); the next
    block's state arriving early does not leak into it."""
    samples = _signals(4000)
    c2 = lambda k: 300.0 + 10.0 * k  # noqa: E731 - a new c2 every block
    late = _feed(_stream(), samples, c2, states_first=False)
    early = _feed(_stream(), samples, c2, states_first=True)
    assert [s.damping for s in late] == [s.damping for s in early]
    # window 1 (samples 500..2499 = blocks 10..49) used the states of blocks 10..49
    assert late[1].damping == pytest.approx(np.mean([c2(k) for k in range(10, 50)]))
    assert late[0].damping == pytest.approx(np.mean([c2(k) for k in range(0, 40)]))


def test_state_stamp_rounding_is_tolerated_and_time_going_back_starts_over():
    stream = _stream()
    stream.damper_state(_stamp(50) + 1, 500.0)  # 1 ns late: still this block's state
    assert stream.damping_at(_stamp(50), FS) == 500.0
    assert math.isnan(stream.damping_at(_stamp(0), FS))  # no state stamped that early
    stream.damper_state(_stamp(0), 700.0)  # a new run (replay loop): history restarts
    assert stream.latest_damping == 700.0 and stream.damping_at(_stamp(0), FS) == 700.0
    assert not stream.damper_state(_stamp(100), float("nan"))
    assert stream.counts["damper_states"] == 2


def test_bad_blocks_are_reported_not_raised():
    stream = _stream()
    stream.damper_state(T0, 500.0)
    spectra, events = stream.block(T0, 0, 0.0, np.zeros((2, BLOCK)))
    assert not spectra and events[0].event == "bad_sample_rate"
    spectra, events = stream.block(T0, 0, 333.0, np.zeros((2, BLOCK)))
    assert events[0].event == "unusable_sample_rate" and events[0].level == "error"
    assert stream.problem and stream.counts["rejected"] == 2
    stream.block(T0, 0, FS, np.ones((2, BLOCK)))
    _, events = stream.block(T0, 100, FS, np.ones((2, BLOCK)))  # 50..99 lost
    assert events[0].event == "reset_gap" and events[0].values["expected_index"] == 50


def test_a_block_waits_for_the_state_stamped_at_its_start():
    """A busy replay hands over block k before the state stamped at its start (DDS orders
    topics separately): the block is held until that state arrives, so the spectra and their
    c2 are those of the in-order feed. The first block waits for the first state too."""
    samples = _signals(4000)
    c2 = lambda k: 300.0 + 10.0 * k  # noqa: E731
    reference = _feed(_stream(), samples, c2, states_first=True)
    stream, out = _stream(), []
    for k, start in enumerate(range(0, samples.shape[1], BLOCK)):
        spectra, events = stream.block(_stamp(start), start, FS,
                                       samples[:, start:start + BLOCK])
        out += spectra
        assert not events and stream.held_blocks == 1
        stream.damper_state(_stamp(start), c2(k))  # block k's own state, after block k
        out += stream.release()[0]
        assert stream.held_blocks == 0
    assert [(s.stamp_ns, s.damping) for s in out] == \
        [(s.stamp_ns, s.damping) for s in reference]


def test_without_any_state_blocks_wait_briefly_then_go_out_with_no_c2():
    """A replayed measurement has no damper states: after FIRST_STATE_BLOCKS held blocks the
    stream stops waiting for them (and waits again once a state comes)."""
    samples = _signals(3000)
    stream = _stream()
    out = []
    for start in range(0, 2500, BLOCK):
        spectra, events = stream.block(_stamp(start), start, FS,
                                       samples[:, start:start + BLOCK])
        assert not events
        out += spectra
    assert stream.held_blocks == 0 and out and all(math.isnan(s.damping) for s in out)
    stream.damper_state(_stamp(2500), 700.0)
    stream.block(_stamp(2500), 2500, FS, samples[:, 2500:2550])  # its state is there
    assert stream.held_blocks == 0
    stream.block(_stamp(2550), 2550, FS, samples[:, 2550:2600])  # states flow: waits again
    assert stream.held_blocks == 1


def test_without_its_state_a_held_block_goes_out_when_forced_and_says_so():
    samples = _signals(400)
    stream = _stream()
    stream.damper_state(_stamp(0), 500.0)
    stream.block(_stamp(0), 0, FS, samples[:, :BLOCK])
    assert stream.held_blocks == 0
    stream.block(_stamp(BLOCK), BLOCK, FS, samples[:, BLOCK:2 * BLOCK])
    assert stream.held_blocks == 1 and stream.oldest_held_stamp == _stamp(BLOCK)
    spectra, events = stream.release()
    assert stream.held_blocks == 1 and not events
    spectra, events = stream.release(force=True)
    assert stream.held_blocks == 0
    assert [e.event for e in events] == ["damper_state_missing"]
    assert events[0].values == {"blocks": 1}
    assert stream.damping_at(_stamp(BLOCK), FS) == 500.0


def test_time_going_back_lets_the_old_runs_held_blocks_out_with_their_own_c2():
    samples = _signals(4000)
    stream = _stream()
    last = 2000 - BLOCK  # the block that completes the first window
    for start in range(0, last, BLOCK):
        stream.damper_state(_stamp(start), 600.0)
        stream.block(_stamp(start), start, FS, samples[:, start:start + BLOCK])
    stream.block(_stamp(last), last, FS, samples[:, last:2000])  # its state never comes
    assert stream.held_blocks == 1
    stream.damper_state(_stamp(0), 900.0)  # a new run
    spectra, events = stream.release()
    assert stream.held_blocks == 0 and events[0].event == "damper_state_missing"
    assert spectra and all(s.damping == 600.0 for s in spectra)


def _late_first_states(stream, samples, late: int):
    """Blocks with their states (each stamped at its block's start, c2 500 + 10 k N s/m), the
    first ``late`` states arriving after the first ``late`` blocks (a state topic whose first
    samples come again at the writer's next heartbeat); every spectrum, forced out at the end."""
    starts = list(range(0, samples.shape[1], BLOCK))
    order = [("block", k) for k in range(late)] + [("state", k) for k in range(late)]
    for k in range(late, len(starts)):
        order += [("state", k), ("block", k)]
    out = []
    for kind, k in order:
        if kind == "state":
            stream.damper_state(_stamp(starts[k]), 500.0 + 10.0 * k)
            out += stream.release()[0]
        else:
            out += stream.block(_stamp(starts[k]), starts[k], FS,
                                samples[:, starts[k]:starts[k] + BLOCK])[0]
    return out + stream.release(force=True)[0]


def test_with_states_required_late_states_change_no_spectrum():
    """Without ``states_required`` three blocks before the first state make the states count
    as absent, and the first spectra carry another c2 than in order: the load decides (the
    mechanism behind a graph replay that once differed from --offline at load 5-6). With it,
    the spectra are the in-order ones whatever the interleaving."""
    samples = _signals(4000)

    def spectra(late: int, required: bool):
        stream = SpectrumStream(("plunge", "pitch"), 2.0, 0.5, FREQS, "rectangular",
                                states_required=required)
        return [(s.stamp_ns, s.damping) for s in _late_first_states(stream, samples, late)]

    in_order = spectra(0, required=False)
    assert len(in_order) == 5 and in_order == spectra(0, required=True)
    assert spectra(3, required=False) != in_order  # the mechanism, shown
    for late in (1, 3, 20, 79):
        assert spectra(late, required=True) == in_order, late
