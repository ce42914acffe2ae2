"""rosbag2-layout MCAP writing and reading without rclpy, checked against mcap-ros2 and rosbags."""

import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from aero_dva.bag import schemas
from aero_dva.bag.reader import (
    BagReadError,
    MessageTypeError,
    TopicNotFoundError,
    bag_topics,
    deserialize,
    read_messages,
)
from aero_dva.bag.schemas import message_definition, typestore
from aero_dva.bag.writer import BagWriter, message_from_dict, qos_profile_yaml

ACC = "dva_msgs/msg/AccelerationBlock"
FLIGHT = "dva_msgs/msg/FlightCondition"
COMMAND = "dva_msgs/msg/DamperCommand"


def stamp(t):
    return {"sec": int(t), "nanosec": int(round((t % 1) * 1e9))}


def acceleration(k):
    rng = np.random.default_rng(k)
    return {
        "header": {"stamp": stamp(0.02 * k), "frame_id": "wing"},
        "sample_rate": 1000.0,
        "first_sample_index": 20 * k,
        "plunge": rng.standard_normal(20),
        "pitch": rng.standard_normal(20),
        "leading_edge": rng.standard_normal(20),
    }


def flight(k):
    return {"header": {"stamp": stamp(0.1 * k)}, "airspeed": 80.0 + k, "air_density": 1.2}


def command(k):
    return {
        "header": {"stamp": stamp(0.1 * k)},
        "damping": 500.0 + 10 * k,
        "source": "rbf_network",
    }


