"""Damper model the simulator applies: validation, saturation, lag, staleness, state."""

import math
import re
from pathlib import Path

import pytest

from aero_dva.flight.damper import DamperConfig, DamperModel, DamperStatus, Rejection

MSG_DIR = Path(__file__).resolve().parents[4] / "ros_ws" / "src" / "dva_msgs" / "msg"


def config(**kw):
    base = dict(min_damping=100.0, max_damping=2000.0, fallback_damping=800.0, stale_timeout=0.5)
    base.update(kw)
    return DamperConfig(**base)


def test_status_codes_match_the_message_definition():
    text = (MSG_DIR / "DamperState.msg").read_text()
    constants = dict(re.findall(r"^uint8 STATUS_(\w+) = (\d+)", text, flags=re.MULTILINE))
    assert {k: int(v) for k, v in constants.items()} == {s.name: s.value for s in DamperStatus}


def test_no_command_applies_the_initial_damping():
    damper = DamperModel(config(initial_damping=300.0))
    assert damper.update(1.0) == 300.0
    state = damper.snapshot()
    assert state.status is DamperStatus.NO_COMMAND and state.source == "initial"
    assert math.isnan(state.commanded_damping) and state.command_age == math.inf
    assert (state.min_damping, state.max_damping, state.time) == (100.0, 2000.0, 1.0)


def test_ideal_damper_applies_commands_at_once():
    damper = DamperModel(config())
    result = damper.command(1234.0, 0.1, source="rbf_network")
    assert result.accepted and not result.saturated and result.rejection is None
    assert damper.applied_damping == 1234.0
    state = damper.snapshot()
    assert state.status is DamperStatus.OK and state.source == "rbf_network"
    assert damper.update(0.3) == 1234.0
    assert damper.snapshot().command_age == pytest.approx(0.2)


@pytest.mark.parametrize(("command", "applied"), [(5000.0, 2000.0), (10.0, 100.0), (0.0, 100.0)])
def test_out_of_range_commands_saturate(command, applied):
    damper = DamperModel(config())
    result = damper.command(command, 0.0, source="fixed")
    assert result.accepted and result.saturated and result.target == applied
    assert damper.applied_damping == applied
    assert damper.snapshot().status is DamperStatus.SATURATED


@pytest.mark.parametrize(
    ("command", "reason"),
    [
        (math.nan, Rejection.NOT_A_NUMBER),
        (math.inf, Rejection.INFINITE),
        (-math.inf, Rejection.INFINITE),
        (-1.0, Rejection.NEGATIVE),
        (20000.5, Rejection.ABSURD),  # above 10 x max
    ],
)
def test_bad_commands_are_rejected_and_never_applied(command, reason):
    damper = DamperModel(config())
    damper.command(1500.0, 0.0, source="airspeed_schedule")
    result = damper.command(command, 0.1, source="broken")
    assert not result.accepted and result.rejection is reason
    assert damper.applied_damping == 1500.0
    state = damper.snapshot()
    assert state.status is DamperStatus.REJECTED and state.rejection is reason
    assert state.source == "airspeed_schedule"
    assert state.commanded_damping == command or math.isnan(command)
    # A good command clears the rejection.
    damper.command(900.0, 0.2)
    assert damper.snapshot().status is DamperStatus.OK


def test_absurd_limit_is_ten_times_the_maximum_by_default():
    damper = DamperModel(config())
    assert damper.command(20000.0, 0.0).accepted  # exactly 10 x max: saturated, not rejected
    assert damper.command(20000.1, 0.0).rejection is Rejection.ABSURD


def test_stale_commands_fall_back_and_recover():
    damper = DamperModel(config())
    damper.command(1500.0, 1.0, source="rbf_network")
    assert damper.update(1.5) == 1500.0  # age == timeout: still fresh
    assert damper.snapshot().status is DamperStatus.OK
    assert damper.update(1.6) == 800.0
    state = damper.snapshot()
    assert state.status is DamperStatus.FALLBACK_STALE and state.source == "fallback"
    assert state.command_age == pytest.approx(0.6)
    # Rejected commands do not refresh the timeout.
    damper.command(math.nan, 1.7)
    assert damper.snapshot().status is DamperStatus.FALLBACK_STALE
    damper.command(1200.0, 1.8, source="rbf_network")
    assert damper.applied_damping == 1200.0 and damper.snapshot().status is DamperStatus.OK


