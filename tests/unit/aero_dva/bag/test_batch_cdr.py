"""Batch CDR layouts generated from the .msg files, byte for byte against rosbags' serializer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from aero_dva.bag import channels as ch
from aero_dva.bag.batch_cdr import (
    CDR_HEADER,
    cdr_layout,
    sample_fields,
    split_stamps,
    stamp_ns,
    stamps_from_seconds,
)
from aero_dva.bag.schemas import INTERFACES, typestore
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES

STORE = typestore()
LENGTHS = [0, 1, 2, 3, 7, 50]
FRAMES = ["", "w", "wi", "win", "wing", "wing1", "wing12", "wing123", "wing_1234", "flügel"]
TIMES = [0.0, 0.05, 0.1 + 0.2, 1.2345678905, 6839.95, 12345.0000000005, 2.0**31 - 1.0]


def fill(layout, values: dict) -> bytes:
    """One message of ``layout`` with its numeric fields set from ``values``."""
    row = layout.batch(1)
    assert set(values) == set(layout.fields), "every numeric field is given"
    for name, value in values.items():
        row[name] = value
    return row.tobytes()


def oracle(type_name: str, **fields) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types[type_name](**fields), type_name))


def time_fields(seconds: float, prefix: str = "header.stamp") -> dict:
    sec, nanosec = divmod(stamp_ns(seconds), 1_000_000_000)
    return {f"{prefix}.sec": sec, f"{prefix}.nanosec": nanosec}


def header(seconds: float, frame: str = ""):
    sec, nanosec = divmod(stamp_ns(seconds), 1_000_000_000)
    return STORE.types["std_msgs/msg/Header"](
        stamp=STORE.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
        frame_id=frame)


@pytest.mark.parametrize("n", LENGTHS)
@pytest.mark.parametrize("frame", ["wing", "", "wing1", "flügel"])
def test_sample_blocks_equal_rosbags(n, frame):
    rng = np.random.default_rng(n)
    for channel, rows in ((ch.ACCELERATION, 3), (ch.DISPLACEMENT, 4), (ch.EXCITATION, 1)):
        fields = sample_fields(channel.type_name)
        data = rng.standard_normal((rows, n))
        layout = cdr_layout(channel.type_name, dict.fromkeys(fields, n),
                            {"header.frame_id": frame})
        for t0 in TIMES:
            first = 1000 * n + 7
            got = fill(layout, {**time_fields(t0), "sample_rate": 999.5,
                                "first_sample_index": first, **dict(zip(fields, data))})
            expected = oracle(channel.type_name, header=header(t0, frame), sample_rate=999.5,
                              first_sample_index=first, **dict(zip(fields, data)))
            assert got == expected, (channel, t0)


def test_special_float_values_are_kept_bit_for_bit():
    values = np.array([[np.nan, np.inf, -np.inf, -0.0, 5e-324, 1.7976931348623157e308]] * 3)
    fields = sample_fields(ch.ACCELERATION.type_name)
    layout = cdr_layout(ch.ACCELERATION.type_name, dict.fromkeys(fields, 6),
                        {"header.frame_id": "wing"})
    got = fill(layout, {**time_fields(0.0), "sample_rate": 1e3, "first_sample_index": 0,
                        **dict(zip(fields, values))})
    assert got == oracle(ch.ACCELERATION.type_name, header=header(0.0, "wing"),
                         sample_rate=1e3, first_sample_index=0, **dict(zip(fields, values)))


@pytest.mark.parametrize("frame", FRAMES)
def test_flight_condition_and_clock(frame):
    for t in TIMES:
        layout = cdr_layout(ch.FLIGHT_CONDITION.type_name, strings={"header.frame_id": frame})
        got = fill(layout, {**time_fields(t), "airspeed": 91.25, "air_density": 1.225})
        assert got == oracle(ch.FLIGHT_CONDITION.type_name, header=header(t, frame),
                             airspeed=91.25, air_density=1.225)
        got = fill(cdr_layout(ch.CLOCK.type_name), time_fields(t, "clock"))
        assert got == oracle(ch.CLOCK.type_name, clock=header(t).stamp)


@pytest.mark.parametrize("source", ["", "initial", "fallback", "rbf_network", "sweep",
                                    "airspeed_schedule", "switching", "x" * 33, "ünï"])
@pytest.mark.parametrize("status", [0, 1, 2, 3, 4, 255])
def test_damper_state_with_nan_and_inf(source, status):
    layout = cdr_layout(ch.DAMPER_STATE.type_name, strings={"source": source})
    values = {"commanded_damping": math.nan, "applied_damping": 500.0, "min_damping": 0.0,
              "max_damping": 2500.0, "command_age": math.inf, "status": status,
              "mode": status % 3, "switching_rate": 40.5}
    got = fill(layout, {**time_fields(3.05), **values})
    assert got == oracle(ch.DAMPER_STATE.type_name, header=header(3.05), source=source,
                         **values)


def test_batch_rows_equal_single_messages_and_decode():
    rng = np.random.default_rng(3)
    k, n = 9, 5
    acc = rng.standard_normal((k, 3, n))
    t0 = np.arange(k) * 0.005 + 0.1
    fields = sample_fields(ch.ACCELERATION.type_name)
    layout = cdr_layout(ch.ACCELERATION.type_name, dict.fromkeys(fields, n),
                        {"header.frame_id": "wing"})
    rows = layout.batch(k)
    rows["header.stamp.sec"], rows["header.stamp.nanosec"] = split_stamps(
        stamps_from_seconds(t0))
    rows["sample_rate"] = 1000.0
    rows["first_sample_index"] = np.arange(k) * n
    for i, name in enumerate(fields):
        rows[name] = acc[:, i]
    data = rows.tobytes()
    assert len(data) == k * layout.size
    for j in range(k):
        one = data[j * layout.size:(j + 1) * layout.size]
        msg = STORE.deserialize_cdr(one, ch.ACCELERATION.type_name)
        assert msg.first_sample_index == j * n and msg.header.frame_id == "wing"
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp_ns(t0[j])
        np.testing.assert_array_equal(msg.pitch, acc[j, 1])


def test_layout_offsets_follow_the_alignment_rules():
    layout = cdr_layout(ch.ACCELERATION.type_name, dict.fromkeys(
        sample_fields(ch.ACCELERATION.type_name), 2), {"header.frame_id": "wing"})
    # header 4 | sec 4 | nanosec 4 | len 4 | "wing\0" 5 | pad 3 | rate 8 | index 8 | ...
    assert layout.fields["header.stamp.sec"][0] == 4
    assert layout.fields["sample_rate"][0] == 4 + 24
    assert layout.fields["first_sample_index"][0] == 4 + 32
    offset, dtype, shape = layout.fields["plunge"]
    assert (offset, dtype.str, shape) == (4 + 48, "<f8", (2,))  # length at 40, padded to 48
    assert layout.template[:4] == CDR_HEADER
    assert layout.fields["plunge"] != cdr_layout(ch.ACCELERATION.type_name, dict.fromkeys(
        sample_fields(ch.ACCELERATION.type_name), 2), {"header.frame_id": "w"}).fields["plunge"]


def test_a_field_added_to_a_msg_file_is_laid_out(tmp_path, monkeypatch):
    """The layout follows the parsed definition: no message is described twice."""
    from rosbags.typesys import get_types_from_msg

    from aero_dva.bag import batch_cdr, schemas

    text = (INTERFACES / "dva_msgs/msg/FlightCondition.msg").read_text()
    extended = get_types_from_msg(text + "\nuint16 quality\nfloat64[] spare\n",
                                  "pkg_x/msg/Extended")
    monkeypatch.setattr(batch_cdr, "message_fields",
                        lambda name: extended[name][1] if name == "pkg_x/msg/Extended"
                        else schemas.message_fields(name))
    layout = cdr_layout("pkg_x/msg/Extended", {"spare": 2})
    assert list(layout.fields)[-3:] == ["air_density", "quality", "spare"]
    assert layout.fields["quality"][1].str == "<u2"
    assert layout.fields["spare"][0] == layout.fields["quality"][0] + 2 + 2 + 4  # count, pad


def test_wing_model_outputs_are_the_sample_fields():
    """Rows of the simulators' arrays map onto the message fields by these names."""
    assert set(sample_fields(ch.ACCELERATION.type_name)) == set(ACCELERATION_NAMES)
    assert set(sample_fields(ch.DISPLACEMENT.type_name)) == set(DISPLACEMENT_NAMES)
    assert sample_fields(ch.EXCITATION.type_name) == ("aileron_force",)


