"""CDR encoding of the simulator's messages, byte for byte against mcap-ros2-support's encoder."""
from __future__ import annotations

import math

import numpy as np
import pytest
from mcap.records import Schema
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory

from aero_dva.bag import cdr_encoding as cdr
from aero_dva.bag.mcap_io import message_definition
from aero_dva.flight.damper import DamperSnapshot, DamperStatus

LENGTHS = [0, 1, 2, 3, 7, 50]
FRAMES = ["", "w", "wi", "win", "wing", "wing1", "wing12", "wing123", "wing_1234", "flügel"]
TIMES = [0.0, 0.05, 0.1 + 0.2, 1.2345678905, 6839.95, 12345.0000000005, 2.0**31 - 1.0]


def reference(type_name: str, message: dict) -> bytes:
    return serialize_dynamic(type_name, message_definition(type_name))[type_name](message)


def time_dict(seconds: float) -> dict:
    # aero_dva_sim.messages.to_time
    ns = int(round(seconds * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def header(seconds: float, frame_id: str = "") -> dict:
    return {"stamp": time_dict(seconds), "frame_id": frame_id}


def snapshot(**changes) -> DamperSnapshot:
    values = dict(time=1.25, commanded_damping=math.nan, applied_damping=500.0,
                  min_damping=0.0, max_damping=2500.0, command_age=math.inf,
                  status=DamperStatus.NO_COMMAND, source="initial", rejection=None)
    values.update(changes)
    return DamperSnapshot(**values)


@pytest.mark.parametrize("n", LENGTHS)
@pytest.mark.parametrize("frame_id", ["wing", "", "wing1", "flügel"])
def test_sample_blocks_match_reference(n, frame_id):
    rng = np.random.default_rng(n)
    acc, disp, force = (rng.standard_normal((3, n)), rng.standard_normal((4, n)),
                        rng.standard_normal(n) * 1e3)
    for t0 in TIMES:
        first = 1000 * n + 7
        expected = reference(cdr.ACCELERATION_BLOCK, {
            "header": header(t0, frame_id), "sample_rate": 1000.0, "first_sample_index": first,
            "plunge": acc[0].tolist(), "pitch": acc[1].tolist(), "leading_edge": acc[2].tolist()})
        assert cdr.encode_acceleration_block(t0, 1000.0, first, acc, frame_id) == expected
        expected = reference(cdr.DISPLACEMENT_BLOCK, {
            "header": header(t0, frame_id), "sample_rate": 999.5, "first_sample_index": first,
            "plunge": disp[0].tolist(), "pitch": disp[1].tolist(),
            "leading_edge": disp[2].tolist(), "absorber_stroke": disp[3].tolist()})
        assert cdr.encode_displacement_block(t0, 999.5, first, disp, frame_id) == expected
        expected = reference(cdr.FORCE_BLOCK, {
            "header": header(t0, frame_id), "sample_rate": 1000.0, "first_sample_index": first,
            "aileron_force": force.tolist()})
        assert cdr.encode_force_block(t0, 1000.0, first, force, frame_id) == expected


def test_default_frames_are_the_nodes():
    """Sample blocks of the wing carry frame_id "wing"; the force block none (messages.py)."""
    acc = np.zeros((3, 2))
    assert b"\x05\x00\x00\x00wing\x00" in cdr.encode_acceleration_block(0.0, 1e3, 0, acc)
    assert b"\x05\x00\x00\x00wing\x00" in cdr.encode_displacement_block(0.0, 1e3, 0,
                                                                        np.zeros((4, 2)))
    expected = reference(cdr.FORCE_BLOCK, {"header": header(0.5), "sample_rate": 1e3,
                                           "first_sample_index": 0, "aileron_force": [1.0]})
    assert cdr.encode_force_block(0.5, 1e3, 0, [1.0]) == expected


def test_special_float_values_are_kept_bit_for_bit():
    values = np.array([[np.nan, np.inf, -np.inf, -0.0, 5e-324, 1.7976931348623157e308]] * 3)
    data = cdr.encode_acceleration_block(0.0, 1000.0, 0, values)
    expected = reference(cdr.ACCELERATION_BLOCK, {
        "header": header(0.0, "wing"), "sample_rate": 1000.0, "first_sample_index": 0,
        "plunge": values[0].tolist(), "pitch": values[1].tolist(),
        "leading_edge": values[2].tolist()})
    assert data == expected


@pytest.mark.parametrize("frame_id", FRAMES)
def test_flight_condition_and_clock(frame_id):
    for t in TIMES:
        expected = reference(cdr.FLIGHT_CONDITION, {"header": header(t, frame_id),
                                                   "airspeed": 91.25, "air_density": 1.225})
        assert cdr.encode_flight_condition(t, 91.25, 1.225, frame_id) == expected
        assert cdr.encode_clock(t) == reference(cdr.CLOCK, {"clock": time_dict(t)})


@pytest.mark.parametrize("source", ["", "initial", "fallback", "rbf_network", "sweep",
                                    "airspeed_schedule", "x" * 33, "ünï"])
@pytest.mark.parametrize("status", list(DamperStatus))
def test_damper_state(source, status):
    state = snapshot(source=source, status=status, commanded_damping=812.5, command_age=0.25,
                     time=3.05)
    expected = reference(cdr.DAMPER_STATE, {
        "header": header(3.05), "commanded_damping": 812.5, "applied_damping": 500.0,
        "min_damping": 0.0, "max_damping": 2500.0, "command_age": 0.25,
        "status": int(status), "source": source})
    assert cdr.encode_damper_state(state) == expected


def test_damper_state_with_nan_and_inf():
    state = snapshot()
    expected = reference(cdr.DAMPER_STATE, {
        "header": header(1.25), "commanded_damping": math.nan, "applied_damping": 500.0,
        "min_damping": 0.0, "max_damping": 2500.0, "command_age": math.inf,
        "status": 4, "source": "initial"})
    assert cdr.encode_damper_state(state) == expected


@pytest.mark.parametrize("source", ["", "fixed", "rbf_network", "airspeed_schedule"])
def test_damper_command(source):
    for t in TIMES:
        expected = reference(cdr.DAMPER_COMMAND, {"header": header(t), "damping": 650.0,
                                                 "source": source})
        assert cdr.encode_damper_command(t, 650.0, source) == expected


@pytest.mark.parametrize("statuses", [
    [],
    [(0, "simulator: flight", "flight completed", "aero_dva_sim", [])],
    [(2, "simulator: flight", "wing diverged at U = 117.32 m/s (U/U_cr = 1.173, t = 28.950 s)"
      ": flight stopped", "aero_dva_sim",
      [("sim_time_s", "29"), ("wall_time_s", "1.5"), ("published:wing/acceleration", "580")]),
     (1, "a", "", "", [("k", "")]),
     (3, "", "ü", "hw", [("", "v"), ("kk", "vvv")])],
])
def test_diagnostic_array(statuses):
    expected = reference(cdr.DIAGNOSTIC_ARRAY, {
        "header": header(29.0), "status": [
            {"level": level, "name": name, "message": message, "hardware_id": hardware,
             "values": [{"key": k, "value": v} for k, v in values]}
            for level, name, message, hardware, values in statuses]})
    assert cdr.encode_diagnostic_array(29.0, statuses) == expected


def test_decoded_values_round_trip():
    """The reference decoder reads the fields back (stamps split as messages.to_time does)."""
    t0 = 0.1 + 0.2
    data = cdr.encode_acceleration_block(t0, 1000.0, 300, np.arange(6.0).reshape(3, 2))
    schema = Schema(id=1, name=cdr.ACCELERATION_BLOCK, encoding="ros2msg",
                    data=message_definition(cdr.ACCELERATION_BLOCK).encode())
    msg = DecoderFactory().decoder_for("cdr", schema)(data)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 300_000_000)
    assert msg.header.frame_id == "wing" and msg.first_sample_index == 300
    assert list(msg.leading_edge) == [4.0, 5.0]


# --------------------------------------------------------------------------------------------
# Layouts and batches
# --------------------------------------------------------------------------------------------


def test_batch_rows_equal_single_messages():
    rng = np.random.default_rng(3)
    k, n = 9, 5
    acc = rng.standard_normal((k, 3, n))
    t0 = np.arange(k) * 0.005 + 0.1
    layout = cdr.acceleration_block_layout(n)
    rows = layout.batch(k)
    sec, nsec = cdr.split_stamps(cdr.stamps_from_seconds(t0))
    rows["stamp_sec"], rows["stamp_nanosec"] = sec, nsec
    rows["sample_rate"] = 1000.0
    rows["first_sample_index"] = np.arange(k) * n
    for i, name in enumerate(("plunge", "pitch", "leading_edge")):
        rows[name] = acc[:, i]
    data = rows.tobytes()
    assert len(data) == k * layout.size
    for j in range(k):
        single = cdr.encode_acceleration_block(t0[j], 1000.0, j * n, acc[j])
        assert data[j * layout.size:(j + 1) * layout.size] == single


def test_layout_offsets_follow_alignment():
    layout = cdr.acceleration_block_layout(2)
    # header 4 | sec 4 | nanosec 4 | len 4 | "wing\0" 5 | pad 3 | rate 8 | index 8 | ...
    assert layout.fields["stamp_sec"][0] == 4
    assert layout.fields["sample_rate"][0] == 4 + 24
    assert layout.fields["first_sample_index"][0] == 4 + 32
    assert layout.fields["plunge"] == (4 + 48, "f64[]", 2)  # length at 40, padded to 48
    assert layout.template[:4] == cdr.CDR_HEADER
    state = cdr.damper_state_layout("initial")
    assert state.fields["status"][1] == "u8"
    assert state.size == len(cdr.encode_damper_state(snapshot()))


def test_stamps_round_like_messages_to_time():
    for t in [0.0, 1e-9, 0.5e-9, 1.5e-9, 2.5e-9, 0.3, 6839.95, 1.0 - 1e-10]:
        ns = cdr.stamp_ns(t)
        assert ns == int(round(t * 1e9))
        assert cdr.stamps_from_seconds([t])[0] == ns
    assert cdr.split_stamps([1_999_999_999])[0][0] == 1
    assert cdr.split_stamps([1_999_999_999])[1][0] == 999_999_999


# --------------------------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------------------------


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="accelerations"):
        cdr.encode_acceleration_block(0.0, 1e3, 0, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="displacements"):
        cdr.encode_displacement_block(0.0, 1e3, 0, np.zeros(3))
    with pytest.raises(ValueError, match="force"):
        cdr.encode_force_block(0.0, 1e3, 0, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="t0"):
        cdr.encode_acceleration_block(math.nan, 1e3, 0, np.zeros((3, 1)))
    with pytest.raises(ValueError, match="int32"):
        cdr.encode_clock(2.0**31)
    with pytest.raises(ValueError, match="first_sample_index"):
        cdr.encode_force_block(0.0, 1e3, -1, np.zeros(1))
    with pytest.raises(TypeError, match="first_index"):
        cdr.encode_force_block(0.0, 1e3, 1.5, np.zeros(1))
    with pytest.raises(TypeError, match="airspeed"):
        cdr.encode_flight_condition(0.0, "fast", 1.2)
    with pytest.raises(ValueError, match="NUL"):
        cdr.encode_damper_command(0.0, 1.0, "a\0b")
    with pytest.raises(TypeError, match="source"):
        cdr.encode_damper_command(0.0, 1.0, 5)
    with pytest.raises(ValueError, match="status"):
        cdr.encode_damper_state(snapshot(status=300))
    with pytest.raises(ValueError, match=r"statuses\[0\]"):
        cdr.encode_diagnostic_array(0.0, [(0, "x")])
    with pytest.raises(ValueError, match="level"):
        cdr.encode_diagnostic_array(0.0, [(256, "x", "", "", [])])
    with pytest.raises(ValueError, match="n must"):
        cdr.acceleration_block_layout(-1)
    with pytest.raises(ValueError, match="count"):
        cdr.clock_layout().batch(-2)
    with pytest.raises(ValueError, match="missing"):
        cdr.clock_layout().encode({"stamp_sec": 0})
    with pytest.raises(ValueError, match="shape"):
        cdr.force_block_layout(2).encode({"stamp_sec": 0, "stamp_nanosec": 0,
                                          "sample_rate": 1.0, "first_sample_index": 0,
                                          "aileron_force": [1.0]})
