"""The spectrum, airspeed and RBF controller nodes over DDS (launch-free, each test isolated).

Nodes run in-process on the test's own Context (one executor, spun until a condition holds),
except where the test is about the executable: those start it as ``ros2 run`` would.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from ament_index_python.packages import get_package_share_directory
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.controllers import controller
from aero_dva.control.rbf_io import save_rbf_network
from aero_dva.control.rbf_network import spectrum_input_names, train_rbf_ols
from aero_dva.control.schedule_io import save_schedule
from aero_dva.control.spectrum import scaled_spectrum
from dva_controller.controller_node import law_node
from dva_controller.spectrum_node import SpectrumNode
from dva_msgs.msg import AccelerationBlock, DamperCommand, DamperState, FlightCondition
from dva_msgs.msg import ScaledSpectrum as ScaledSpectrumMsg
from dva_ros_common import conversions

from .conftest import ros2_run_path

AirspeedController, RBFController = law_node("schedule"), law_node("rbf")

pytestmark = pytest.mark.ros

FS = 1000.0  # [Hz]
BLOCK = 50  # samples per acceleration block
T0_NS = 100_000_000_000  # [ns] sim time of stream sample 0
FREQS = np.arange(5.0, 21.0)


# ---------------------------------------------------------------------------- helpers
class Probe:
    """A test node: publishers on demand, and everything received on subscribed topics."""

    def __init__(self, context, executor, namespace: str = "/"):
        self.node = Node("probe", namespace=namespace, context=context)
        executor.add_node(self.node)
        self.received: dict[str, list] = {}

    def listen(self, msg_type, topic: str, depth: int = 100) -> list:
        inbox = self.received.setdefault(topic, [])
        self.node.create_subscription(msg_type, topic, inbox.append, depth)
        return inbox

    def publisher(self, msg_type, topic: str, depth: int = 100):
        return self.node.create_publisher(msg_type, topic, depth)


def matched(executor, spin, publisher, timeout: float = 10.0) -> None:
    assert spin(executor, lambda: publisher.get_subscription_count() > 0, timeout), (
        f"nobody subscribed to {publisher.topic_name}"
    )


def statuses(diagnostics: list, event: str) -> list[DiagnosticStatus]:
    """Statuses of the received DiagnosticArrays whose value 'event' is ``event``."""
    found = []
    for array in diagnostics:
        for status in array.status:
            values = {kv.key: kv.value for kv in status.values}
            if values.get("event") == event:
                found.append(status)
    return found


def values_of(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def stamp_ns(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


# ---------------------------------------------------------------------------- spectrum
def _signals(n: int) -> np.ndarray:
    """Plunge, pitch, leading-edge accelerations: 12 Hz + 7 Hz with different mixes."""
    t = np.arange(n) / FS
    s12, s7 = np.sin(2 * np.pi * 12.0 * t), np.sin(2 * np.pi * 7.0 * t + 0.3)
    rng = np.random.default_rng(3)
    plunge = 3.0 * s12 + 1.0 * s7 + 0.01 * rng.standard_normal(n)
    pitch = 0.2 * s12 + 0.5 * s7 + 0.01 * rng.standard_normal(n)
    return np.vstack([plunge, pitch, plunge - 0.8 * pitch])


def _block(samples: np.ndarray, start: int) -> AccelerationBlock:
    chunk = samples[:, start : start + BLOCK]
    stamp = conversions.ns_to_time(T0_NS + round(start * 1e9 / FS))
    return conversions.acceleration_block(stamp, FS, start, chunk)


def test_spectrum_node_windows_match_pure_function_and_gap_resets(executor, spin, ros_context):
    node = SpectrumNode(context=ros_context, parameter_overrides=[Parameter("hop", value=0.5)])
    executor.add_node(node)
    probe = Probe(ros_context, executor)
    spectra = probe.listen(ScaledSpectrumMsg, "dva/spectrum")
    diagnostics = probe.listen(DiagnosticArray, "/diagnostics")
    blocks = probe.publisher(AccelerationBlock, "wing/acceleration")
    states = probe.publisher(DamperState, "dva/damper_state")
    matched(executor, spin, blocks)
    matched(executor, spin, states)

    state = DamperState(applied_damping=800.0)
    assert spin(executor, lambda: states.publish(state) or node.latest_damping == 800.0, 10.0)

    samples = _signals(6000)
    sent = 0

    def feed(start: int) -> None:
        nonlocal sent
        blocks.publish(_block(samples, start))
        sent += 1
        assert spin(executor, lambda: node.counts["blocks"] == sent, 5.0), "block not received"

    for start in range(0, 3000, BLOCK):  # 3 s: windows starting at 0, 0.5, 1.0 s
        feed(start)
    assert spin(executor, lambda: len(spectra) == 3, 5.0), len(spectra)

    first = spectra[0]
    assert stamp_ns(first.header.stamp) == T0_NS + 1_999_000_000  # last sample of the window
    assert list(first.channel_names) == ["plunge", "pitch"]
    np.testing.assert_array_equal(first.frequencies, FREQS)
    expected = scaled_spectrum(samples[:2, :2000], FS, FREQS)
    mags = np.asarray(first.magnitudes).reshape(2, 16)
    np.testing.assert_allclose(mags, expected.magnitudes, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(mags.sum(axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(first.band_sums, expected.band_sums, rtol=1e-9)
    assert FREQS[np.argmax(mags[0])] == 12.0 and FREQS[np.argmax(mags[1])] == 7.0
    assert (first.window_duration, first.hop) == (2.0, 0.5)
    assert first.window_function == ScaledSpectrumMsg.WINDOW_RECTANGULAR
    assert first.scaling == ScaledSpectrumMsg.SCALING_BAND_SUM
    assert first.damping == 800.0
    assert stamp_ns(spectra[2].header.stamp) == T0_NS + 2_999_000_000

    # A lost block (3000..3049): the window restarts at 3050 and says why.
    for start in range(3050, 5050, BLOCK):
        feed(start)
    assert spin(executor, lambda: statuses(diagnostics, "reset_gap"), 5.0)
    reset = statuses(diagnostics, "reset_gap")[0]
    assert reset.level == DiagnosticStatus.WARN
    assert values_of(reset)["expected_index"] == "3000"
    assert values_of(reset)["received_index"] == "3050"
    assert "gap" in reset.message and "3000" in reset.message and "3050" in reset.message
    assert spin(executor, lambda: len(spectra) == 4, 5.0), len(spectra)
    after = spectra[3]
    assert stamp_ns(after.header.stamp) == T0_NS + 5_049_000_000
    expected = scaled_spectrum(samples[:2, 3050:5050], FS, FREQS)
    np.testing.assert_allclose(
        np.asarray(after.magnitudes).reshape(2, 16), expected.magnitudes, rtol=1e-9, atol=1e-12
    )


def test_spectrum_node_reports_out_of_order_rate_change_and_bad_blocks(
    executor, spin, ros_context
):
    node = SpectrumNode(context=ros_context, parameter_overrides=[
        Parameter("channels", value=["leading_edge"]), Parameter("window", value="hann")])
    executor.add_node(node)
    probe = Probe(ros_context, executor)
    diagnostics = probe.listen(DiagnosticArray, "/diagnostics")
    blocks = probe.publisher(AccelerationBlock, "wing/acceleration")
    matched(executor, spin, blocks)
    samples = _signals(400)
    stream = [_block(samples, 0), _block(samples, 50), _block(samples, 100),
              _block(samples, 50)]  # a repeated (late) block
    slow = _block(samples, 150)
    slow.sample_rate = 500.0  # the rate changes
    odd = _block(samples, 200)
    odd.sample_rate = 333.0  # 0.1 s is not a whole number of samples: unusable
    short = _block(samples, 250)
    short.pitch = short.pitch[:10]  # arrays of different lengths
    for msg in [*stream, slow, odd, short]:
        blocks.publish(msg)
    events = ("reset_out_of_order", "reset_sample_rate", "unusable_sample_rate", "malformed")
    assert spin(executor, lambda: all(statuses(diagnostics, e) for e in events), 5.0), [
        e for e in events if not statuses(diagnostics, e)]
    late = values_of(statuses(diagnostics, "reset_out_of_order")[0])
    assert (late["expected_index"], late["received_index"]) == ("150", "50")
    assert late["dropped_samples"] == "150"
    rate = statuses(diagnostics, "reset_sample_rate")[0]
    assert "1000 to 500 Hz at index 150 (expected index 100)" in rate.message
    assert values_of(rate)["dropped_samples"] == "50"  # block 50..99, kept after the reset
    assert statuses(diagnostics, "unusable_sample_rate")[0].level == DiagnosticStatus.ERROR
    # 500 -> 333 Hz is a third reset (its diagnostic is throttled; the status counts it)
    assert node.counts["rejected"] == 2 and node.counts["resets"] == 3


def test_spectrum_node_rejects_bad_parameters(ros_context):
    with pytest.raises(ValueError, match="channels"):
        SpectrumNode(context=ros_context,
                     parameter_overrides=[Parameter("channels", value=["plunge", "yaw"])])
    with pytest.raises(ValueError, match="window"):
        SpectrumNode(context=ros_context,
                     parameter_overrides=[Parameter("window", value="blackman")])
    with pytest.raises(ValueError, match="frequencies"):
        SpectrumNode(context=ros_context,
                     parameter_overrides=[Parameter("frequencies", value=[5.0, -1.0])])


# ---------------------------------------------------------------------------- airspeed
def _condition(t_s: float, airspeed: float) -> FlightCondition:
    return conversions.flight_condition(conversions.ns_to_time(round(t_s * 1e9)), airspeed)


def _airspeed_rig(executor, spin, ros_context, **params):
    overrides = [Parameter(k, value=v) for k, v in params.items()]
    node = AirspeedController(context=ros_context, parameter_overrides=overrides)
    executor.add_node(node)
    probe = Probe(ros_context, executor)
    commands = probe.listen(DamperCommand, "dva/damper_command")
    diagnostics = probe.listen(DiagnosticArray, "/diagnostics")
    conditions = probe.publisher(FlightCondition, "flight/condition")
    matched(executor, spin, conditions)
    return node, probe, commands, diagnostics, conditions


def test_airspeed_controller_commands_clamped_schedule(executor, spin, ros_context):
    node, probe, commands, diagnostics, conditions = _airspeed_rig(
        executor, spin, ros_context, a0=-2150.0, a1=31.5, damping_max=1500.0, use_sim_time=True
    )
    conditions.publish(_condition(10.0, 100.0))  # 1000 N s/m
    conditions.publish(_condition(10.1, 120.0))  # 1630 -> clamped to 1500
    assert spin(executor, lambda: len(commands) == 2, 5.0)
    assert [c.damping for c in commands] == [1000.0, 1500.0]
    assert all(c.source == controller("schedule").source for c in commands)
    # Sim time without /clock yet: the command is stamped with its input's time.
    assert stamp_ns(commands[0].header.stamp) == 10_000_000_000

    # NaN, negative and absurd airspeeds: no command, a diagnostic; then a valid one goes on.
    for bad in (math.nan, -5.0, 1.0e5):
        conditions.publish(_condition(10.2, bad))
    conditions.publish(_condition(10.3, 110.0))
    assert spin(executor, lambda: len(commands) == 3, 5.0)
    assert commands[2].damping == pytest.approx(-2150.0 + 31.5 * 110.0)
    assert node.counts["rejected"] == 3
    assert spin(executor, lambda: statuses(diagnostics, "rejected_airspeed"), 5.0)
    rejected = statuses(diagnostics, "rejected_airspeed")[0]
    assert rejected.level == DiagnosticStatus.WARN and "nan" in rejected.message

    # Even with /clock ahead of the input, a command carries its input's stamp.
    clock = probe.publisher(Clock, "/clock", 10)
    matched(executor, spin, clock)
    tick = Clock(clock=conversions.ns_to_time(50_000_000_000))
    assert spin(executor, lambda: clock.publish(tick)
                or node.get_clock().now().nanoseconds == 50_000_000_000, 5.0)
    conditions.publish(_condition(40.0, 100.0))
    assert spin(executor, lambda: len(commands) == 4, 5.0)
    assert stamp_ns(commands[3].header.stamp) == 40_000_000_000


def test_airspeed_controller_min_period_in_ros_time(executor, spin, ros_context):
    _, _, commands, _, conditions = _airspeed_rig(
        executor, spin, ros_context, a0=0.0, a1=10.0, min_period=1.0, use_sim_time=True
    )
    for t, u in ((10.0, 100.0), (10.5, 101.0), (11.0, 102.0), (11.2, 103.0)):
        conditions.publish(_condition(t, u))
    conditions.publish(_condition(12.5, 104.0))
    assert spin(executor, lambda: len(commands) == 3, 5.0)
    assert [c.damping for c in commands] == [1000.0, 1020.0, 1040.0]


@pytest.mark.parametrize("extrapolate", [True, False])
def test_airspeed_controller_schedule_file(executor, spin, ros_context, tmp_path, extrapolate):
    schedule = AirspeedSchedule(a0=100.0, a1=10.0, airspeed_range=(90.0, 110.0),
                                damping_range=(200.0, 1800.0))
    path = save_schedule(schedule, tmp_path / "schedule.json")
    _, _, commands, _, conditions = _airspeed_rig(
        executor, spin, ros_context, schedule_file=str(path), extrapolate=extrapolate,
    )
    speeds = (100.0, 150.0, 200.0, 10.0)
    for i, u in enumerate(speeds):
        conditions.publish(_condition(1.0 + i, u))
    assert spin(executor, lambda: len(commands) == len(speeds), 5.0)
    expected = [schedule.evaluate(u, extrapolate=extrapolate) for u in speeds]
    assert [c.damping for c in commands] == pytest.approx(expected)
    if extrapolate:
        assert [c.damping for c in commands] == pytest.approx([1100.0, 1600.0, 1800.0, 200.0])


# ---------------------------------------------------------------------------- rbf
@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny network on synthetic spectra: (path, network)."""
    rng = np.random.default_rng(0)
    n = 80
    mags = rng.dirichlet(np.ones(16), size=(n, 2))  # each channel sums to 1
    damping = rng.uniform(300.0, 1500.0, n)
    inputs = np.column_stack([mags.reshape(n, 32), damping])
    targets = 400.0 + 3000.0 * mags[:, 0, 7] + 0.3 * damping
    names, units = spectrum_input_names(("plunge", "pitch"), FREQS)
    result = train_rbf_ols(inputs, targets, spread=2.0, max_neurons=20,
                           input_names=names, input_units=units)
    path = save_rbf_network(result.network, tmp_path_factory.mktemp("rbf") / "net.npz")
    return path, result.network, inputs


