"""record_sweep: measured-only topics; writing on a second thread (same bytes, errors raised)."""
from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from aero_dva.bag import sweep_recording_io as sr
from aero_dva.bag.chunk_framing import ChunkedMcapFile
from aero_dva.bag.reader import bag_topics, read_messages
from aero_dva.flight import sweep_simulator
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from tests.unit.aero_dva.bag.test_batch_recording import SWEEP

# The mini sweep of test_batch_recording (3 airspeeds x 3 c2 x 0.6 s = 5.4 s at 1 kHz);
# chunks of 1300 samples give 5 chunks.
DISPLACEMENT = "/wing/displacement"


@pytest.fixture
def scenario(tmp_path) -> str:
    path = tmp_path / "sweep.yaml"
    path.write_text(SWEEP)
    return str(path)


def _runtime(scenario: str) -> FlightRuntime:
    return FlightRuntime(load_runtime_config({"scenario": scenario}))


def _raw(bag: Path, skip=("/diagnostics",)) -> list[tuple]:
    """(topic, log time, sequence, data) of every message in file order, CRCs checked."""
    (path,) = bag.glob("*.mcap")
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        return [(c.topic, m.log_time, m.sequence, m.data)
                for _, c, m in reader.iter_messages(log_time_order=False)
                if c.topic not in skip]


def _status(bag: Path) -> list:
    return [s for m in read_messages(bag, ["/diagnostics"]) for s in m.message.status]


def _writer_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name == "bag-writer"]


def test_simulate_sweep_computes_only_the_channels_asked_for(scenario):
    runtime = _runtime(scenario)
    plan = sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    full = list(sweep_simulator.simulate_sweep(runtime.config, plan, chunk_samples=1300))
    some = list(sweep_simulator.simulate_sweep(
        runtime.config, plan, chunk_samples=1300,
        outputs=("leading_edge_acceleration", "leading_edge")))
    assert [c.outputs.shape[0] for c in some] == [2] * len(full)
    for a, b in zip(full, some):
        np.testing.assert_array_equal(b.force, a.force)
        # each channel is its own product: the same bits whatever else is computed
        np.testing.assert_array_equal(b.rows(["leading_edge"]), a.displacements[2:3])
        np.testing.assert_array_equal(b.outputs[0], a.accelerations[2])
    with pytest.raises(ValueError, match="this chunk has"):
        some[0].displacements  # noqa: B018 - the property raises
    with pytest.raises(ValueError, match="outputs must be distinct names"):
        next(sweep_simulator.simulate_sweep(runtime.config, plan, outputs=("stroke",)))


def test_measured_only_sweep_is_the_full_bag_without_the_displacement(tmp_path, scenario):
    full = sr.record_sweep(tmp_path / "full", _runtime(scenario), chunk_samples=1300)
    measured = sr.record_sweep(tmp_path / "measured", _runtime(scenario), chunk_samples=1300,
                               displacement=False)
    assert DISPLACEMENT in bag_topics(tmp_path / "full")
    assert set(bag_topics(tmp_path / "measured")) == \
        set(bag_topics(tmp_path / "full")) - {DISPLACEMENT}
    assert (measured.samples, measured.blocks) == (full.samples, full.blocks) == (5400, 108)
    expected = [m for m in _raw(tmp_path / "full") if m[0] != DISPLACEMENT]
    assert len(expected) == 5 * 108
    assert _raw(tmp_path / "measured") == expected  # topics, times, sequences, bytes
    (status,) = _status(tmp_path / "measured")
    values = {kv.key: kv.value for kv in status.values}
    assert status.message == "flight completed"
    assert values["published:wing/displacement"] == "108"  # the node published it


def test_writing_on_a_second_thread_gives_the_same_bytes(tmp_path, scenario):
    for name, overlap in (("thread", True), ("inline", False)):
        sr.record_sweep(tmp_path / name, _runtime(scenario), chunk_samples=1300,
                        displacement=False, overlap=overlap)
    assert _raw(tmp_path / "thread") == _raw(tmp_path / "inline")
    assert _writer_threads() == []


