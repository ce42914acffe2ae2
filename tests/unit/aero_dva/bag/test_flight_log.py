"""Flight logs: a bag written the way the simulator publishes reads back into exact arrays."""
from __future__ import annotations

import math

import numpy as np
import pytest

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.flight_summary import sample_airspeed, summarize
from aero_dva.bag.reader import BagReadError
from aero_dva.bag.writer import BagWriter
from aero_dva.flight.divergence import divergence_airspeed, stop_message

RATE, BLOCK = 1000.0, 50


def _stamp(t: float) -> dict:
    ns = int(round(t * 1e9))
    return {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": "wing"}


def _write_flight(bag, leading_edge, airspeed, skip_blocks=(), u_cr=100.0, diverged=False):
    n = leading_edge.size
    with BagWriter(bag) as writer:
        writer.add_topic("/wing/displacement", "dva_msgs/msg/DisplacementBlock")
        writer.add_topic("/flight/condition", "dva_msgs/msg/FlightCondition")
        writer.add_topic("/dva/damper_state", "dva_msgs/msg/DamperState")
        writer.add_topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")
        for b, i0 in enumerate(range(0, n, BLOCK)):
            t0 = i0 / RATE
            t_ns = int(round(t0 * 1e9))
            sl = slice(i0, i0 + BLOCK)
            if b not in skip_blocks:
                writer.write("/wing/displacement", {
                    "header": _stamp(t0), "sample_rate": RATE, "first_sample_index": i0,
                    "plunge": np.zeros(BLOCK), "pitch": np.zeros(BLOCK),
                    "leading_edge": leading_edge[sl], "absorber_stroke": np.zeros(BLOCK)}, t_ns)
            writer.write("/flight/condition", {"header": _stamp(t0), "airspeed": airspeed[i0],
                                               "air_density": 1.2}, t_ns)
            writer.write("/dva/damper_state", {"header": _stamp(t0), "applied_damping": 700.0,
                                               "status": 0, "source": "fixed"}, t_ns)
        text = stop_message(118.0, u_cr, n / RATE) if diverged else "flight completed"
        writer.write("/diagnostics", {"header": _stamp(n / RATE), "status": [{
            "level": 2 if diverged else 0, "name": "simulator: flight",
            "message": text, "hardware_id": "aero_dva_sim",
            "values": [{"key": "critical_airspeed_no_dva", "value": str(u_cr)}]}]},
            int(n / RATE * 1e9))


def _ramp(n):
    return 80.0 + 40.0 * np.arange(n) / n


def test_blocks_are_placed_by_index_and_gaps_stay_nan(tmp_path):
    n = 1000
    le = np.sin(np.arange(n) * 0.1) * 1e-3
    _write_flight(tmp_path / "bag", le, _ramp(n), skip_blocks=(3,))
    log = load_flight_log(tmp_path / "bag")
    assert log.sample_rate == RATE and log.time.size == n
    missing = np.isnan(log.displacements[2])
    assert missing.sum() == BLOCK == log.missing_samples
    assert missing[3 * BLOCK:4 * BLOCK].all()
    np.testing.assert_array_equal(log.displacements[2][~missing], le[~missing])
    # Per-block airspeed is held over the block's samples.
    np.testing.assert_array_equal(log.airspeed[:BLOCK], np.full(BLOCK, 80.0))
    assert log.applied_damping[0] == 700.0
    assert log.diagnostics[-1]["values"]["critical_airspeed_no_dva"] == "100.0"


def test_summary_finds_divergence_of_a_growing_response(tmp_path):
    n = 30000
    t = np.arange(n) / RATE
    rng = np.random.default_rng(0)
    le = 1e-3 * rng.standard_normal(n)
    grow = t > 24.0  # response grows from t = 24 s (U = 112 m/s) on
    le[grow] *= np.exp(2.0 * (t[grow] - 24.0))
    airspeed = _ramp(n)
    _write_flight(tmp_path / "bag", le, airspeed, diverged=True)
    log = load_flight_log(tmp_path / "bag")
    summary = summarize(log)
    assert summary.critical_airspeed == 100.0
    assert 112.0 < summary.divergence_airspeed < 116.0
    assert summary.divergence_ratio == pytest.approx(summary.divergence_airspeed / 100.0)
    assert summary.stopped_by_simulator
    # the one detector, on each sample's airspeed: the bag's one per block read off the ramp
    np.testing.assert_allclose(sample_airspeed(log), airspeed, rtol=1e-12)
    assert summary.divergence_airspeed == pytest.approx(divergence_airspeed(airspeed, le, RATE),
                                                        rel=1e-12)
    before = airspeed < summary.divergence_airspeed
    assert summary.leading_edge_rms_before_divergence == pytest.approx(
        np.sqrt(np.mean(le[before] ** 2)))
    assert 1e-3 < summary.leading_edge_rms_before_divergence < 1e-2  # the onset of the growth
    # the RMS that compares flights: over 0.8-1.05 U_cr after the first 2 s, before the growth
    inside = (airspeed >= 80.0) & (airspeed <= 105.0) & (t >= 2.0)
    assert summary.rms_range == (0.8, 1.05)
    assert summary.leading_edge_rms == pytest.approx(np.sqrt(np.mean(le[inside] ** 2)))
    assert summary.mean_damping == 700.0


def test_a_flight_that_ends_inside_the_rms_range_has_no_such_rms(tmp_path):
    """Diverged at 1.0 U_cr, the flight has no RMS over 0.8-1.05 U_cr: over what it survived
    its RMS would be small, and rank it above a flight that held to 1.2 U_cr."""
    n = 15000  # 80 -> 100 m/s: the log ends below 105 m/s
    le = 1e-3 * np.random.default_rng(2).standard_normal(n)
    _write_flight(tmp_path / "bag", le, 80.0 + 20.0 * np.arange(n) / n, diverged=True)
    summary = summarize(load_flight_log(tmp_path / "bag"))
    assert math.isnan(summary.leading_edge_rms)
    assert summary.to_dict()["leading_edge_rms"] is None
    assert summary.leading_edge_rms_before_divergence > 0


def test_bounded_flight_has_no_divergence(tmp_path):
    n = 10000
    le = 1e-3 * np.random.default_rng(1).standard_normal(n)
    _write_flight(tmp_path / "bag", le, _ramp(n))
    summary = summarize(load_flight_log(tmp_path / "bag"))
    assert math.isnan(summary.divergence_airspeed)
    assert summary.to_dict()["divergence_airspeed"] is None
    assert not summary.stopped_by_simulator


def test_missing_topic_is_named(tmp_path):
    with BagWriter(tmp_path / "bag") as writer:
        writer.add_topic("/flight/condition", "dva_msgs/msg/FlightCondition")
        writer.write("/flight/condition", {"airspeed": 80.0, "air_density": 1.2}, 0)
    with pytest.raises(BagReadError, match="/wing/displacement"):
        load_flight_log(tmp_path / "bag")


def test_airspeeds_that_are_no_ramp_keep_their_blocks_values(tmp_path):
    """Steps of 1 s (20 blocks each) are no straight line: every sample keeps its block's."""
    n = 6000
    steps = 90.0 + 5.0 * (np.arange(n) // 1000)
    _write_flight(tmp_path / "bag", 1e-3 * np.ones(n), steps)
    log = load_flight_log(tmp_path / "bag")
    assert np.array_equal(sample_airspeed(log), log.airspeed)
    assert np.array_equal(log.airspeed, steps)


def test_a_damper_block_schema_without_the_commanded_c2_reads_the_other_rows():
    """A bag recorded before DamperBlock.commanded_damping: its rows are read, the commanded
    c2 is left out (NaN in the log; the flight analysis then refuses the law's flight)."""
    from types import SimpleNamespace

    from aero_dva.bag import channels as ch
    from aero_dva.bag.flight_log_io import _present
    from aero_dva.bag.schemas import message_definition

    rows = ("damping", "force", "commanded_damping")
    now = message_definition(ch.DAMPER_BLOCK.type_name)
    old = "\n".join(line for line in now.splitlines()
                    if not line.startswith(("float64[] commanded_damping", "  ")))
    assert "commanded_damping" in now and "commanded_damping" not in old.split("===")[0]
    for text, want in ((now, rows), (old, rows[:2])):
        batch = SimpleNamespace(type_name=ch.DAMPER_BLOCK.type_name, schema_text=text)
        assert _present(ch.DAMPER_BLOCK, rows, batch) == want
