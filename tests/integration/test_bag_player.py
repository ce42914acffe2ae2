"""The bag player over DDS: round trip into the recorder, replay into the spectrum node, timing,
QoS, offsets, a damaged bag, remapping (launch-free; nodes in-process unless the test is about
the executable)."""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

from aero_dva.bag.reader import bag_topics, read_messages
from aero_dva.bag.writer import BagWriter, qos_profile_yaml
from aero_dva_sim.bag_player_node import BagPlayer
from aero_dva_sim.mcap_recorder_node import McapRecorder
from bench.faults.bit_flips import expected_messages, flip_copy, layout
from dva_controller.spectrum_node import SpectrumNode
from dva_msgs.msg import AccelerationBlock
from dva_offline.replay.bag_io import read_outputs, read_recording
from dva_offline.replay.rerun import compare
from tests.unit.dva_offline.small_networks import small_spectrum_network

from .conftest import ros2_run_path

pytestmark = pytest.mark.ros

FLIGHT_TOPICS = ["/wing/acceleration", "/wing/displacement", "/wing/excitation",
                 "/flight/condition", "/dva/damper_state", "/dva/damper_command",
                 "/dva/spectrum"]


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A 4 s flight with the spectrum node and an RBF network in the loop, recorded by
    run_flight (every node a process, as `ros2 run` starts them)."""
    root = tmp_path_factory.mktemp("player")
    scenario = root / "short.yaml"
    scenario.write_text("name: short\nduration: 4.0\nblock_size: 50\n"
                        "airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 0.9}\n"
                        "excitation: {force_std: 1000.0, seed: 2}\n")
    nets = {"a": small_spectrum_network(root / "net_a.npz", 0.3)[0],
            "b": small_spectrum_network(root / "net_b.npz", 0.6)[0]}
    bag = root / "flight"
    result = subprocess.run(
        [str(ros2_run_path("aero_dva_sim", "run_flight")), "--scenario", str(scenario),
         "--controller", "rbf", "--network", str(nets["a"]), "--output", str(bag), "--json",
         # slow enough that the controller has matched the spectrum node before the first
         # spectrum (run_flight waits for the nodes, not for their topics to match)
         "--real-time-factor", "2"],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert bag_topics(bag)["/dva/damper_command"].message_count > 0
    return {"bag": bag, "nets": nets, "root": root}


def _payloads(bag, topic) -> list[bytes]:
    return [bytes(m.message) for m in read_messages(bag, [topic], decode=False)]


def _play(executor, spin, ros_context, player_params, *others, timeout=60.0):
    """Build a player after ``others`` (already in the executor), play, return it."""
    player = BagPlayer(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in player_params.items()])
    executor.add_node(player)
    assert spin(executor, player.finished.done, timeout), "the bag was not played"
    return player


def _recorder(ros_context, executor, path, use_sim_time=False):
    recorder = McapRecorder(context=ros_context, parameter_overrides=[
        Parameter("output", value=str(path)), Parameter("discovery_period", value=0.02),
        Parameter("exclude", value=["/rosout", "/parameter_events"]),
        Parameter("use_sim_time", value=use_sim_time)])
    executor.add_node(recorder)
    return recorder


def test_round_trip_into_the_recorder_keeps_every_message_its_order_and_bytes(
        flight, executor, spin, ros_context, tmp_path):
    out = tmp_path / "round_trip"
    recorder = _recorder(ros_context, executor, out)
    player = _play(executor, spin, ros_context, {
        "bag": str(flight["bag"]), "rate": 0.0, "topics": FLIGHT_TOPICS,
        "wait_for_subscribers": 1}, recorder)
    total = sum(player.counts.values()) + player.clock_published + 1  # + the status
    assert player.finished.result() == "completed"
    assert spin(executor, lambda: recorder.received >= total, 10.0), (recorder.received, total)
    recorder.close()
    original = bag_topics(flight["bag"])
    for topic in FLIGHT_TOPICS:
        assert player.counts[topic] == original[topic].message_count > 0, topic
        assert _payloads(out, topic) == _payloads(flight["bag"], topic), topic
    assert player.summary["outcome"] == "completed" and "damage" not in player.summary


def test_replay_into_a_fresh_spectrum_node_gives_the_recorded_spectra(
        flight, executor, spin, ros_context, tmp_path):
    out = tmp_path / "spectra"
    sim_time = [Parameter("use_sim_time", value=True)]
    spectrum = SpectrumNode(context=ros_context, parameter_overrides=sim_time)
    executor.add_node(spectrum)
    recorder = _recorder(ros_context, executor, out, use_sim_time=True)
    recording = read_recording(flight["bag"])
    _play(executor, spin, ros_context, {
        "bag": str(flight["bag"]), "rate": 10.0, "wait_for_subscribers": 1,
        "wait_for_nodes": ["spectrum"], "wait_for_topics": ["/dva/spectrum"],
        "topics": ["/wing/acceleration", "/dva/damper_state", "/flight/condition"]},
        spectrum, recorder)
    assert spin(executor, lambda: spectrum.counts["spectra"] == len(recording.spectra), 60.0)
    assert spin(executor, lambda: recorder.received_by_topic["/dva/spectrum"]
                >= len(recording.spectra), 60.0), recorder.received_by_topic
    recorder.close()
    spectra, _ = read_outputs(out)
    result = compare(recording.spectra, spectra)
    assert result.identical and result.matched == len(recording.spectra) >= 20, result


def test_rate_one_keeps_the_recorded_timing(flight, executor, spin, ros_context, tmp_path):
    out = tmp_path / "timed"
    recorder = _recorder(ros_context, executor, out)  # wall-clock log times
    player = _play(executor, spin, ros_context, {
        "bag": str(flight["bag"]), "rate": 1.0, "topics": ["/wing/acceleration"],
        "clock": False, "wait_for_subscribers": 1}, recorder)
    assert spin(executor, lambda: recorder.received >= 80 + 1, 10.0), recorder.received
    recorder.close()
    recorded = np.array([m.log_time_ns for m in read_messages(
        flight["bag"], ["/wing/acceleration"], decode=False)]) / 1e9
    received = np.array([m.log_time_ns for m in read_messages(
        out, ["/wing/acceleration"], decode=False)]) / 1e9
    offset = received - recorded
    error = np.abs(offset - np.median(offset))
    span = recorded[-1] - recorded[0]
    assert span > 3.5 and received.size == recorded.size
    assert player.summary["bag_time_played_s"] == pytest.approx(span)
    # Paced, not as fast as possible (which takes a few ms here): how close the pacing is
    # depends on the machine's load, so it is measured by bench/bench_bag_player.py
    # (docs/replay.md), not asserted here.
    assert np.all(np.diff(received) >= 0) and received[-1] - received[0] > 0.5 * span, (
        np.median(error), error.max())


def test_subset_offset_duration_and_the_status_at_the_end(flight, executor, spin,
                                                          ros_context):
    probe = Node("probe", context=ros_context)
    executor.add_node(probe)
    statuses = []
    probe.create_subscription(DiagnosticArray, "/diagnostics", statuses.append, 10)
    player = _play(executor, spin, ros_context, {
        "bag": str(flight["bag"]), "rate": 0.0, "topics": ["flight/condition"],
        "start_offset": 1.0, "duration": 1.0}, probe)
    # log times are sim time from 0 in 50 ms steps: 1.0 .. 2.0 s inclusive
    assert player.counts == {"/flight/condition": 21}
    assert spin(executor, lambda: statuses, 10.0)
    status = statuses[-1].status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert status.name == "bag_player: playback" and status.level == b"\x00"
    assert values["published:/flight/condition"] == "21" and values["outcome"] == "completed"


def test_loop_plays_the_part_again_until_stopped(flight, executor, spin, ros_context):
    player = BagPlayer(context=ros_context, parameter_overrides=[
        Parameter("bag", value=str(flight["bag"])), Parameter("rate", value=0.0),
        Parameter("topics", value=["/flight/condition"]), Parameter("duration", value=0.1),
        Parameter("loop", value=True), Parameter("delay", value=0.0)])
    executor.add_node(player)
    try:
        # 0 .. 0.1 s of log time: 3 conditions a round
        assert spin(executor, lambda: player.counts["/flight/condition"] >= 9, 30.0)
        assert not player.finished.done()
    finally:
        player.close()
    assert player.finished.done() and player.finished.result() == "stopped"


def test_recorded_qos_is_offered_again(tmp_path, executor, spin, ros_context):
    bag = tmp_path / "qos"
    with BagWriter(bag) as writer:
        writer.add_topic("/latched", "std_msgs/msg/String",
                         qos_profile_yaml("best_effort", "transient_local", depth=3))
        writer.add_topic("/plain", "std_msgs/msg/String")
        writer.write("/latched", {"data": "x"}, 1)
        writer.write("/plain", {"data": "y"}, 2)
    player = BagPlayer(context=ros_context, parameter_overrides=[
        Parameter("bag", value=str(bag)), Parameter("exit_on_end", value=False),
        Parameter("wait_for_subscribers", value=1), Parameter("wait_timeout", value=30.0)])
    executor.add_node(player)
    try:
        offered = {t: player.get_publishers_info_by_topic(t)[0].qos_profile
                   for t in ("/latched", "/plain")}
        assert offered["/latched"].reliability == ReliabilityPolicy.BEST_EFFORT
        assert offered["/latched"].durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert offered["/plain"].reliability == ReliabilityPolicy.RELIABLE
        assert offered["/plain"].durability == DurabilityPolicy.VOLATILE
    finally:
        player.close()


def test_a_damaged_bag_plays_up_to_its_damage_with_a_warning(flight, executor, spin,
                                                             ros_context, tmp_path):
    damaged = tmp_path / "damaged"
    shutil.copytree(flight["bag"], damaged)
    (damaged / "metadata.yaml").unlink()  # the recorder was killed: no metadata, no footer
    mcap = next(damaged.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    player = _play(executor, spin, ros_context, {"bag": str(damaged), "rate": 0.0})
    played = sum(player.counts.values())
    total = sum(t.message_count for t in bag_topics(flight["bag"]).values())
    assert 0 < played < total
    assert player.summary["outcome"] == "completed" and "damage" in player.summary
    assert player.source.damage


def test_a_chunk_failing_its_crc_is_skipped_and_the_player_exits_1(
        flight, executor, spin, ros_context, start_process, tmp_path):
    """One flipped bit in the first chunk of a closed bag: the player plays every other chunk
    (the messages mcap's own reader finds in the chunks that pass their CRC), says how many it
    skipped, and the executable exits 1 (PLAYED_LESS: completed, partial)."""
    flipped = tmp_path / "flipped"
    shutil.copytree(flight["bag"], flipped)
    (mcap,) = flipped.glob("*.mcap")
    lay = layout(mcap)
    start, end = lay.chunks[0]
    flip_copy(flight["bag"], [((start + end) // 2, 3)], tmp_path / "f2")
    shutil.copy(next((tmp_path / "f2").glob("*.mcap")), mcap)
    expected, valid = expected_messages(next(flight["bag"].glob("*.mcap")), mcap, lay)
    assert valid == len(lay.chunks) - 1
    player = _play(executor, spin, ros_context, {"bag": str(flipped), "rate": 0.0})
    played_topics = set(player.played)
    want = sum(n for m, n in expected.items() if m[0] in played_topics)
    promised = sum(t.message_count for n, t in bag_topics(flight["bag"]).items()
                   if n in played_topics)
    assert sum(player.counts.values()) == want < promised
    assert player.summary["skipped"] == promised - want and player.exit_code == 1
    # (a flipped bit in a zstd chunk fails its CRC or its decompression, whichever reads first)
    assert mcap.name in player.summary["damage"], player.summary["damage"]
    proc = start_process([ros2_run_path("aero_dva_sim", "bag_player"), "--ros-args",
                          "-p", f"bag:={flipped}", "-p", "rate:=0.0"])
    assert proc.proc.wait(timeout=60) == 1, proc.output()
    assert f"({promised - want} skipped)" in proc.output()


def test_remapping_and_bad_parameters_of_the_executable(flight, executor, spin, ros_context,
                                                        start_process, tmp_path):
    probe = Node("probe", context=ros_context)
    executor.add_node(probe)
    got = []
    from dva_msgs.msg import FlightCondition

    probe.create_subscription(FlightCondition, "/replayed/condition", got.append, 100)
    proc = start_process([ros2_run_path("aero_dva_sim", "bag_player"), "--ros-args",
                          "-p", f"bag:={flight['bag']}", "-p", "rate:=0.0",
                          "-p", "topics:=[/flight/condition]", "-p", "wait_for_subscribers:=1",
                          "-r", "/flight/condition:=/replayed/condition"])
    assert spin(executor, lambda: len(got) == 80, 30.0), proc.output()
    assert proc.proc.wait(timeout=120) == 0, proc.output()

    for bad, words in ((["-p", f"bag:={tmp_path}/none"], "does not exist"),
                       (["-p", f"bag:={flight['bag']}", "-p", "topics:=[/nope]"], "/nope"),
                       (["-p", f"bag:={flight['bag']}", "-p", "rate:=-1.0"], "rate")):
        proc = start_process([ros2_run_path("aero_dva_sim", "bag_player"), "--ros-args", *bad])
        assert proc.proc.wait(timeout=120) == 2, proc.output()
        assert words in proc.output() and "Traceback" not in proc.output()


def test_dva_replay_through_the_graph_equals_offline_and_the_recording(flight, tmp_path):
    """The ROS path and --offline give the same spectra and commands; with the network that
    flew they are the recorded ones, with another they differ."""
    dva = shutil.which("dva")
    assert dva, "the dva command is not on PATH"
    outputs = {}
    for net in ("a", "b"):
        for path in ("ros", "offline"):
            out = tmp_path / f"{net}_{path}"
            argv = [dva, "replay", str(flight["bag"]), "--controller", "rbf", "--network",
                    str(flight["nets"][net]), "--out", str(out), "--json"]
            result = subprocess.run(argv + (["--offline"] if path == "offline" else []),
                                    capture_output=True, text=True, timeout=300)
            assert result.returncode == 0, result.stderr
            outputs[net, path] = yaml.safe_load(result.stdout), read_outputs(out)
    for net in ("a", "b"):
        (_, (ros_spectra, ros_commands)) = outputs[net, "ros"]
        (_, (off_spectra, off_commands)) = outputs[net, "offline"]
        assert compare(off_spectra, ros_spectra).identical
        assert compare(off_commands, ros_commands).identical
    assert outputs["a", "ros"][0]["commands"]["identical"]
    assert outputs["a", "ros"][0]["spectra"]["identical"]
    assert not outputs["b", "ros"][0]["commands"]["identical"]


def _child(parent: int, executable: str) -> int | None:
    """The pid of ``parent``'s child process running ``executable`` (None: none yet)."""
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            command = (entry / "cmdline").read_bytes().split(b"\0")
        except (OSError, ValueError):
            continue
        # (a Python entry point runs as "python <prefix>/lib/<package>/<executable> ...")
        if int(stat.rsplit(")", 1)[1].split()[1]) == parent and any(
                part.decode(errors="replace").endswith(f"/{executable}") for part in command[:2]):
            return int(entry.name)
    return None


def test_a_replay_whose_spectrum_node_is_frozen_while_the_bag_plays_loses_nothing(
        flight, tmp_path, ros_domain, executor, ros_context, spin):
    """The spectrum node stopped (SIGSTOP) from the first block the probe sees until the player
    has sent the bag's last block: the player's writers keep what the frozen reader has not
    acknowledged, and the player stays until it has, so once the node runs again it gets every
    block, and the spectra and commands are --offline's. (With the recorded depth of 10 it lost
    21 of the 30 blocks of a 3 s freeze and gave 1 spectrum of 21; docs/reliability.md.)

    The probe is no node the player waits for: DDS may match it up to an announcement period
    (3 s) after the player's start, when the first blocks have gone (it missed the first 24-50
    blocks in 4 of 14 replays here), so the freeze ends on the bag's last block, not on a
    count of 80 the probe may never reach."""
    offline = tmp_path / "offline"
    net = str(flight["nets"]["a"])
    subprocess.run(["dva", "replay", str(flight["bag"]), "--controller", "rbf", "--network", net,
                    "--out", str(offline), "--offline"], check=True, capture_output=True,
                   timeout=300)
    off_spectra, off_commands = read_outputs(offline)
    probe = Node("probe", context=ros_context)
    executor.add_node(probe)
    last = max(m.message.first_sample_index
               for m in read_messages(flight["bag"], ["/wing/acceleration"]))
    blocks = []  # first_sample_index of each block the probe got
    probe.create_subscription(AccelerationBlock, "/wing/acceleration",
                              lambda m: blocks.append(m.first_sample_index), 1000)
    out = tmp_path / "ros"
    runner = subprocess.Popen(
        [str(ros2_run_path("aero_dva_sim", "replay_flight")), str(flight["bag"]),
         "--controller", "rbf", "--network", net, "--out", str(out), "--rate", "2",
         "--domain-id", str(ros_domain), "--expect-spectra", str(len(off_spectra)),
         "--expect-commands", str(len(off_commands)), "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert spin(executor, lambda: blocks or runner.poll() is not None, timeout=120.0)
    spectrum = _child(runner.pid, "spectrum")
    assert spectrum is not None and runner.poll() is None, runner.communicate()
    os.kill(spectrum, signal.SIGSTOP)
    try:  # until the player has published the whole bag
        assert spin(executor, lambda: blocks[-1] == last or runner.poll() is not None,
                    timeout=120.0)
    finally:
        with contextlib.suppress(ProcessLookupError):  # replay_flight ended: err says why
            os.kill(spectrum, signal.SIGCONT)
    _, err = runner.communicate(timeout=300)
    assert runner.returncode == 0, err
    spectra, commands = read_outputs(out)
    assert len(spectra) == len(off_spectra) == 21
    assert compare(off_spectra, spectra).identical and compare(off_commands, commands).identical