def test_stamps_round_like_the_node():
    for t in [0.0, 1e-9, 0.5e-9, 1.5e-9, 2.5e-9, 0.3, 6839.95, 1.0 - 1e-10]:
        ns = stamp_ns(t)
        assert ns == int(round(t * 1e9))
        assert stamps_from_seconds([t])[0] == ns
    assert split_stamps([1_999_999_999])[0][0] == 1
    assert split_stamps([1_999_999_999])[1][0] == 999_999_999


def test_bad_inputs_are_named():
    acc = ch.ACCELERATION.type_name
    with pytest.raises(ValueError, match="plunge is a sequence: its length must be given"):
        cdr_layout(acc)
    with pytest.raises(ValueError, match="length must be an integer >= 0"):
        cdr_layout(acc, {"plunge": -1, "pitch": 1, "leading_edge": 1})
    with pytest.raises(ValueError, match=r"no string or sequence fields \['bogus'\]"):
        cdr_layout(ch.CLOCK.type_name, {"bogus": 1})
    with pytest.raises(ValueError, match="NUL"):
        cdr_layout(ch.DAMPER_COMMAND.type_name, strings={"source": "a\0b"})
    with pytest.raises(TypeError, match="source must be a string"):
        cdr_layout(ch.DAMPER_COMMAND.type_name, strings={"source": 5})
    with pytest.raises(ValueError, match="only empty sequences"):
        cdr_layout(ch.DIAGNOSTICS.type_name, {"status": 1})
    with pytest.raises(ValueError, match="count"):
        cdr_layout(ch.CLOCK.type_name).batch(-2)
    with pytest.raises(ValueError, match="int32"):
        stamp_ns(2.0**31)
    with pytest.raises(ValueError, match="finite"):
        stamps_from_seconds([math.nan])
