"""The batch recorder: flight blocks -> rosbag2 MCAP bag, byte for byte what rosbags and mcap's
writer make of the same messages, read back exactly by every reader."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader

from aero_dva.bag import sweep_recording_io as sr
from aero_dva.bag.batch_recorder import DAMPER_COLUMNS, BatchRecorder, recorded_topics
from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import bag_topics, read_messages
from aero_dva.bag.runtime_recording import record_flight_blocks, record_runtime
from aero_dva.bag.schemas import message_definition
from aero_dva.bag.writer import qos_profile_yaml
from aero_dva.flight.damper import DamperSnapshot, DamperStatus
from aero_dva.flight.samples import FlightSamples
from tests.unit.aero_dva.bag.reference_bag import ReferenceBag

RATE = 1000.0
TOPICS = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/wing/acceleration": "dva_msgs/msg/AccelerationBlock",
    "/wing/displacement": "dva_msgs/msg/DisplacementBlock",
    "/wing/excitation": "dva_msgs/msg/ForceBlock",
    "/flight/condition": "dva_msgs/msg/FlightCondition",
    "/dva/damper_state": "dva_msgs/msg/DamperState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}


def make_flight(count=120, n=50, last=17, seed=0, switch_source_at=70):
    """Blocks of a flight (the last one shorter) and the damper snapshot after each."""
    rng = np.random.default_rng(seed)
    blocks, states = [], []
    index = 0
    for k in range(count):
        m = last if k == count - 1 else n
        blocks.append(FlightSamples(
            first_index=index, sample_rate=RATE,
            force=1e3 * rng.standard_normal(m),
            airspeed=80.0 + 0.1 * k + np.arange(m) * 1e-4,
            density=1.2 * (1 + 0.05 * np.sin(2 * np.pi * (index + np.arange(m)) / RATE)),
            damping=np.full(m, 300.0),
            displacements=rng.standard_normal((4, m)) * 1e-3,
            accelerations=rng.standard_normal((3, m)),
            diverged=False))
        states.append(DamperSnapshot(
            time=(index + m) / RATE, commanded_damping=math.nan if k < 10 else 700.0 + k,
            applied_damping=500.0 + k, min_damping=0.0, max_damping=2500.0,
            command_age=math.inf if k < 10 else 0.05,
            status=DamperStatus.NO_COMMAND if k < 10 else DamperStatus.OK,
            source="initial" if k < switch_source_at else "rbf_network", rejection=None))
        index += m
    return blocks, states


@pytest.fixture(scope="module")
def flight():
    return make_flight()


@pytest.fixture(scope="module")
def bag(flight, tmp_path_factory):
    blocks, states = flight
    path = tmp_path_factory.mktemp("batch") / "run"
    with BatchRecorder(path, RATE) as recorder:
        recorder.write_blocks(blocks[:50], states[:50])
        recorder.write_blocks(blocks[50:], states[50:])
        recorder.write_diagnostics(blocks[-1].t_end, [
            ("ok", "flight completed", {"sim_time_s": blocks[-1].t_end, "published": 120})])
    return path


def ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def test_topics_types_counts_and_qos(bag):
    topics = bag_topics(bag)
    assert {name: info.type_name for name, info in topics.items()} == TOPICS
    counts = {name: info.message_count for name, info in topics.items()}
    assert counts == {**dict.fromkeys(TOPICS, 120), "/diagnostics": 1}
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["message_count"] == 6 * 120 + 1
    assert [t["topic_metadata"]["name"] for t in info["topics_with_message_count"]] == list(TOPICS)
    with open(bag / "run_0.mcap", "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert {c.metadata["offered_qos_profiles"] for c in summary.channels.values()} == {
        qos_profile_yaml()}
    for schema in summary.schemas.values():
        assert schema.encoding == "ros2msg"
        assert schema.data.decode() == message_definition(schema.name)


def test_messages_read_back_exactly(bag, flight):
    blocks, states = flight
    got: dict[str, list] = {}
    for record in read_messages(bag):
        got.setdefault(record.topic, []).append(record)
    for k, block in enumerate(blocks):
        end = ns(block.t_end)
        for topic in TOPICS:
            if topic != "/diagnostics":
                assert got[topic][k].log_time_ns == got[topic][k].publish_time_ns == end
        clock = got["/clock"][k].message.clock
        assert clock.sec * 10**9 + clock.nanosec == end
        for topic, attribute, fields in (
            ("/wing/acceleration", "accelerations", ("plunge", "pitch", "leading_edge")),
            ("/wing/displacement", "displacements",
             ("plunge", "pitch", "leading_edge", "absorber_stroke")),
            ("/wing/excitation", None, ("aileron_force",)),
        ):
            msg = got[topic][k].message
            stamp = msg.header.stamp
            assert stamp.sec * 10**9 + stamp.nanosec == ns(block.t0)
            assert msg.header.frame_id == ("" if attribute is None else "wing")
            assert msg.sample_rate == RATE and msg.first_sample_index == block.first_index
            expected = block.force[None] if attribute is None else getattr(block, attribute)
            for row, field in zip(expected, fields, strict=True):
                np.testing.assert_array_equal(getattr(msg, field), row)
        condition = got["/flight/condition"][k].message
        assert (condition.airspeed, condition.air_density) == (block.airspeed[0],
                                                                block.density[0])
        assert condition.header.stamp.sec * 10**9 + condition.header.stamp.nanosec == ns(
            block.t0)
        damper = got["/dva/damper_state"][k].message
        state = states[k]
        assert damper.header.stamp.sec * 10**9 + damper.header.stamp.nanosec == ns(state.time)
        assert damper.applied_damping == state.applied_damping
        assert damper.source == state.source and damper.status == int(state.status)
        assert (math.isnan(damper.commanded_damping) if math.isnan(state.commanded_damping)
                else damper.commanded_damping == state.commanded_damping)
    (diagnostics,) = got["/diagnostics"]
    status = diagnostics.message.status[0]
    assert (status.name, status.message, status.hardware_id) == (
        "simulator: flight", "flight completed", "aero_dva_sim")
    assert {kv.key: kv.value for kv in status.values} == {"sim_time_s": "5.967",
                                                          "published": "120"}


def test_sequence_numbers_and_file_order(bag):
    """Per-topic sequence numbers count from 0; the file holds blocks in publish order."""
    with open(bag / "run_0.mcap", "rb") as stream:
        records = list(make_reader(stream).iter_messages(log_time_order=False))
    topics = [channel.topic for _, channel, _ in records]
    assert topics[:6] == list(TOPICS)[:6] and topics[-1] == "/diagnostics"
    for topic in TOPICS:
        assert [m.sequence for _, c, m in records if c.topic == topic] == list(
            range(topics.count(topic)))
    log_times = [m.log_time for _, _, m in records]
    assert log_times == sorted(log_times)


def test_flight_log_loads_the_exact_arrays(bag, flight):
    blocks, states = flight
    log = load_flight_log(bag)
    assert log.sample_rate == RATE and log.missing_samples == 0
    np.testing.assert_array_equal(log.displacements,
                                  np.concatenate([b.displacements for b in blocks], axis=1))
    np.testing.assert_array_equal(log.accelerations,
                                  np.concatenate([b.accelerations for b in blocks], axis=1))
    np.testing.assert_array_equal(log.force, np.concatenate([b.force for b in blocks]))
    n = sum(b.force.size for b in blocks)
    np.testing.assert_array_equal(log.time, np.arange(n) / RATE)
    starts = np.repeat([b.airspeed[0] for b in blocks], [b.force.size for b in blocks])
    np.testing.assert_array_equal(log.airspeed, starts)
    assert log.diagnostics[0]["message"] == "flight completed"
    assert log.diagnostics[0]["level"] == 0


def test_rosbags_reads_the_bag(bag, flight):
    """An independent reader decodes the same values."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    blocks, _ = flight
    typestore = get_typestore(Stores.EMPTY)
    with Reader(bag) as reader:
        for connection in reader.connections:
            typestore.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        displacement = [
            typestore.deserialize_cdr(raw, c.msgtype)
            for c, _, raw in reader.messages() if c.topic == "/wing/displacement"]
    assert len(displacement) == len(blocks)
    np.testing.assert_array_equal(displacement[-1].absorber_stroke, blocks[-1].displacements[3])
    assert displacement[-1].first_sample_index == blocks[-1].first_index