def _spectrum_msg(magnitudes: np.ndarray, damping: float, freqs=FREQS) -> ScaledSpectrumMsg:
    msg = ScaledSpectrumMsg()
    msg.header.stamp = conversions.ns_to_time(T0_NS)
    msg.frequencies = [float(f) for f in freqs]
    msg.channel_names = ["plunge", "pitch"]
    msg.magnitudes = np.asarray(magnitudes, dtype=float).ravel().tolist()
    msg.window_duration = 2.0
    msg.hop = 0.1
    msg.window_function = ScaledSpectrumMsg.WINDOW_RECTANGULAR
    msg.scaling = ScaledSpectrumMsg.SCALING_BAND_SUM
    msg.damping = float(damping)
    return msg


def test_rbf_controller_commands_network_output(executor, spin, ros_context, trained):
    path, network, inputs = trained
    x_free, x_clamped = inputs[5], inputs[11]
    y_free, y_clamped = network.predict(x_free), network.predict(x_clamped)
    assert abs(y_free - y_clamped) > 1.0
    top = 0.5 * (y_free + y_clamped)  # the damper range cuts one of the two outputs
    node = RBFController(context=ros_context, parameter_overrides=[
        Parameter("network_file", value=str(path)), Parameter("damping_max", value=top)])
    executor.add_node(node)
    probe = Probe(ros_context, executor)
    commands = probe.listen(DamperCommand, "dva/damper_command")
    diagnostics = probe.listen(DiagnosticArray, "/diagnostics")
    spectra = probe.publisher(ScaledSpectrumMsg, "dva/spectrum")
    matched(executor, spin, spectra)

    spectra.publish(_spectrum_msg(x_free[:32].reshape(2, 16), x_free[32]))
    spectra.publish(_spectrum_msg(x_clamped[:32].reshape(2, 16), x_clamped[32]))
    assert spin(executor, lambda: len(commands) == 2, 5.0)
    assert [c.damping for c in commands] == pytest.approx(
        [min(y_free, top), min(y_clamped, top)], rel=1e-12)
    assert max(c.damping for c in commands) == pytest.approx(top)
    assert all(c.source == controller("rbf").source for c in commands)
    assert all(stamp_ns(c.header.stamp) >= T0_NS for c in commands)

    # 15 frequencies (5..19 Hz): not what the network was trained on -> no command, a diagnostic.
    spectra.publish(_spectrum_msg(x_free[:30].reshape(2, 15), 900.0, freqs=FREQS[:15]))
    spectra.publish(_spectrum_msg(x_free[:32].reshape(2, 16), x_free[32]))
    assert spin(executor, lambda: len(commands) == 3, 5.0)
    assert commands[2].damping == pytest.approx(commands[0].damping, rel=1e-12)
    assert node.counts["rejected"] == 1
    assert spin(executor, lambda: statuses(diagnostics, "rejected_spectrum"), 5.0)
    rejected = statuses(diagnostics, "rejected_spectrum")[0]
    assert rejected.level == DiagnosticStatus.WARN and "15 frequencies" in rejected.message