N_ACC, N_FLIGHT, N_CMD = 50, 10, 8


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    directory = tmp_path_factory.mktemp("bags") / "run"
    with BagWriter(directory) as writer:
        writer.add_topic("wing/acceleration", ACC, qos_profile_yaml("best_effort"))
        writer.add_topic("/flight/condition", FLIGHT)
        writer.add_topic("dva/damper_command", "dva_msgs/DamperCommand")
        store = typestore()
        for k in range(N_ACC):
            writer.write("wing/acceleration", acceleration(k), log_time_ns=20_000_000 * k)
            if k % 5 == 0:
                writer.write("flight/condition", flight(k // 5), log_time_ns=20_000_000 * k + 1)
        for k in range(N_CMD):
            message = command(k)
            if k % 2:  # already-CDR bytes, as from a raw rclpy subscription
                message = bytes(store.serialize_cdr(message_from_dict(COMMAND, message),
                                                    COMMAND))
            writer.write("dva/damper_command", message, log_time_ns=100_000_000 * k + 2)
    return directory


def test_layout_and_metadata(bag):
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml", "run_0.mcap"]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] >= 5 and info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["run_0.mcap"]
    counts = {
        t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]
    }
    assert counts == {
        "/wing/acceleration": N_ACC,
        "/flight/condition": N_FLIGHT,
        "/dva/damper_command": N_CMD,
    }
    assert info["message_count"] == N_ACC + N_FLIGHT + N_CMD
    assert info["starting_time"]["nanoseconds_since_epoch"] == 0
    assert info["duration"]["nanoseconds"] == 20_000_000 * (N_ACC - 1)
    assert info["files"][0]["message_count"] == info["message_count"]


def test_mcap_file_follows_the_ros2_profile(bag):
    with open(bag / "run_0.mcap", "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        schemas = {s.name: s for s in summary.schemas.values()}
        assert set(schemas) == {ACC, FLIGHT, COMMAND}
        assert {s.encoding for s in schemas.values()} == {"ros2msg"}
        assert schemas[COMMAND].data.decode() == message_definition(COMMAND)
        channels = {c.topic: c for c in summary.channels.values()}
        assert {c.message_encoding for c in channels.values()} == {"cdr"}
        qos = yaml.safe_load(channels["/wing/acceleration"].metadata["offered_qos_profiles"])
        assert qos[0]["reliability"] == 2 and qos[0]["depth"] == 10  # best effort
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        assert yaml.safe_load(metadata["rosbag2"]["serialized_metadata"])["message_count"] == 68


def test_own_reader_returns_every_message(bag):
    got = list(
        read_messages(bag, ["wing/acceleration", "/flight/condition", "dva/damper_command"])
    )
    by_topic = {}
    for m in got:
        by_topic.setdefault(m.topic, []).append(m)
    assert {t: len(v) for t, v in by_topic.items()} == {
        "/wing/acceleration": N_ACC,
        "/flight/condition": N_FLIGHT,
        "/dva/damper_command": N_CMD,
    }
    for k, m in enumerate(by_topic["/wing/acceleration"]):
        assert m.type_name == ACC and m.log_time_ns == 20_000_000 * k
        np.testing.assert_array_equal(m.message.plunge, acceleration(k)["plunge"])
        assert m.message.first_sample_index == 20 * k
    assert [m.message.damping for m in by_topic["/dva/damper_command"]] == [
        500.0 + 10 * k for k in range(N_CMD)
    ]
    assert [m.message.airspeed for m in by_topic["/flight/condition"]] == [
        80.0 + k for k in range(N_FLIGHT)
    ]
    assert [m.log_time_ns for m in got] == sorted(m.log_time_ns for m in got)


def test_mcap_ros2_reads_the_file_directly(bag):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from mcap_ros2.reader import read_ros2_messages

        messages = list(read_ros2_messages(str(bag / "run_0.mcap")))
    counts = {}
    for m in messages:
        counts[m.channel.topic] = counts.get(m.channel.topic, 0) + 1
    assert counts == {
        "/wing/acceleration": N_ACC,
        "/flight/condition": N_FLIGHT,
        "/dva/damper_command": N_CMD,
    }
    flights = [m.ros_msg for m in messages if m.channel.topic == "/flight/condition"]
    assert flights[3].airspeed == 83.0 and flights[3].header.stamp.nanosec == 300_000_000


def test_rosbags_reads_the_directory(bag):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    typestore = get_typestore(Stores.EMPTY)
    with Reader(bag) as reader:
        for connection in reader.connections:
            typestore.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        assert reader.message_count == N_ACC + N_FLIGHT + N_CMD
        qos = {c.topic: c.ext.offered_qos_profiles[0] for c in reader.connections}
        assert qos["/wing/acceleration"].reliability.name == "BEST_EFFORT"
        seen = {}
        for connection, timestamp, raw in reader.messages():
            msg = typestore.deserialize_cdr(raw, connection.msgtype)
            seen.setdefault(connection.topic, []).append((timestamp, msg))
    assert {t: len(v) for t, v in seen.items()} == {
        "/wing/acceleration": N_ACC,
        "/flight/condition": N_FLIGHT,
        "/dva/damper_command": N_CMD,
    }
    timestamp, last = seen["/wing/acceleration"][-1]
    assert timestamp == 20_000_000 * (N_ACC - 1)
    np.testing.assert_array_equal(last.leading_edge, acceleration(N_ACC - 1)["leading_edge"])
    assert [m.source for _, m in seen["/dva/damper_command"]] == ["rbf_network"] * N_CMD


def test_the_project_typestore_reads_a_bag_with_rosbags_as_its_examples_do(bag):
    """``aero_dva.bag.typestore()`` in place of rosbags' Jazzy store (docs/bags.md): every
    message decodes; the Jazzy store alone does not know the project's types."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    import aero_dva.bag

    jazzy, store = get_typestore(Stores.ROS2_JAZZY), aero_dva.bag.typestore()
    with Reader(bag) as reader:
        decoded = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages()]
        connection, _, raw = next(reader.messages())
        with pytest.raises(KeyError, match="dva_msgs/msg/"):
            jazzy.deserialize_cdr(raw, connection.msgtype)
    assert len(decoded) == N_ACC + N_FLIGHT + N_CMD
    assert sorted(m.damping for m in decoded if hasattr(m, "damping")) == [
        command(k)["damping"] for k in range(N_CMD)]


def test_schema_text_has_rosbag2_layout():
    text = message_definition(ACC)
    own = (
        Path(__file__).resolve().parents[4] / "ros_ws/src/dva_msgs/msg/AccelerationBlock.msg"
    ).read_text()
    assert text.startswith(own)
    parts = text[len(own) :].split("\n" + "=" * 80 + "\n")
    assert parts[0] == ""
    assert [p.splitlines()[0] for p in parts[1:]] == [
        "MSG: std_msgs/Header",
        "MSG: builtin_interfaces/Time",
    ]
    assert "uint64 first_sample_index" in text and "# [m/s^2]" in text  # comments stay


def test_standard_types_without_files_come_from_rosbags(monkeypatch, tmp_path):
    """With no ROS 2 interface files installed, the definition is rosbags' own, and it
    parses to the same fields as the installed file."""
    from rosbags.typesys import get_types_from_msg

    installed = schemas.find_message_file("std_msgs/msg/Header")
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    monkeypatch.setattr(sys, "prefix", str(tmp_path))  # no share/ of an environment either
    assert schemas.find_message_file("std_msgs/msg/Header") is None
    generated = message_definition("std_msgs/Header")
    assert generated.startswith("builtin_interfaces/Time stamp\nstring frame_id\n")
    assert "MSG: builtin_interfaces/Time" in generated
    if installed is not None:
        name = "std_msgs/msg/Header"
        from_file = get_types_from_msg(installed.read_text(), name)[name]
        assert get_types_from_msg(generated, name)[name] == from_file
    with pytest.raises(schemas.MessageDefinitionNotFound, match="no .msg file for 'pkg_a/X'"):
        message_definition("pkg_a/X")


def test_dependencies_come_depth_first_and_once(tmp_path):
    msg = tmp_path / "pkg_a" / "msg"
    msg.mkdir(parents=True)
    (msg / "Root.msg").write_text(
        "# root\nInner inner\npkg_a/Leaf[] leaves\nstd_msgs/Header header\n"
    )
    (msg / "Inner.msg").write_text("Leaf leaf\nint32 X = 3\n")
    (msg / "Leaf.msg").write_text("float64 value  # [m]\n")
    text = message_definition("pkg_a/Root", msg_dirs=[tmp_path])
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert headers == [
        "MSG: pkg_a/Inner",
        "MSG: pkg_a/Leaf",
        "MSG: std_msgs/Header",
        "MSG: builtin_interfaces/Time",
    ]
    assert text.index("MSG: pkg_a/Leaf") < text.index("MSG: std_msgs/Header")
    # A package's msg directory itself is also accepted.
    assert message_definition("pkg_a/Root", msg_dirs=[msg]) == text
    with pytest.raises(
        schemas.MessageDefinitionNotFound, match="no .msg file for 'pkg_a/Missing'"
    ):
        message_definition("pkg_a/Missing", msg_dirs=[tmp_path])


def test_missing_topic_lists_what_exists(bag):
    with pytest.raises(TopicNotFoundError, match="'/wing/displacement'") as info:
        read_messages(bag, ["/wing/displacement"])
    assert "/wing/acceleration" in str(info.value) and "/dva/damper_command" in str(info.value)


def test_wrong_type_is_reported(bag):
    with pytest.raises(MessageTypeError, match="carries 'dva_msgs/msg/FlightCondition'"):
        read_messages(bag, expected_types={"flight/condition": "dva_msgs/ScaledSpectrum"})
    good = read_messages(bag, expected_types={"flight/condition": FLIGHT})
    assert len(list(good)) == N_ACC + N_FLIGHT + N_CMD  # topics=None: all topics


def test_truncated_file_is_reported_and_can_be_salvaged(tmp_path):
    directory = tmp_path / "run"
    with BagWriter(directory, chunk_size=4096) as writer:  # several chunks, as in a long run
        writer.add_topic("wing/acceleration", ACC)
        for k in range(N_ACC):
            writer.write("wing/acceleration", acceleration(k), log_time_ns=k)
    mcap = directory / "run_0.mcap"
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * 0.6)])
    with pytest.raises(BagReadError, match="run_0.mcap.*truncated or corrupt"):
        read_messages(directory, ["wing/acceleration"])
    with pytest.warns(RuntimeWarning, match="ends early"):
        salvaged = list(read_messages(directory, ["wing/acceleration"], allow_truncated=True))
    # Whole chunks before the cut come back intact and in order; the cut chunk is lost.
    assert N_ACC // 3 < len(salvaged) < N_ACC
    for k, m in enumerate(salvaged):
        np.testing.assert_array_equal(m.message.pitch, acceleration(k)["pitch"])


def test_unfinished_and_missing_bags(bag, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(bag, copy)
    (copy / "metadata.yaml").unlink()
    with pytest.raises(BagReadError, match="no metadata.yaml: the recording was not closed"):
        bag_topics(copy)
    assert set(bag_topics(copy, allow_truncated=True)) == {
        "/wing/acceleration",
        "/flight/condition",
        "/dva/damper_command",
    }
    with pytest.raises(BagReadError, match="does not exist"):
        read_messages(tmp_path / "nowhere")
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 64)
    with pytest.raises(BagReadError, match="garbage.mcap"):
        read_messages(garbage)


def test_close_is_idempotent_and_keeps_messages_after_an_error(tmp_path):
    directory = tmp_path / "crash"
    with pytest.raises(RuntimeError, match="boom"):
        with BagWriter(directory) as writer:
            writer.add_topic("flight/condition", FLIGHT)
            for k in range(3):
                writer.write("flight/condition", flight(k), log_time_ns=k)
            raise RuntimeError("boom")
    assert writer.closed
    summary = writer.close()  # second close: no error, same summary
    assert summary.message_count == 3 and summary.topics[0].name == "/flight/condition"
    assert len(list(read_messages(directory))) == 3


def test_writer_validates_its_input(tmp_path):
    with BagWriter(tmp_path / "b") as writer:
        writer.add_topic("flight/condition", FLIGHT)
        with pytest.raises(ValueError, match="not registered"):
            writer.write("dva/damper_command", command(0), log_time_ns=0)
        with pytest.raises(ValueError, match="cannot encode"):
            writer.write("flight/condition", {"airspeed": "fast"}, log_time_ns=0)
        with pytest.raises(ValueError, match="log_time_ns"):
            writer.write("flight/condition", flight(0), log_time_ns=-1)
        with pytest.raises(ValueError, match="already registered"):
            writer.add_topic("flight/condition", COMMAND)
    with pytest.raises(ValueError, match="closed"):
        writer.write("flight/condition", flight(0), log_time_ns=0)
    with pytest.raises(FileExistsError, match="not empty"):
        BagWriter(tmp_path / "b")


def test_flushed_messages_survive_a_writer_that_never_closes(tmp_path):
    writer = BagWriter(tmp_path / "live")
    writer.add_topic("flight/condition", FLIGHT)
    for k in range(10):
        writer.write("flight/condition", flight(k), log_time_ns=k)
    writer.flush()
    snapshot = tmp_path / "crashed"
    shutil.copytree(tmp_path / "live", snapshot)  # what a crash right now would leave
    writer.close()
    (snapshot / "live_0.mcap").rename(snapshot / "crashed_0.mcap")
    with pytest.raises(BagReadError, match="not closed"):
        read_messages(snapshot)
    with pytest.warns(RuntimeWarning, match="ends early"):
        salvaged = list(read_messages(snapshot, allow_truncated=True))
    assert [m.message.airspeed for m in salvaged] == [80.0 + k for k in range(10)]


def test_raw_bytes_and_deserialize_give_the_decoded_messages(bag):
    """What a bag player does: raw CDR with log times, decoded later with the bag's schema."""
    raw = list(read_messages(bag, ["/flight/condition"], decode=False))
    decoded = list(read_messages(bag, ["/flight/condition"]))
    assert [m.log_time_ns for m in raw] == [m.log_time_ns for m in decoded]
    for r, d in zip(raw, decoded, strict=True):
        assert isinstance(r.message, bytes) and r.type_name == FLIGHT
        assert r.schema_text == message_definition(FLIGHT)
        assert deserialize(r.message, r.type_name, r.schema_text) == d.message
        assert deserialize(r.message, r.type_name).airspeed == d.message.airspeed
    with pytest.raises(BagReadError, match="do not decode as dva_msgs/msg/FlightCondition"):
        deserialize(raw[0].message[:12], FLIGHT)


def test_a_type_the_project_does_not_know_is_decoded_by_the_bags_schema(tmp_path):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    msg = tmp_path / "pkg_b" / "msg"
    msg.mkdir(parents=True)
    (msg / "Probe.msg").write_text("std_msgs/Header header\nint16[] counts\nstring label\n")
    text = message_definition("pkg_b/Probe", msg_dirs=[tmp_path])
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(text, "pkg_b/msg/Probe"))
    Probe = store.types["pkg_b/msg/Probe"]
    values = Probe(header=store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=3, nanosec=4), frame_id="p"),
        counts=np.array([1, -2, 3], dtype=np.int16), label="x")
    with BagWriter(tmp_path / "bag", msg_dirs=[tmp_path]) as writer:
        writer.add_topic("probe", "pkg_b/Probe")
        writer.write("probe", bytes(store.serialize_cdr(values, "pkg_b/msg/Probe")), 7)
        with pytest.raises(ValueError, match="not in the project's typestore"):
            writer.write("probe", {"label": "y"}, 8)
    (got,) = read_messages(tmp_path / "bag")
    assert got.type_name == "pkg_b/msg/Probe" and got.message.label == "x"
    np.testing.assert_array_equal(got.message.counts, [1, -2, 3])
    with pytest.raises(BagReadError, match="pkg_b/msg/Probe is unknown"):
        deserialize(b"\0\1\0\0", "pkg_b/Probe")


def test_an_old_definition_in_a_bag_is_decoded_by_that_definition(tmp_path):
    """A bag recorded before a field was added to a .msg file still reads."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    text = "std_msgs/Header header\nfloat64 airspeed\n\n" + "=" * 80 + \
        "\nMSG: std_msgs/Header\n" + message_definition("std_msgs/Header")
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(text, FLIGHT))
    data = bytes(store.serialize_cdr(store.types[FLIGHT](header=store.types[
        "std_msgs/msg/Header"](stamp=store.types["builtin_interfaces/msg/Time"](
            sec=1, nanosec=2), frame_id="f"), airspeed=91.5), FLIGHT))
    with BagWriter(tmp_path / "bag") as writer:
        writer.add_topic("flight/condition", FLIGHT, schema_text=text)
        writer.write("flight/condition", data, 1)
    (got,) = read_messages(tmp_path / "bag")
    assert got.message.airspeed == 91.5 and not hasattr(got.message, "air_density")