# --------------------------------------------------------------------------------------------
# The batch recorder writes what rosbags + mcap's writer write, byte for byte
# --------------------------------------------------------------------------------------------


def _record(path, flight, compression, chunk_size):
    blocks, states = flight
    with BatchRecorder(path, RATE, compression=compression,
                       chunk_size=chunk_size) as recorder:
        recorder.write_blocks(blocks[:33], states[:33])
        recorder.write_diagnostics(1.0, [("warn", "no damper command within 0.5 s", {})])
        for start in range(33, len(blocks), 10):  # equal runs: work buffers are reused
            recorder.write_blocks(blocks[start:start + 10], states[start:start + 10])
        recorder.write_diagnostics(blocks[-1].t_end, [("error", "diverged", {"u": 1.5})])
    return (path / f"{path.name}_0.mcap").read_bytes(), (path / "metadata.yaml").read_text()


def _reference(path, flight, compression, chunk_size):
    """The oracle: each message serialized by rosbags, written by mcap's writer."""
    blocks, states = flight
    bag = ReferenceBag(path, RATE, compression=compression, chunk_size=chunk_size)
    bag.blocks(blocks[:33], states[:33])
    bag.diagnostics(1.0, "warn", "no damper command within 0.5 s", {})
    bag.blocks(blocks[33:], states[33:])
    bag.diagnostics(blocks[-1].t_end, "error", "diverged", {"u": 1.5})
    bag.close()
    return (path / f"{path.name}_0.mcap").read_bytes(), (path / "metadata.yaml").read_text()


