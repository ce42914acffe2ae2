"""Airspeed schedule c2 = a0 + a1 U (Zhang (2006) eq. 7.1) and its JSON file."""

import json

import numpy as np
import pytest

from aero_dva.control.airspeed_schedule import AirspeedSchedule, fit_airspeed_schedule
from aero_dva.control.schedule_io import ScheduleFileError, load_schedule, save_schedule

DAMPER = (0.0, 2500.0)  # [N s/m]


def test_fit_recovers_a_line_inside_the_range_only():
    u = np.linspace(80.0, 125.0, 46)
    c2 = -2000.0 + 30.0 * u
    c2[u < 115.0] = 100.0  # the curved part the study leaves out of the fit
    fit = fit_airspeed_schedule(u, c2, DAMPER, airspeed_range=(115.0, 120.0))
    assert fit.schedule.a0 == pytest.approx(-2000.0, rel=1e-10)
    assert fit.schedule.a1 == pytest.approx(30.0, rel=1e-10)
    assert fit.n_points == 6
    assert fit.rmse < 1e-9 and fit.r_squared == pytest.approx(1.0)


def test_fit_matches_ordinary_least_squares_on_noisy_data():
    rng = np.random.default_rng(4)
    u = rng.uniform(100.0, 130.0, 50)
    c2 = 500.0 + 12.0 * u + rng.normal(0.0, 20.0, 50)
    fit = fit_airspeed_schedule(u, c2, DAMPER)
    a1, a0 = np.polyfit(u, c2, 1)
    assert (fit.schedule.a0, fit.schedule.a1) == pytest.approx((a0, a1), rel=1e-9)
    residual = c2 - (a0 + a1 * u)
    assert fit.rmse == pytest.approx(np.sqrt(np.mean(residual**2)), rel=1e-9)
    assert fit.max_abs_error == pytest.approx(np.max(np.abs(residual)), rel=1e-9)
    assert fit.schedule.airspeed_range == (u.min(), u.max())


def test_evaluation_clamps_to_the_damper_and_extrapolates_by_default():
    s = AirspeedSchedule(
        a0=-2000.0, a1=30.0, airspeed_range=(115.0, 120.0), damping_range=(200.0, 1800.0)
    )
    assert s.evaluate(116.0) == pytest.approx(1480.0)
    assert s.evaluate(125.0) == pytest.approx(1750.0)  # outside the fit, on the line
    assert s.evaluate(130.0) == 1800.0  # clamped to the damper's maximum
    assert s.evaluate(50.0) == 200.0  # clamped to the minimum
    assert s.evaluate(125.0, extrapolate=False) == pytest.approx(1600.0)  # held at 120 m/s
    np.testing.assert_allclose(s.evaluate([116.0, 130.0]), [1480.0, 1800.0])
    assert s.in_range(117.0) and not s.in_range(121.0)


@pytest.mark.parametrize("airspeed", [np.nan, np.inf, -1.0])
def test_evaluation_refuses_bad_airspeeds(airspeed):
    s = AirspeedSchedule(0.0, 10.0, (100.0, 120.0), DAMPER)
    with pytest.raises(ValueError, match="airspeed"):
        s.evaluate(airspeed)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (([110.0, 110.0], [1.0, 2.0], DAMPER), "two distinct"),
        (([110.0, 120.0], [1.0, np.nan], DAMPER), "optimal_damping"),
        (([110.0, 120.0], [1.0], DAMPER), "optimal_damping"),
        (([110.0, 120.0], [1.0, 2.0], (10.0, 5.0)), "damping_range"),
        (([110.0, 120.0], [1.0, 2.0], (-1.0, 5.0)), "damping_range"),
    ],
)
def test_fit_arguments_are_validated(args, match):
    with pytest.raises(ValueError, match=match):
        fit_airspeed_schedule(*args)


def test_too_few_points_in_the_range():
    with pytest.raises(ValueError, match="airspeed_range"):
        fit_airspeed_schedule([100.0, 110.0, 121.0], [1.0, 2.0, 3.0], DAMPER, (115.0, 120.0))


def test_file_round_trip(tmp_path):
    s = AirspeedSchedule(-2150.5, 31.25, (115.0, 120.0), (0.0, 2500.0))
    path = save_schedule(s, tmp_path / "schedule.json", description="fit on fig. 7.4")
    assert load_schedule(path) == s
    data = json.loads(path.read_text())
    assert data["units"]["a1"] == "N s^2/m^2" and data["description"] == "fit on fig. 7.4"


def write(tmp_path, **changes):
    s = AirspeedSchedule(-2150.5, 31.25, (115.0, 120.0), (0.0, 2500.0))
    path = save_schedule(s, tmp_path / "schedule.json")
    data = json.loads(path.read_text())
    for key, value in changes.items():
        if value is None:
            del data[key]
        else:
            data[key] = value
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        (
            {"units": {"a0": "N s/mm", "a1": "N s^2/m^2", "airspeed": "m/s", "damping": "N s/m"}},
            "units",
        ),
        ({"a1": None}, "'a1' is missing"),
        ({"a0": "12"}, "'a0' must be a number"),
        ({"damping_max": float("nan")}, "'damping_max' must be finite"),
        ({"airspeed_min": 130.0}, "airspeed_range"),
        ({"version": 2}, "version 2"),
        ({"format": "something_else"}, "format"),
    ],
)
def test_invalid_files_name_the_field(tmp_path, changes, match):
    path = write(tmp_path, **changes)
    with pytest.raises(ScheduleFileError, match=match) as info:
        load_schedule(path)
    assert "schedule.json" in str(info.value)


def test_unreadable_files(tmp_path):
    with pytest.raises(ScheduleFileError, match="cannot read"):
        load_schedule(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ScheduleFileError, match="not valid JSON"):
        load_schedule(bad)