def test_lag_is_the_exact_first_order_response_regardless_of_step_size():
    tau = 0.05
    coarse = DamperModel(config(time_constant=tau, initial_damping=200.0, stale_timeout=math.inf))
    fine = DamperModel(config(time_constant=tau, initial_damping=200.0, stale_timeout=math.inf))
    for damper in (coarse, fine):
        damper.command(1200.0, 0.0)
    coarse.update(0.12)
    for k in range(1, 121):
        fine.update(k * 0.001)
    expected = 1200.0 + (200.0 - 1200.0) * math.exp(-0.12 / tau)
    assert coarse.applied_damping == pytest.approx(expected, rel=1e-12)
    assert fine.applied_damping == pytest.approx(expected, rel=1e-10)


def test_lag_sees_the_fallback_switch_at_the_stale_instant():
    tau, timeout = 0.1, 0.5
    damper = DamperModel(config(time_constant=tau, initial_damping=200.0, stale_timeout=timeout))
    damper.command(1200.0, 0.0)
    damper.update(1.0)  # one call across the switch at 0.5 s
    at_switch = 1200.0 + (200.0 - 1200.0) * math.exp(-timeout / tau)
    expected = 800.0 + (at_switch - 800.0) * math.exp(-(1.0 - timeout) / tau)
    assert damper.applied_damping == pytest.approx(expected, rel=1e-12)


def test_time_must_not_go_backwards():
    damper = DamperModel(config())
    damper.update(2.0)
    with pytest.raises(ValueError, match="time"):
        damper.command(500.0, 1.0)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"min_damping": 3000.0}, "min_damping < max_damping"),
        ({"fallback_damping": 5000.0}, "fallback_damping"),
        ({"initial_damping": 50.0}, "initial_damping"),
        ({"stale_timeout": 0.0}, "stale_timeout"),
        ({"time_constant": -0.1}, "time_constant"),
        ({"absurd_factor": 0.5}, "absurd_factor"),
    ],
)
def test_config_is_validated(kw, match):
    with pytest.raises(ValueError, match=match):
        config(**kw)


def test_non_numbers_are_type_errors():
    damper = DamperModel(config())
    with pytest.raises(TypeError, match="damping"):
        damper.command("1000", 0.0)
    with pytest.raises(TypeError, match="source"):
        damper.command(1000.0, 0.0, source=None)


def test_rejected_commands_do_not_keep_the_damper_from_falling_back():
    # A controller sending only NaN is as good as a silent one: the fallback acts after the
    # timeout counted from the last *accepted* command (docs/reliability.md, bursts).
    model = DamperModel(DamperConfig(0.0, 2500.0, 500.0, stale_timeout=0.5))
    model.command(800.0, 0.0)
    for k in range(1, 50):  # NaN every 10 ms up to 0.49 s
        model.command(math.nan, 0.01 * k)
    assert model.applied_damping == 800.0
    for k in range(50, 60):  # and on, past the 0.5 s timeout
        model.command(math.nan, 0.01 * k)
    assert model.applied_damping == 500.0
    assert model.snapshot().status == DamperStatus.FALLBACK_STALE


def test_a_hostile_source_is_echoed_escaped_and_cut():
    """Every damper state carries the source in force: a 10 MB source with escape codes
    reaches the states (and the bag) escaped and cut, not whole."""
    damper = DamperModel(config())
    assert damper.command(500.0, 0.0, source="\x1b[31m\n" + "x" * 10_000_000).accepted
    source = damper.snapshot().source
    assert source.startswith("\\x1b[31m\\n") and len(source) < 200
    assert "\x1b" not in source and "\n" not in source