@pytest.mark.parametrize(("compression", "chunk_size"), [
    ("none", 1 << 20), ("none", 4000), ("none", 1), ("zstd", 1 << 20), ("zstd", 10_000),
    ("lz4", 30_000)])
def test_batch_recorder_equals_rosbags_and_mcap_byte_for_byte(tmp_path, flight, compression,
                                                              chunk_size):
    fast = _record(tmp_path / "a" / "bag", flight, compression, chunk_size)
    reference = _reference(tmp_path / "b" / "bag", flight, compression, chunk_size)
    assert fast[1] == reference[1]
    assert len(fast[0]) == len(reference[0])
    assert fast[0] == reference[0]


def test_writer_library_is_named(bag):
    with open(bag / "run_0.mcap", "rb") as stream:
        header = make_reader(stream).get_header()
    assert header.profile == "ros2" and header.library == "aero_dva.bag.batch_recorder"


# --------------------------------------------------------------------------------------------
# Options and errors
# --------------------------------------------------------------------------------------------


def test_record_flight_blocks_streams_and_namespaces(tmp_path, flight):
    blocks, states = flight
    summary = record_flight_blocks(tmp_path / "ns", iter(blocks), iter(states), RATE,
                                      batch_blocks=7, namespace="/wing1/")
    assert {t.name for t in summary.topics} == set(recorded_topics("wing1"))
    assert "/wing1/wing/acceleration" in recorded_topics("wing1")
    assert "/clock" in recorded_topics("wing1")
    log = load_flight_log(tmp_path / "ns", namespace="wing1")
    np.testing.assert_array_equal(log.force, np.concatenate([b.force for b in blocks]))
    assert summary.message_count == 6 * len(blocks)
    assert summary.starting_time_ns == ns(blocks[0].t_end)
    assert summary.duration_ns == ns(blocks[-1].t_end) - ns(blocks[0].t_end)


def test_without_damper_states_there_is_no_damper_topic(tmp_path, flight):
    blocks, _ = flight
    summary = record_flight_blocks(tmp_path / "b", blocks, None, RATE)
    assert "/dva/damper_state" not in {t.name for t in summary.topics}
    log = load_flight_log(tmp_path / "b")
    assert np.all(np.isnan(log.applied_damping))


def test_bad_input_is_refused(tmp_path, flight):
    blocks, states = flight
    with BatchRecorder(tmp_path / "x", RATE) as recorder:
        with pytest.raises(ValueError, match="damper_states is required"):
            recorder.write_blocks(blocks[:2])
        with pytest.raises(ValueError, match="2 snapshots for 3 blocks"):
            recorder.write_blocks(blocks[:3], states[:2])
        bad = replace(blocks[1], displacements=np.zeros((3, 50)))
        with pytest.raises(ValueError, match=r"blocks\[1\]\.displacements"):
            recorder.write_blocks([blocks[0], bad], states[:2])
        with pytest.raises(ValueError, match="first_index"):
            recorder.write_blocks([replace(blocks[0], first_index=0.5)], states[:1])
        with pytest.raises(ValueError, match="finite"):
            recorder.write_blocks([replace(blocks[0], sample_rate=math.nan)], states[:1])
        with pytest.raises(ValueError, match=">= 0"):
            recorder.write_blocks([replace(blocks[0], first_index=-50)], states[:1])
        with pytest.raises(ValueError, match="level"):
            recorder.write_diagnostics(0.0, [("fatal", "x", {})])
        assert recorder.message_counts == dict.fromkeys(TOPICS, 0)
    with pytest.raises(ValueError, match="closed"):
        recorder.write_blocks(blocks[:1], states[:1])
    with pytest.raises(FileExistsError):
        BatchRecorder(tmp_path / "x", RATE)
    for kwargs, match in (({"compression": "gzip"}, "compression"),
                          ({"chunk_size": 0}, "chunk_size")):
        with pytest.raises(ValueError, match=match):
            BatchRecorder(tmp_path / "y", RATE, **kwargs)
    with pytest.raises(ValueError, match="sample_rate"):
        BatchRecorder(tmp_path / "y", 0.0)
    with pytest.raises(ValueError, match="ended after 2"):
        record_flight_blocks(tmp_path / "z", blocks[:3], states[:2], RATE)
    with pytest.raises(ValueError, match="more snapshots"):
        record_flight_blocks(tmp_path / "w", blocks[:2], states[:3], RATE)