def test_measured_only_sweep_stops_at_divergence_like_the_full_one(tmp_path):
    path = tmp_path / "div.yaml"
    path.write_text(SWEEP.replace("ratios: [0.9, 0.95, 1.0]", "ratios: [0.9, 1.3]")
                    .replace("dwell: 0.6", "dwell: 2.0"))
    full = sr.record_sweep(tmp_path / "full", _runtime(str(path)))
    measured = sr.record_sweep(tmp_path / "measured", _runtime(str(path)), displacement=False)
    assert full.outcome == measured.outcome == "diverged"
    assert (measured.samples, measured.blocks) == (full.samples, full.blocks)
    assert measured.samples < 12000
    (a,), (b,) = _status(tmp_path / "full"), _status(tmp_path / "measured")
    assert a.message == b.message and b.message.startswith("flight stopped at U = ")


def _on_writer_thread() -> bool:
    return threading.current_thread().name == "bag-writer"


def test_the_writer_is_at_most_two_runs_behind(tmp_path, scenario, monkeypatch):
    simulated, lag = [], []
    append = ChunkedMcapFile.add_messages

    def slow_append(bag, *args):
        if _on_writer_thread():
            lag.append(len(simulated) - len(lag))  # chunks encoded but not yet written
            threading.Event().wait(0.05)
        return append(bag, *args)

    monkeypatch.setattr(ChunkedMcapFile, "add_messages", slow_append)
    result = sr.record_sweep(tmp_path / "bag", _runtime(scenario), chunk_samples=1300,
                             progress=lambda done, total: simulated.append(done))
    assert result.samples == 5400 and len(lag) == 5  # one encoded run per chunk here
    assert max(lag) <= 3  # the one being written + 2 queued: memory stays bounded
    assert max(lag) >= 2  # ... and the simulation did run ahead of the slow writer
    assert _raw(tmp_path / "bag") == _raw_reference(tmp_path, scenario)


def _raw_reference(tmp_path: Path, scenario: str) -> list[tuple]:
    sr.record_sweep(tmp_path / "reference", _runtime(scenario), chunk_samples=1300,
                    overlap=False)
    return _raw(tmp_path / "reference")


def test_a_writer_error_is_raised_and_leaves_no_completed_flight(tmp_path, scenario,
                                                                  monkeypatch):
    calls = []
    append = ChunkedMcapFile.add_messages

    def failing(bag, *args):
        if _on_writer_thread():
            calls.append(len(args[1]))
            if len(calls) == 3:
                raise OSError(28, "No space left on device")
        return append(bag, *args)

    monkeypatch.setattr(ChunkedMcapFile, "add_messages", failing)
    with pytest.raises(OSError, match="No space left"):
        sr.record_sweep(tmp_path / "bag", _runtime(scenario), chunk_samples=1300)
    assert _writer_threads() == []
    assert len(calls) == 3  # nothing written after the failed run
    # What was written before the failure is closed as a valid bag: a prefix without holes,
    # metadata counting what is in the file, and no final status: nothing presents it as a
    # completed flight.
    assert _status(tmp_path / "bag") == []
    blocks = [m.message for m in read_messages(tmp_path / "bag", ["/wing/excitation"])]
    assert [b.first_sample_index for b in blocks] == list(range(0, 2400, 50))
    topics = bag_topics(tmp_path / "bag")
    assert topics["/wing/excitation"].message_count == topics["/clock"].message_count == 48
    assert len(_raw(tmp_path / "bag")) == 6 * 48


def test_a_simulation_error_stops_the_writer(tmp_path, scenario, monkeypatch):
    simulate = sweep_simulator.simulate_sweep

    def breaks_after_two(*args, **kwargs):
        chunks = simulate(*args, **kwargs)
        yield next(chunks)
        yield next(chunks)
        raise FloatingPointError("simulation failed")

    monkeypatch.setattr(sweep_simulator, "simulate_sweep", breaks_after_two)
    with pytest.raises(FloatingPointError, match="simulation failed"):
        sr.record_sweep(tmp_path / "bag", _runtime(scenario), chunk_samples=1300)
    assert _writer_threads() == []
    assert _status(tmp_path / "bag") == []


def test_training_names_the_missing_displacement_of_a_measured_only_bag(tmp_path, scenario):
    from aero_dva.bag.reader import TopicNotFoundError
    from dva_offline.training.rbf_cli import _check_topics

    sr.record_sweep(tmp_path / "bag", _runtime(scenario), displacement=False)
    with pytest.raises(TopicNotFoundError, match=r"no topic /wing/displacement \(the "
                                                 r".*leading-edge RMS.*--no-displacement"):
        _check_topics(tmp_path / "bag")