def test_rbf_controller_refuses_network_of_other_inputs(ros_context, trained):
    path = str(trained[0])
    with pytest.raises(ValueError, match="leading_edge"):
        RBFController(context=ros_context, parameter_overrides=[
            Parameter("network_file", value=path),
            Parameter("channels", value=["plunge", "leading_edge"])])
    with pytest.raises(ValueError, match="input_dim is 33, the controller needs 31"):
        RBFController(context=ros_context, parameter_overrides=[
            Parameter("network_file", value=path),
            Parameter("frequencies", value=[float(f) for f in range(5, 20)])])


def test_rbf_controller_subprocess_publishes(executor, spin, ros_context, start_process, trained):
    path, network, inputs = trained
    exe = ros2_run_path("dva_controller", "rbf_controller")
    assert exe.is_file() and os.access(exe, os.X_OK), exe
    proc = start_process([exe, "--ros-args", "-p", f"network_file:={path}",
                          "-r", "__ns:=/wing1"])
    probe = Probe(ros_context, executor)
    commands = probe.listen(DamperCommand, "/wing1/dva/damper_command")
    spectra = probe.publisher(ScaledSpectrumMsg, "/wing1/dva/spectrum")
    x = inputs[7]
    msg = _spectrum_msg(x[:32].reshape(2, 16), x[32])
    # Publish until the subprocess has discovered us and answered.
    assert spin(executor, lambda: spectra.publish(msg) or bool(commands), 20.0), proc.output()
    expected = min(max(network.predict(x), 0.0), 2500.0)
    assert commands[0].damping == pytest.approx(expected, rel=1e-12)
    assert proc.stop() == 0, proc.output()