def test_lists_and_other_dtypes_are_converted(tmp_path, flight):
    blocks, states = flight
    block = blocks[0]
    as_lists = replace(block, force=block.force.tolist(),
                       accelerations=block.accelerations.astype(np.float32),
                       displacements=np.asfortranarray(block.displacements))
    record_flight_blocks(tmp_path / "l", [as_lists], states[:1], RATE)
    log = load_flight_log(tmp_path / "l")
    np.testing.assert_array_equal(log.force, block.force)
    np.testing.assert_array_equal(log.accelerations,
                                  block.accelerations.astype(np.float32).astype(float))
    np.testing.assert_array_equal(log.displacements, block.displacements)


# --------------------------------------------------------------------------------------------
# record_runtime
# --------------------------------------------------------------------------------------------


def _scenario(tmp_path: Path, text: str) -> str:
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    return str(path)


RAMP = """name: short
duration: 1.0
sample_rate: 1000.0
block_size: 50
airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}
density: {base: 1.2, variation: 0.05, frequency: 1.0}
excitation: {force_std: 1000.0, seed: 11}
"""
DIVERGING = """name: div
duration: 3.0
sample_rate: 1000.0
block_size: 50
airspeed: {kind: constant, value_ratio: 1.3}
excitation: {force_std: 1000.0, seed: 2}
"""


def _runtime(scenario: str, **params):
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    return FlightRuntime(load_runtime_config({"scenario": scenario, **params}))


def test_record_runtime_records_the_same_flight_as_stepping_it(tmp_path):
    scenario = _scenario(tmp_path, RAMP)
    seen = []
    result = record_runtime(tmp_path / "bag", _runtime(scenario), batch_blocks=6,
                               progress=lambda done, total: seen.append((done, total)))
    assert result.outcome == "completed" and result.blocks == 20 and result.samples == 1000
    assert seen[-1] == (1000, 1000) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    twin = _runtime(scenario)  # same seed -> same data
    blocks, states = [], []
    while not twin.done:
        blocks.append(twin.step())
        states.append(twin.flown_damper)
    log = load_flight_log(tmp_path / "bag")
    np.testing.assert_array_equal(log.displacements,
                                  np.concatenate([b.displacements for b in blocks], axis=1))
    np.testing.assert_array_equal(log.accelerations,
                                  np.concatenate([b.accelerations for b in blocks], axis=1))
    np.testing.assert_array_equal(log.force, np.concatenate([b.force for b in blocks]))
    conditions = [m.message for m in read_messages(tmp_path / "bag", ["/flight/condition"])]
    assert [c.airspeed for c in conditions] == [b.airspeed[0] for b in blocks]
    assert [c.air_density for c in conditions] == [b.density[0] for b in blocks]
    dampers = [m.message for m in read_messages(tmp_path / "bag", ["/dva/damper_state"])]
    assert [d.applied_damping for d in dampers] == [s.applied_damping for s in states]
    (diagnostic,) = log.diagnostics
    assert diagnostic["name"] == "simulator: flight" and diagnostic["level"] == 0
    assert diagnostic["message"] == "flight completed"
    values = diagnostic["values"]
    assert values["sim_time_s"] == "1" and values["published:wing/acceleration"] == "20"
    assert set(values) == {"sim_time_s", "wall_time_s", "real_time_factor",
                           "critical_airspeed_no_dva", "published:wing/acceleration",
                           "published:wing/displacement", "published:wing/excitation",
                           "published:flight/condition", "published:dva/damper_state"}
    assert float(values["critical_airspeed_no_dva"]) == pytest.approx(
        twin.critical_airspeed, rel=1e-8)


