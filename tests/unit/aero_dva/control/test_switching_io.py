"""The switching-gains file: round trip and refusal of bad files, naming the field."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from aero_dva.control.switching_design import law_gain
from aero_dva.control.switching_io import (
    SwitchingGains,
    SwitchingGainsError,
    gains_problem,
    gains_to_dict,
    load_gains,
    save_gains,
    wing_problem,
)
from aero_dva.flight.per_sample.switching_law import SwitchingLaw
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing, wing_fingerprint


@pytest.fixture(scope="module")
def gains():
    cfg = load_wing(None)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    gain = law_gain(model, 115.0, 1.2, 100.0, 2500.0, design="clipped")
    law = SwitchingLaw(gain, 100.0, 2500.0, np.full((7, 4), 0.25))
    return SwitchingGains(law=law, design="clipped", wing_fingerprint="abc",
                          design_airspeed=115.0, density=1.2, time_constant=0.01,
                          sample_rate=1000.0, effort=1.0, state_names=model.state_names,
                          selection=[{"effort": 1.0}], description="test")


def test_round_trip(tmp_path, gains):
    back = load_gains(save_gains(gains, tmp_path / "g.json"))
    assert np.array_equal(back.law.gain, gains.law.gain)
    assert np.array_equal(back.law.observer, gains.law.observer)
    assert (back.law.c_lo, back.law.c_hi, back.design) == (100.0, 2500.0, "clipped")
    assert back.selection == [{"effort": 1.0}]


@pytest.mark.parametrize("change, message", [
    ({"format": "x"}, "format"),
    ({"c_lo": 2000.0, "c_hi": 1000.0}, "c_lo < c_hi"),
    ({"c_hi": 1e12}, "lies outside the damper's range"),
    ({"c_hi": None}, "'c_hi' must be a number"),
    ({"time_constant": -0.1}, "time_constant"),
    ({"gain": [1.0, 2.0]}, "'gain' must have 7 entries"),
    ({"observer": [[1.0]]}, "observer"),
    ({"design": "magic"}, "design"),
    ({"units": {"damping": "N s/mm"}}, "units"),
])
def test_bad_files_are_refused_naming_the_field(tmp_path, gains, change, message):
    data = gains_to_dict(gains)
    data.update(change)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(SwitchingGainsError, match=message):
        load_gains(path)


def test_non_finite_gain_is_refused(tmp_path, gains):
    data = gains_to_dict(gains)
    text = json.dumps(data).replace(str(data["gain"][0]), "NaN", 1)
    path = tmp_path / "nan.json"
    path.write_text(text)
    with pytest.raises(SwitchingGainsError, match="finite"):
        load_gains(path)


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(SwitchingGainsError):
        load_gains(tmp_path / "none.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(SwitchingGainsError, match="not valid JSON"):
        load_gains(tmp_path / "broken.json")


def test_gains_for_another_wing_or_other_states_are_refused_by_one_rule(tmp_path, gains):
    # one rule for the simulator (with_switching), the supervisor node and `dva switching`
    names = gains.state_names
    assert wing_problem(gains, "g.json", "abc", names) is None
    assert "designed for another wing (fingerprint abc" in wing_problem(gains, "g.json", "xyz")
    assert "are not the flown wing's" in wing_problem(gains, "g.json", "abc", names[::-1])
    path = save_gains(gains, tmp_path / "g.json")  # fingerprint "abc": not the package's wing
    assert "another wing" in gains_problem(path)
    assert gains_problem(tmp_path / "none.json").startswith("invalid switching gains")
    ours = save_gains(dataclasses.replace(gains, wing_fingerprint=wing_fingerprint(
        load_wing(None))), tmp_path / "ours.json")
    assert gains_problem(ours) is None


@pytest.fixture(scope="module")
def scheduled():
    from aero_dva.control.clipped_optimal import scheduled_law

    cfg = load_wing(None)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    law = scheduled_law(model, [80.0, 100.0, 120.0], 1.2, 100.0, 2500.0, effort=30.0,
                        lead=0.01, observer=np.full((7, 4), 0.25))
    return SwitchingGains(law=law, design="clipped_optimal", wing_fingerprint="abc",
                          design_airspeed=115.0, density=1.2, time_constant=0.01,
                          sample_rate=1000.0, effort=30.0, state_names=model.state_names,
                          lead=0.01)


def test_a_scheduled_law_round_trips(tmp_path, scheduled):
    back = load_gains(save_gains(scheduled, tmp_path / "s.json"))
    assert back.design == "clipped_optimal" and back.law.scheduled
    assert np.array_equal(back.law.airspeeds, [80.0, 100.0, 120.0])
    assert np.array_equal(back.law.gain, scheduled.law.gain)
    assert np.array_equal(back.law.force_gain, scheduled.law.force_gain)


@pytest.mark.parametrize("change, message", [
    ({"airspeeds": None}, "'airspeeds' is required with design 'clipped_optimal'"),
    ({"design": "clipped"}, "'airspeeds' is required with design 'clipped_optimal' and "
                            "only with it"),
    ({"airspeeds": [80.0, 100.0]}, "in each of 2 rows, one per airspeed"),
    ({"airspeeds": [80.0, 120.0, 100.0]}, "increasing"),
    ({"force_gain": [[0.0] * 7] * 2}, "force_gain"),
])
def test_bad_schedules_are_refused_naming_the_field(tmp_path, scheduled, change, message):
    data = gains_to_dict(scheduled)
    data.update(change)
    if data["airspeeds"] is None:
        del data["airspeeds"]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(SwitchingGainsError, match=message):
        load_gains(path)


def test_the_package_files_are_for_the_package_wing():
    """The shipped gains of both per-sample laws load and are the default wing's: the
    switching law's at one airspeed, the clipped-optimal law's scheduled with it."""
    from aero_dva.data_files import data_file

    for name, design, scheduled in (("switching_gains.json", "lyapunov", False),
                                    ("clipped_optimal_gains.json", "clipped_optimal", True)):
        path = data_file(name)
        assert gains_problem(path) is None
        g = load_gains(path)
        assert (g.design, g.law.scheduled, g.time_constant) == (design, scheduled, 0.01)