def test_rbf_controller_corrupt_file_exits_2(start_process, tmp_path):
    bad = tmp_path / "corrupt_network.npz"
    bad.write_bytes(b"PK\x03\x04 this is not a zip archive")
    proc = start_process([ros2_run_path("dva_controller", "rbf_controller"),
                          "--ros-args", "-p", f"network_file:={bad}"])
    assert proc.proc.wait(timeout=120) == 2
    out = proc.output()
    assert str(bad) in out and "Traceback" not in out, out
    assert len([line for line in out.splitlines() if "error" in line]) == 1, out


# ---------------------------------------------------------------------------- config files
@pytest.mark.parametrize("node_class", [SpectrumNode, AirspeedController, RBFController])
def test_example_parameter_files_load(ros_context, trained, node_class):
    spec = getattr(node_class, "SPEC", None) or \
        __import__(node_class.__module__, fromlist=["SPEC"]).SPEC
    name = spec.name
    path = Path(get_package_share_directory("dva_controller")) / "config" / f"{name}.yaml"
    params = yaml.safe_load(path.read_text())[name]["ros__parameters"]
    args = ["--ros-args", "--params-file", str(path)]
    if node_class is RBFController:
        args += ["-p", f"network_file:={trained[0]}"]
    node = node_class(context=ros_context, cli_args=args)
    try:
        for key, value in params.items():
            got = node.get_parameter(key).value
            if key == "network_file":
                assert got == str(trained[0])
            elif isinstance(value, list):
                assert list(got) == value, key
            else:
                assert got == value, key
    finally:
        node.destroy_node()


# ---------------------------------------------------------------------------- stale input
@pytest.mark.parametrize("node_class", [SpectrumNode, AirspeedController, RBFController])
def test_silent_input_is_reported_stale(executor, spin, ros_context, trained, node_class):
    params = [Parameter("stale_timeout", value=0.05), Parameter("diagnostic_period", value=0.05)]
    if node_class is RBFController:
        params.append(Parameter("network_file", value=str(trained[0])))
    node = node_class(context=ros_context, parameter_overrides=params)
    executor.add_node(node)
    probe = Probe(ros_context, executor)
    diagnostics = probe.listen(DiagnosticArray, "/diagnostics")

    def stale() -> list:
        return [s for s in statuses(diagnostics, "status") if s.level == DiagnosticStatus.WARN]

    assert spin(executor, stale, 5.0)
    status = stale()[0]
    assert "stale input" in status.message
    assert status.name.startswith(node.get_name() + ": ")