def test_record_runtime_stops_at_divergence_like_the_node(tmp_path):
    result = record_runtime(tmp_path / "bag", _runtime(_scenario(tmp_path, DIVERGING)))
    assert result.outcome == "diverged" and result.sim_time < 3.0
    log = load_flight_log(tmp_path / "bag")
    assert log.time.size == result.samples == 50 * result.blocks
    (diagnostic,) = log.diagnostics
    assert diagnostic["level"] == 2
    assert diagnostic["message"].startswith("flight stopped at U = ")
    assert diagnostic["message"].endswith("after the wing diverged")
    assert "(U/U_cr = 1.300, t = " in diagnostic["message"]
    assert diagnostic["values"]["published:wing/displacement"] == str(result.blocks)
    counts = {t.name: t.message_count for t in result.summary.topics}
    assert counts["/clock"] == result.blocks and counts["/diagnostics"] == 1


@dataclass
class _FakeDamper:
    stale_timeout: float = 0.5


@dataclass
class _FakeConfig:
    damper: _FakeDamper


class _FakeRuntime:
    """Goes stale after 3 blocks, as a damper without commands would (duck-typed runtime)."""

    def __init__(self, blocks, states):
        self._blocks, self._states, self._k = blocks, states, 0
        self.sample_rate = RATE
        self.critical_airspeed = 100.0
        self.config = _FakeConfig(_FakeDamper())

        class _Scenario:
            n_samples = sum(b.force.size for b in blocks)

        self.scenario = _Scenario()

    @property
    def time(self):
        return self._blocks[self._k - 1].t_end if self._k else 0.0

    @property
    def done(self):
        return self._k >= len(self._blocks)

    def step(self):
        self._k += 1
        return self._blocks[self._k - 1]

    @property
    def flown_damper(self):
        state = self._states[self._k - 1]
        if self._k >= 4:
            return replace(state, status=DamperStatus.FALLBACK_STALE, source="fallback",
                           applied_damping=640.0)
        return state


def test_record_runtime_warns_once_when_the_damper_goes_stale(tmp_path, flight):
    blocks, states = flight
    runtime = _FakeRuntime(blocks[:10], states[:10])
    result = record_runtime(tmp_path / "bag", runtime, batch_blocks=3)
    assert result.outcome == "completed"
    diagnostics = [m for m in read_messages(tmp_path / "bag") if m.topic == "/diagnostics"]
    assert len(diagnostics) == 2
    warning = diagnostics[0].message.status[0]
    assert warning.message == "no damper command within 0.5 s: fallback c2 = 640 N s/m applied"
    assert diagnostics[0].log_time_ns == ns(blocks[3].t_end)
    # The warning comes right after the block that went stale, before the next block.
    with open(tmp_path / "bag" / "bag_0.mcap", "rb") as stream:
        order = [c.topic for _, c, _ in make_reader(stream).iter_messages(log_time_order=False)]
    assert order[6 * 4] == "/diagnostics" and order[6 * 4 + 1] == "/clock"


# --------------------------------------------------------------------------------------------
# record_sweep: the sweep simulated parallel in time (aero_dva.flight.sweep_simulator)
# --------------------------------------------------------------------------------------------

# 3 airspeeds x 3 c2 x 0.6 s = 5.4 s. The airspeed steps (0.05 U_cr) are above the runtime's
# 0.1 % hold quantum, so every dwell is its own segment; 1.0 U_cr with c2 = 60 N s/m grows, but
# not for long enough to diverge.
SWEEP = """name: mini
duration: auto
sample_rate: 1000.0
block_size: 50
airspeed: {kind: steps, ratios: [0.9, 0.95, 1.0]}
density: {base: 1.2}
excitation: {force_std: 1000.0, seed: 5}
sweep: {dwell: 0.6, damping: [60.0, 400.0, 1100.0]}
"""


def _stepped(runtime):
    blocks, states = [], []
    while not runtime.done:
        blocks.append(runtime.step())
        states.append(runtime.flown_damper)
    return blocks, states


def _raw_messages(bag: Path):
    (path,) = bag.glob("*.mcap")
    with open(path, "rb") as stream:
        return [(c.topic, m.log_time, m.sequence, m.data)
                for _, c, m in make_reader(stream).iter_messages(log_time_order=False)]


