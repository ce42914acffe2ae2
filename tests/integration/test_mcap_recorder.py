"""The recorder node writes bags that other tools read, and loses nothing it received on SIGINT."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.duration import Duration
from rclpy.node import Node
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from aero_dva.bag.reader import bag_topics, read_messages
from dva_msgs.msg import AccelerationBlock, DamperCommand

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros


def _start_recorder(start_process, bag: Path, *extra: str):
    return start_process([ros2_run_path("aero_dva_sim", "mcap_recorder"), "--ros-args",
                          "-p", f"output:={bag}", *extra])


def _wait_subscribed(executor, spin, publisher, count: int = 1) -> bool:
    return spin(executor, lambda: publisher.get_subscription_count() >= count, timeout=20.0)


def _rosbags_messages(bag: Path, topic: str) -> list:
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        for connection in reader.connections:
            store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        wanted = [c for c in reader.connections if c.topic == topic]
        return [store.deserialize_cdr(raw, c.msgtype)
                for c, _, raw in reader.messages(connections=wanted)]


def test_recorded_bag_reads_back_in_three_readers(executor, spin, ros_context, start_process,
                                                 tmp_path):
    bag = tmp_path / "bag"
    node = Node("source", context=ros_context)
    executor.add_node(node)
    blocks = node.create_publisher(AccelerationBlock, "wing/acceleration", 100)
    commands = node.create_publisher(DamperCommand, "dva/damper_command", 100)
    recorder = _start_recorder(start_process, bag)
    assert _wait_subscribed(executor, spin, blocks), recorder.output()
    assert _wait_subscribed(executor, spin, commands), recorder.output()

    sent = 50
    for i in range(sent):
        msg = AccelerationBlock(sample_rate=1000.0, first_sample_index=20 * i)
        msg.plunge = [float(i)] * 20
        msg.pitch = [0.5 * i] * 20
        msg.leading_edge = [-float(i)] * 20
        blocks.publish(msg)
        commands.publish(DamperCommand(damping=100.0 + i, source="test"))
        executor.spin_once(timeout_sec=0.001)
    # Every message acknowledged by the recorder's reader, then stop it (it takes what is
    # queued before closing the bag).
    assert blocks.wait_for_all_acked(Duration(seconds=120))
    assert commands.wait_for_all_acked(Duration(seconds=120))
    assert recorder.stop() == 0, recorder.output()

    assert (bag / "metadata.yaml").is_file()
    topics = bag_topics(bag)
    assert topics["/wing/acceleration"].message_count == sent
    assert topics["/dva/damper_command"].message_count == sent
    # (1) the project's reader
    ours = [m.message for m in read_messages(bag, ["/wing/acceleration"])]
    assert [m.first_sample_index for m in ours] == [20 * i for i in range(sent)]
    assert list(ours[7].plunge) == [7.0] * 20
    # (2) mcap-ros2-support on the MCAP file itself
    mcap_file = next(bag.glob("*.mcap"))
    with open(mcap_file, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        dampings = [msg.damping for _, _, _, msg in
                    reader.iter_decoded_messages(topics=["/dva/damper_command"])]
    assert dampings == [100.0 + i for i in range(sent)]
    # (3) rosbags, an independent implementation, on the bag directory
    decoded = _rosbags_messages(bag, "/wing/acceleration")
    assert len(decoded) == sent
    assert list(decoded[-1].leading_edge) == [-float(sent - 1)] * 20
    # (4) rerun converts it to a recording with the topics as entities
    rerun = str(Path(sys.executable).with_name("rerun"))
    rrd = tmp_path / "run.rrd"
    subprocess.run([rerun, "mcap", "convert", str(mcap_file), "-o", str(rrd)], check=True,
                   capture_output=True, timeout=120)
    stats = subprocess.run([rerun, "rrd", "stats", str(rrd)], check=True, capture_output=True,
                           text=True, timeout=120)
    assert "/wing/acceleration" in stats.stdout + stats.stderr


def test_sigint_mid_stream_keeps_a_valid_bag(executor, spin, ros_context, start_process,
                                             tmp_path):
    bag = tmp_path / "interrupted"
    node = Node("source", context=ros_context)
    executor.add_node(node)
    commands = node.create_publisher(DamperCommand, "dva/damper_command", 1000)
    recorder = _start_recorder(start_process, bag)
    assert _wait_subscribed(executor, spin, commands), recorder.output()
    count = 0
    for _ in range(200):  # publishing continues while the recorder is interrupted
        commands.publish(DamperCommand(damping=float(count), source="stream"))
        count += 1
        executor.spin_once(timeout_sec=0.002)
        if count == 10:  # the recorder's reader has the first ones: it records mid-stream
            assert commands.wait_for_all_acked(Duration(seconds=120)), recorder.output()
        if count == 100:
            recorder.proc.send_signal(2)  # SIGINT
    assert recorder.stop() == 0, recorder.output()

    recorded = [m.message.damping for m in read_messages(bag, ["/dva/damper_command"])]
    assert recorded, "nothing recorded before SIGINT"
    # What was received is contiguous from the first message: nothing dropped in the middle.
    assert recorded == [float(i) for i in range(len(recorded))]
    assert len(_rosbags_messages(bag, "/dva/damper_command")) == len(recorded)
    assert bag_topics(bag)["/dva/damper_command"].message_count == len(recorded)


def test_messages_a_writer_dropped_before_the_recorder_had_them_are_reported(
        executor, spin, ros_context, start_process, tmp_path):
    """A stopped (starved) recorder's transport buffers overflow, and a reliable keep-last
    writer cannot send again what has left its history: those messages are lost for good. DDS
    says so, and so does the recorder, in its log and in its closing line."""
    import signal

    from rclpy.qos import QoSProfile, ReliabilityPolicy

    bag = tmp_path / "bag"
    node = Node("source", context=ros_context)
    executor.add_node(node)
    commands = node.create_publisher(
        DamperCommand, "dva/damper_command",
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    recorder = _start_recorder(start_process, bag)
    assert _wait_subscribed(executor, spin, commands), recorder.output()
    # one message acknowledged: the recorder's reader knows this writer (a sample sent before
    # that would not be missed, only never meant for it)
    commands.publish(DamperCommand(damping=-2.0, source="test"))
    assert commands.wait_for_all_acked(Duration(seconds=120))
    recorder.proc.send_signal(signal.SIGSTOP)
    try:
        for i in range(3000):  # more than its buffers hold; the writer keeps only the last
            commands.publish(DamperCommand(damping=float(i), source="test"))
    finally:
        recorder.proc.send_signal(signal.SIGCONT)
    commands.publish(DamperCommand(damping=-1.0, source="test"))
    assert commands.wait_for_all_acked(Duration(seconds=120))
    assert spin(executor, lambda: "lost before they reached the recorder" in recorder.output(),
                timeout=30.0), recorder.output()
    assert recorder.stop() == 0, recorder.output()
    closing = next(line for line in recorder.output().splitlines() if "closed" in line)
    assert "lost before reaching it" in closing and "/dva/damper_command" in closing, closing
    assert " 0 message(s) lost" not in recorder.output()  # each loss said once, with its count
    lost = int(re.search(r"'/dva/damper_command': (\d+)", closing).group(1))
    recorded = bag_topics(bag)["/dva/damper_command"].message_count
    assert 1 < recorded < 3002
    assert recorded + lost == 3002, closing  # every message is either in the bag or counted


@pytest.mark.parametrize(("claimed_extra", "left_out"), [(0, False), (3, False), (0, True)])
def test_a_stopped_recorder_takes_what_the_simulator_counted(
        executor, spin, ros_context, start_process, tmp_path, claimed_extra, left_out):
    """On SIGINT the recorder holds on until it has every message the simulator's flight report
    counts, and says so on closing; a count it cannot reach is said as missing. A topic the
    recorder leaves out (``exclude``) is not waited for."""
    from diagnostic_msgs.msg import DiagnosticArray

    from aero_dva.bag import channels as ch
    from dva_msgs.msg import FlightCondition
    from dva_ros_common.conversions import diagnostics

    bag = tmp_path / "bag"
    node = Node("source", context=ros_context)
    executor.add_node(node)
    conditions = node.create_publisher(FlightCondition, "flight/condition", 1000)
    reports = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
    words = []  # the recorder's word on dva/recorded that it holds the flight
    node.create_subscription(DiagnosticArray, ch.RECORDED.name, words.append, 10)
    recorder = _start_recorder(start_process, bag,
                               *(["-p", "exclude:=[/wing/acceleration]"] if left_out else []))
    assert _wait_subscribed(executor, spin, conditions), recorder.output()
    assert _wait_subscribed(executor, spin, reports), recorder.output()
    sent = 40
    for i in range(sent):
        conditions.publish(FlightCondition(airspeed=80.0 + i, air_density=1.2))
    reports.publish(diagnostics(1.0, ch.FLIGHT_DIAGNOSTIC_NAME, ch.SIMULATOR_HARDWARE_ID, [
        ("ok", "flight completed", {"published:flight/condition": sent + claimed_extra,
                                    **({"published:wing/acceleration": 7} if left_out else {})})]))
    assert reports.wait_for_all_acked(Duration(seconds=120))
    if not claimed_extra:  # said as soon as it holds them, before it is stopped
        assert spin(executor, lambda: words, timeout=60.0), recorder.output()
    assert recorder.stop() == 0, recorder.output()
    closing = next(line for line in recorder.output().splitlines() if "closed" in line)
    if claimed_extra:
        assert f"; {claimed_extra} of the {sent + claimed_extra} its flight report counts " \
               "missing" in closing, closing
        executor.spin_once(timeout_sec=0.1)
        assert words == []  # never said: it does not hold them
    else:
        assert f"; all {sent} its flight report counts" in closing, closing
        [word] = words
        [status] = word.status
        assert (word.header.stamp.sec, word.header.stamp.nanosec) == (1, 0)  # the report's
        assert status.name == ch.RECORDED_NAME and status.hardware_id == "/mcap_recorder"
        assert {kv.key: kv.value for kv in status.values} == {"recorded:/flight/condition": "40"}
    assert bag_topics(bag)["/flight/condition"].message_count == sent
    assert "/dva/recorded" not in bag_topics(bag)  # the word is not recorded


def test_a_message_past_max_message_bytes_is_counted_not_recorded(executor, spin, ros_context,
                                                                  start_process, tmp_path):
    """A command whose source is 2 MB (a hostile publisher) is not written into the bag: the
    recorder says so and the bag stays readable; the commands around it are recorded."""
    bag = tmp_path / "bag"
    node = Node("source", context=ros_context)
    executor.add_node(node)
    commands = node.create_publisher(DamperCommand, "dva/damper_command", 10)
    recorder = _start_recorder(start_process, bag)
    assert _wait_subscribed(executor, spin, commands), recorder.output()
    commands.publish(DamperCommand(damping=1.0, source="test"))
    commands.publish(DamperCommand(damping=2.0, source="\x1b[31m" + "x" * 2_000_000))
    commands.publish(DamperCommand(damping=3.0, source="test"))
    assert commands.wait_for_all_acked(Duration(seconds=120))
    assert recorder.stop() == 0, recorder.output()
    kept = [m.message.damping for m in read_messages(bag, ["/dva/damper_command"])]
    assert kept == [1.0, 3.0]
    output = recorder.output()
    assert "not recorded (more than max_message_bytes 1,048,576" in output, output
    assert "1 too large, not recorded" in output, output


@pytest.mark.parametrize(("topics", "offers"), [([], True), (["/flight/condition"], False),
                                               (["/diagnostics"], True)])
def test_the_recorder_offers_its_word_only_when_it_records_the_flight_report(
        ros_context, tmp_path, topics, offers):
    """The word on dva/recorded needs the simulator's report on /diagnostics: a recorder that
    leaves it out offers no word (the simulator then waits for acknowledgements instead)."""
    from rclpy.parameter import Parameter

    from aero_dva_sim.mcap_recorder_node import McapRecorder

    overrides = [Parameter("output", value=str(tmp_path / "bag"))]
    if topics:
        overrides.append(Parameter("topics", value=topics))
    recorder = McapRecorder(context=ros_context, parameter_overrides=overrides)
    try:
        assert (recorder.count_publishers("dva/recorded") == 1) is offers
        assert (recorder._word is not None) is offers
    finally:
        recorder.close()
        recorder.destroy_node()
