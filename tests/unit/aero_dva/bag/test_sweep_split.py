"""record_sweep with several processes: a split bag with the same messages as one process."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from aero_dva.bag import reader as bag_reader
from aero_dva.bag import sweep_recording_io as sr
from aero_dva.bag.batch_recorder import BatchRecorder
from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import BagReadError, bag_topics, read_messages
from aero_dva.flight import sweep_simulator
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from tests.unit.aero_dva.bag.test_batch_recording import SWEEP

# The mini sweep: 9 dwells of 600 samples (5.4 s at 1 kHz), one segment each.
DIVERGES_FIRST = SWEEP.replace("ratios: [0.9, 0.95, 1.0]", "ratios: [1.3, 0.9]").replace(
    "dwell: 0.6", "dwell: 2.0")  # 1.3 U_cr with c2 = 60 N s/m diverges in the first dwell


def _runtime(tmp_path: Path, text: str = SWEEP) -> FlightRuntime:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return FlightRuntime(load_runtime_config({"scenario": str(path)}))


def _files(bag: Path) -> list[str]:
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert [f["path"] for f in meta["files"]] == meta["relative_file_paths"]
    return meta["relative_file_paths"]


def _raw(bag: Path) -> list[tuple]:
    """(topic, log time, sequence, data) of every message, file after file, CRCs checked."""
    out = []
    for name in _files(bag):
        with open(bag / name, "rb") as stream:
            reader = make_reader(stream, validate_crcs=True)
            out += [(c.topic, m.log_time, m.sequence, m.data)
                    for _, c, m in reader.iter_messages(log_time_order=False)]
    return out


def _status(bag: Path) -> list[str]:
    return [s.message for m in read_messages(bag, ["/diagnostics"]) for s in m.message.status]


def test_spans_are_segment_starts_on_block_boundaries_balanced_by_weight(tmp_path):
    runtime = _runtime(tmp_path)
    plan = sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    assert sweep_simulator.split_sweep(plan, 1) == [(0, 5400)]
    assert sweep_simulator.split_sweep(plan, 2, weights=[1.2, 1]) == [(0, 3000), (3000, 5400)]
    assert sweep_simulator.split_sweep(plan, 3, weights=[2.2, 1, 1]) == \
        [(0, 3000), (3000, 4200), (4200, 5400)]  # the segment starts nearest 2829 and 4114
    assert sweep_simulator.split_sweep(plan, 2, align=1800, weights=[1.2, 1]) == \
        [(0, 3600), (3600, 5400)]
    assert len(sweep_simulator.split_sweep(plan, 20)) == 9  # one span per segment at most
    with pytest.raises(ValueError, match="parts must be a positive integer"):
        sweep_simulator.split_sweep(plan, 0)
    with pytest.raises(ValueError, match="weights must be 2 finite values > 0"):
        sweep_simulator.split_sweep(plan, 2, weights=[1.0, -1.0])
    # Equal work: a later span also carries the state over the samples before it.
    weights = sr._balanced_weights(3)
    starts = np.concatenate([[0.0], np.cumsum(weights)[:-1]])
    np.testing.assert_allclose(sr.PREFIX_COST * starts + weights, 1.0)


def test_a_span_is_the_same_bits_as_that_part_of_the_whole_flight(tmp_path):
    runtime = _runtime(tmp_path)
    plan = sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    whole = list(sweep_simulator.simulate_sweep(runtime.config, plan, chunk_samples=1300))
    outputs = np.concatenate([c.outputs for c in whole], axis=1)
    force = np.concatenate([c.force for c in whole])
    for first, end in ((1800, 4200), (4200, 5400)):
        part = list(sweep_simulator.simulate_sweep(runtime.config, plan, chunk_samples=1300,
                                               span=(first, end)))
        assert part[0].first_index == first
        np.testing.assert_array_equal(np.concatenate([c.outputs for c in part], axis=1),
                                      outputs[:, first:end])
        np.testing.assert_array_equal(np.concatenate([c.force for c in part]),
                                      force[first:end])
    with pytest.raises(ValueError, match=r"span \(100, 600\) must be two segment starts"):
        next(sweep_simulator.simulate_sweep(runtime.config, plan, span=(100, 600)))


@pytest.mark.parametrize("jobs", [2, 3])
def test_several_processes_write_the_messages_of_one(tmp_path, jobs):
    one = sr.record_sweep(tmp_path / "one", _runtime(tmp_path), chunk_samples=1300)
    seen = []
    split = sr.record_sweep(tmp_path / "split", _runtime(tmp_path), chunk_samples=1300,
                            jobs=jobs, progress=lambda done, total: seen.append((done, total)))
    assert _files(tmp_path / "split") == [f"split_{j}.mcap" for j in range(jobs)]
    assert (split.outcome, split.samples, split.blocks) == \
        (one.outcome, one.samples, one.blocks) == ("completed", 5400, 108)
    assert seen[-1] == (5400, 5400)
    # Every message, its log time and sequence number, byte for byte, in the same order.
    a, b = _raw(tmp_path / "split"), _raw(tmp_path / "one")
    assert [m[:3] for m in a if m[0] != "/diagnostics"] == \
        [m[:3] for m in b if m[0] != "/diagnostics"]
    assert [m[3] for m in a if m[0] != "/diagnostics"] == \
        [m[3] for m in b if m[0] != "/diagnostics"]
    assert a[-1][0] == "/diagnostics" and _status(tmp_path / "split") == ["flight completed"]
    assert {t: i.message_count for t, i in bag_topics(tmp_path / "split").items()} == \
        {t: i.message_count for t, i in bag_topics(tmp_path / "one").items()}
    assert split.summary.message_count == one.summary.message_count == 6 * 108 + 1
    np.testing.assert_array_equal(load_flight_log(tmp_path / "split").accelerations,
                                  load_flight_log(tmp_path / "one").accelerations)


def test_divergence_in_an_early_span_ends_the_bag_there(tmp_path):
    runtime = _runtime(tmp_path, DIVERGES_FIRST)
    plan = sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    spans = sweep_simulator.split_sweep(plan, 2, align=50, weights=sr._balanced_weights(2))
    one = sr.record_sweep(tmp_path / "one", _runtime(tmp_path, DIVERGES_FIRST))
    assert one.outcome == "diverged" and one.samples < spans[0][1]  # in the first span
    split = sr.record_sweep(tmp_path / "split", _runtime(tmp_path, DIVERGES_FIRST), jobs=2)
    assert (split.outcome, split.samples) == ("diverged", one.samples)
    assert _files(tmp_path / "split") == ["split_0.mcap"]
    assert sorted(p.name for p in (tmp_path / "split").iterdir()) == \
        ["metadata.yaml", "split_0.mcap"]  # the later file is gone
    a, b = _raw(tmp_path / "split"), _raw(tmp_path / "one")
    assert [m[:3] for m in a] == [m[:3] for m in b]
    assert _status(tmp_path / "split") == _status(tmp_path / "one")
    assert _status(tmp_path / "split")[0].startswith("flight stopped at U = ")


def test_a_failed_span_leaves_no_completed_bag(tmp_path, monkeypatch):
    write = BatchRecorder.write_samples

    def fails_at_the_start(recorder, first_index, *args, **kwargs):
        if first_index == 0:  # the first span's process
            raise OSError(28, "No space left on device")
        return write(recorder, first_index, *args, **kwargs)

    monkeypatch.setattr(BatchRecorder, "write_samples", fails_at_the_start)
    with pytest.raises(RuntimeError, match="recording span 0 of the sweep failed: OSError: "
                                           r"\[Errno 28\] No space left"):
        sr.record_sweep(tmp_path / "bag", _runtime(tmp_path), jobs=2)
    # Nothing before the second span was written, so no file makes a prefix of the flight.
    assert list((tmp_path / "bag").iterdir()) == []
    with pytest.raises(BagReadError, match="no metadata.yaml"):
        bag_topics(tmp_path / "bag")


def test_a_failure_in_the_last_span_keeps_the_prefix_without_status(tmp_path, monkeypatch):
    write = BatchRecorder.write_samples

    def fails_late(recorder, first_index, *args, **kwargs):
        if first_index >= 3000:  # the calling process's span
            raise OSError(5, "Input/output error")
        return write(recorder, first_index, *args, **kwargs)

    monkeypatch.setattr(BatchRecorder, "write_samples", fails_late)
    with pytest.raises(OSError, match="Input/output error"):
        sr.record_sweep(tmp_path / "bag", _runtime(tmp_path), jobs=2)
    # The first span's file and what the second wrote before failing (nothing here) make
    # the bag: a prefix of the flight, without a final status.
    assert _files(tmp_path / "bag") == ["bag_0.mcap", "bag_1.mcap"]
    assert _status(tmp_path / "bag") == []
    blocks = [m.message.first_sample_index
              for m in read_messages(tmp_path / "bag", ["/wing/excitation"])]
    assert blocks == list(range(0, 3000, 50))


def test_jobs_must_be_a_positive_integer(tmp_path):
    with pytest.raises(ValueError, match="jobs must be a positive integer, got 0"):
        sr.record_sweep(tmp_path / "bag", _runtime(tmp_path), jobs=0)
    assert sr.default_jobs(1000) == 1  # too short to be worth a process


def test_a_split_bag_without_metadata_is_salvaged_in_file_order(tmp_path):
    sr.record_sweep(tmp_path / "bag", _runtime(tmp_path), jobs=3)
    (tmp_path / "bag" / "metadata.yaml").unlink()  # as if the recording had crashed
    blocks = [m.message.first_sample_index for m in read_messages(
        tmp_path / "bag", ["/wing/excitation"], allow_truncated=True)]
    assert blocks == list(range(0, 5400, 50))
    names = [Path(f"bag_{i}.mcap") for i in (10, 2, 1)]
    assert [p.name for p in sorted(names, key=bag_reader._file_order)] == \
        ["bag_1.mcap", "bag_2.mcap", "bag_10.mcap"]