def test_parallel_sweep_equals_the_stepped_runtime_sample_by_sample(tmp_path):
    from aero_dva.flight import sweep_simulator

    runtime = _runtime(_scenario(tmp_path, SWEEP))
    plan = sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    assert plan.lengths.tolist() == [600] * 9  # one segment per dwell
    chunks = list(sweep_simulator.simulate_sweep(runtime.config, plan, chunk_samples=1300))
    assert [c.first_index for c in chunks] == [0, 1200, 2400, 3600, 4800]
    blocks, _ = _stepped(_runtime(_scenario(tmp_path, SWEEP)))
    force = np.concatenate([b.force for b in blocks])
    np.testing.assert_array_equal(np.concatenate([c.force for c in chunks]), force)
    for name in ("displacements", "accelerations"):
        fast = np.concatenate([getattr(c, name) for c in chunks], axis=1)
        ref = np.concatenate([getattr(b, name) for b in blocks], axis=1)
        scale = np.abs(ref).max(axis=1, keepdims=True)
        assert np.all(scale > 0)
        assert np.max(np.abs(fast - ref) / scale) < 1e-9, name


def test_record_sweep_writes_the_runtimes_bag(tmp_path):
    scenario = _scenario(tmp_path, SWEEP)
    seen = []
    fast = sr.record_sweep(tmp_path / "fast", _runtime(scenario),
                           progress=lambda done, total: seen.append((done, total)))
    ref = record_runtime(tmp_path / "ref", _runtime(scenario))
    assert (fast.method, ref.method) == ("parallel", "stepped")
    assert (fast.outcome, fast.samples, fast.blocks) == ("completed", 5400, 108)
    assert (fast.sim_time, fast.blocks) == (ref.sim_time, ref.blocks)
    assert seen[-1] == (5400, 5400)
    a, b = _raw_messages(tmp_path / "fast"), _raw_messages(tmp_path / "ref")
    assert [m[:3] for m in a] == [m[:3] for m in b]  # topics, log times, sequence numbers
    for (topic, _, _, data), (_, _, _, ref_data) in zip(a, b):
        if topic in ("/clock", "/wing/excitation", "/flight/condition", "/dva/damper_state"):
            assert data == ref_data, topic  # byte for byte
        elif topic != "/diagnostics":  # its wall times' digits vary: compared below
            assert len(data) == len(ref_data), topic
    log, ref_log = load_flight_log(tmp_path / "fast"), load_flight_log(tmp_path / "ref")
    timing = ("wall_time_s", "real_time_factor")

    def untimed(diagnostics):
        return [{**d, "values": {k: v for k, v in d["values"].items() if k not in timing}}
                for d in diagnostics]

    assert log.diagnostics and untimed(log.diagnostics) == untimed(ref_log.diagnostics)
    np.testing.assert_array_equal(log.force, ref_log.force)
    np.testing.assert_array_equal(log.applied_damping, ref_log.applied_damping)
    np.testing.assert_array_equal(log.airspeed, ref_log.airspeed)
    scale = np.abs(ref_log.displacements).max(axis=1, keepdims=True)
    assert np.max(np.abs(log.displacements - ref_log.displacements) / scale) < 1e-9
    (diagnostic,) = log.diagnostics
    (ref_diagnostic,) = ref_log.diagnostics
    assert diagnostic["message"] == ref_diagnostic["message"] == "flight completed"
    assert diagnostic["values"].keys() == ref_diagnostic["values"].keys()
    for key, value in ref_diagnostic["values"].items():
        if key not in ("wall_time_s", "real_time_factor"):
            assert diagnostic["values"][key] == value, key


def test_record_sweep_blocks_across_chunk_boundaries(tmp_path):
    # 70-sample blocks do not divide the 600-sample dwells: blocks straddle the chunks.
    scenario = _scenario(tmp_path, SWEEP.replace("block_size: 50", "block_size: 70"))
    fast = sr.record_sweep(tmp_path / "fast", _runtime(scenario), chunk_samples=1300)
    ref = record_runtime(tmp_path / "ref", _runtime(scenario))
    assert fast.method == "parallel" and fast.blocks == ref.blocks == 78
    a, b = _raw_messages(tmp_path / "fast"), _raw_messages(tmp_path / "ref")
    assert [m[:3] for m in a] == [m[:3] for m in b]
    assert [m[3] for m in a if m[0] == "/wing/excitation"] == \
        [m[3] for m in b if m[0] == "/wing/excitation"]
    assert [m[3] for m in a if m[0] == "/dva/damper_state"] == \
        [m[3] for m in b if m[0] == "/dva/damper_state"]
    log, ref_log = load_flight_log(tmp_path / "fast"), load_flight_log(tmp_path / "ref")
    scale = np.abs(ref_log.accelerations).max(axis=1, keepdims=True)
    assert np.max(np.abs(log.accelerations - ref_log.accelerations) / scale) < 1e-9


def test_record_sweep_with_dwell_sized_blocks_keeps_the_samples(tmp_path):
    scenario = _scenario(tmp_path, SWEEP)
    result = sr.record_sweep(tmp_path / "big", _runtime(scenario), block_size=600)
    assert result.blocks == 9
    counts = {t.name: t.message_count for t in result.summary.topics}
    assert counts["/wing/acceleration"] == counts["/dva/damper_state"] == 9
    small = load_flight_log(tmp_path / "big")
    sr.record_sweep(tmp_path / "small", _runtime(scenario))
    np.testing.assert_array_equal(small.displacements,
                                  load_flight_log(tmp_path / "small").displacements)
    np.testing.assert_array_equal(small.applied_damping, np.repeat(
        np.tile([60.0, 400.0, 1100.0], 3), 600))
    with pytest.raises(ValueError, match="must divide the dwell"):
        sr.record_sweep(tmp_path / "odd", _runtime(scenario), block_size=250)


def test_record_sweep_stops_at_divergence_like_the_runtime(tmp_path):
    text = SWEEP.replace("ratios: [0.9, 0.95, 1.0]", "ratios: [0.9, 1.3]").replace(
        "dwell: 0.6", "dwell: 2.0")
    scenario = _scenario(tmp_path, text)
    fast = sr.record_sweep(tmp_path / "fast", _runtime(scenario))
    ref = record_runtime(tmp_path / "ref", _runtime(scenario))
    assert fast.outcome == ref.outcome == "diverged"
    assert (fast.samples, fast.blocks) == (ref.samples, ref.blocks)
    (diagnostic,) = load_flight_log(tmp_path / "fast").diagnostics
    (ref_diagnostic,) = load_flight_log(tmp_path / "ref").diagnostics
    assert diagnostic["message"] == ref_diagnostic["message"]
    assert diagnostic["level"] == 2


def test_record_sweep_steps_what_it_does_not_model(tmp_path):
    from aero_dva.flight import sweep_simulator

    varying = SWEEP.replace("density: {base: 1.2}",
                            "density: {base: 1.2, variation: 0.05, frequency: 1.0}")
    runtime = _runtime(_scenario(tmp_path, varying))
    assert "density varies" in sweep_simulator.unsupported_reason(runtime.config, runtime.scenario)
    with pytest.raises(ValueError, match="density varies"):
        sweep_simulator.plan_sweep(runtime.config, runtime.scenario)
    result = sr.record_sweep(tmp_path / "bag", runtime)
    assert result.method == "stepped" and result.samples == 5400
    ramp = _runtime(_scenario(tmp_path, RAMP))
    assert "not a stepped sweep" in sweep_simulator.unsupported_reason(ramp.config, ramp.scenario)


def test_sweep_damper_states_equal_the_damper_model(tmp_path):
    from aero_dva.flight.damper import DamperConfig

    t0 = np.arange(40) * 0.05
    c2 = np.repeat([300.0, 2400.0, 900.0, 3000.0], 10)
    for config in (DamperConfig(0.0, 2500.0, 500.0),
                   DamperConfig(0.0, 2500.0, 500.0, time_constant=0.08)):
        from aero_dva.flight.damper import DamperModel

        model = DamperModel(config)
        expected = []
        for t, c in zip(t0, c2):
            model.command(float(c), float(t), "sweep")
            model.update(float(t))
            s = model.snapshot()
            expected.append((s.time, s.commanded_damping, s.applied_damping, s.min_damping,
                             s.max_damping, s.command_age, int(s.status)))
        got = sr._sweep_damper_states(config, t0, c2)
        np.testing.assert_array_equal(np.column_stack([got[k] for k in (
            "time", "commanded_damping", "applied_damping", "min_damping", "max_damping",
            "command_age", "status")]), np.array(expected))
    ideal = sr._sweep_damper_states(DamperConfig(0.0, 2500.0, 500.0), t0[:10], c2[:10])
    assert np.all(ideal["status"] == 0) and np.all(ideal["applied_damping"] == 300.0)


def test_write_samples_equals_write_blocks(tmp_path, flight):
    blocks, states = flight
    blocks, states = blocks[:-1], [replace(s, source="sweep") for s in states[:-1]]
    acc = np.concatenate([b.accelerations for b in blocks], axis=1)
    disp = np.concatenate([b.displacements for b in blocks], axis=1)
    force = np.concatenate([b.force for b in blocks])
    columns = dict(zip(DAMPER_COLUMNS, np.array(
        [(s.time, s.commanded_damping, s.applied_damping, s.min_damping, s.max_damping,
          s.command_age, int(s.status)) for s in states]).T))
    ref_blocks = blocks  # blocks of 50, t0 = index / rate as write_samples stamps them
    with BatchRecorder(tmp_path / "samples", RATE) as recorder:
        recorder.write_samples(0, acc[:, :2000], disp[:, :2000], force[:2000], block_size=50,
                               airspeed=[b.airspeed[0] for b in blocks[:40]],
                               density=[b.density[0] for b in blocks[:40]],
                               damper={k: v[:40] for k, v in columns.items()}, source="sweep")
        count = recorder.write_samples(
            2000, acc[:, 2000:], disp[:, 2000:], force[2000:], block_size=50,
            airspeed=[b.airspeed[0] for b in blocks[40:]],
            density=[b.density[0] for b in blocks[40:]],
            damper={k: v[40:] for k, v in columns.items()}, source="sweep")
        assert count == len(blocks) - 40
    with BatchRecorder(tmp_path / "blocks", RATE) as recorder:
        recorder.write_blocks(ref_blocks, states)
    reference = ReferenceBag(tmp_path / "reference", RATE)
    reference.blocks(ref_blocks, states)
    reference.close()
    ref = _raw_messages(tmp_path / "reference")
    assert _raw_messages(tmp_path / "samples") == ref
    assert _raw_messages(tmp_path / "blocks") == ref


def test_write_samples_ends_with_a_shorter_block_and_checks_input(tmp_path):
    rng = np.random.default_rng(3)
    acc, disp, force = rng.standard_normal((3, 130)), rng.standard_normal((4, 130)), \
        rng.standard_normal(130)
    with BatchRecorder(tmp_path / "bag", RATE, damper_state=False) as recorder:
        assert recorder.write_samples(100, acc, disp, force, block_size=50,
                                      airspeed=[80.0, 81.0, 82.0], density=[1.2] * 3) == 3
        with pytest.raises(ValueError, match=r"accelerations must have shape \(3, T\)"):
            recorder.write_samples(0, acc[:2], disp, force, block_size=50, airspeed=[1.0] * 3,
                                   density=[1.2] * 3)
        with pytest.raises(ValueError, match=r"airspeed must have shape \(3,\)"):
            recorder.write_samples(0, acc, disp, force, block_size=50, airspeed=[1.0],
                                   density=[1.2] * 3)
        with pytest.raises(ValueError, match="block_size"):
            recorder.write_samples(0, acc, disp, force, block_size=0, airspeed=[1.0],
                                   density=[1.2])
        with pytest.raises(ValueError, match="no dva/damper_state"):
            recorder.write_samples(0, acc, disp, force, block_size=50, airspeed=[1.0] * 3,
                                   density=[1.2] * 3, damper={})
    log = load_flight_log(tmp_path / "bag")
    np.testing.assert_array_equal(log.force[100:], force)
    np.testing.assert_array_equal(log.accelerations[:, 100:], acc)
    assert np.all(np.isnan(log.force[:100]))
    conditions = [m.message for m in read_messages(tmp_path / "bag", ["/flight/condition"])]
    assert [c.airspeed for c in conditions] == [80.0, 81.0, 82.0]
    blocks = [m.message for m in read_messages(tmp_path / "bag", ["/wing/excitation"])]
    assert [(b.first_sample_index, len(b.aileron_force)) for b in blocks] == [
        (100, 50), (150, 50), (200, 30)]


def test_chunk_crc_can_be_left_out(tmp_path, flight):
    blocks, states = flight
    for crc in (True, False):
        with BatchRecorder(tmp_path / f"c{crc}", RATE, chunk_crc=crc,
                              chunk_size=20_000) as recorder:
            recorder.write_blocks(blocks, states)
    with open(tmp_path / "cTrue" / "cTrue_0.mcap", "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        assert sum(1 for _ in reader.iter_messages()) == 6 * len(blocks)
    crcs = {}
    for name in ("cTrue", "cFalse"):
        with open(tmp_path / name / f"{name}_0.mcap", "rb") as stream:
            records = StreamReader(stream, emit_chunks=True).records
            crcs[name] = [r.uncompressed_crc for r in records if isinstance(r, Chunk)]
    assert len(crcs["cFalse"]) > 3 and set(crcs["cFalse"]) == {0}
    assert len(crcs["cTrue"]) == len(crcs["cFalse"]) and 0 not in crcs["cTrue"]
    assert _raw_messages(tmp_path / "cFalse") == _raw_messages(tmp_path / "cTrue")
