"""No route applies a c2 outside the damper's range: commands, the per-sample law, sweeps,
training plans, schedules, replays and the design commands, each flown or run with hostile
values. Loaders and commands refuse them in one line; what flies stays inside the range."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from aero_dva.control.command_laws import ScheduleLaw
from aero_dva.control.schedule_io import (
    ScheduleFileError,
    load_schedule,
    save_schedule,
    schedule_from_dict,
)
from aero_dva.control.switching_io import (
    SwitchingGainsError,
    load_gains,
    save_gains,
    with_switching,
)
from aero_dva.data_files import data_file
from aero_dva.flight.damper import (
    DAMPER_RANGE,
    SWITCHING_SOURCE,
    DamperMode,
    check_damping,
    damping_problem,
)
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.per_sample.switching_law import SwitchingLaw
from aero_dva.flight.seed_batch import IdealDampers
from dva_offline import cli

HOSTILE = (1e12, 1e300, math.inf, -math.inf, math.nan, -1.0, -5e-324, 2500.0000001, 5e3)
LOW, HIGH = DAMPER_RANGE


def hold_scenario(tmp_path, duration=0.5):
    path = tmp_path / "hold.yaml"
    path.write_text(f"name: hold\nduration: {duration}\nblock_size: 50\n"
                    "airspeed: {kind: constant, value_ratio: 1.0}\n"
                    "excitation: {force_std: 1000.0, seed: 7}\n")
    return str(path)


def applied(rt, blocks, command):
    """Fly ``blocks`` blocks, ``command(k)`` before each; every c2 the wing flew with."""
    flown = []
    for k in range(blocks):
        value = command(k)
        if value is not None:
            rt.command(*value)
        block = rt.step()
        flown += list(block.damping) + [rt.flown_damper.applied_damping,
                                        rt.damper_snapshot().applied_damping]
    return np.array(flown)


def in_range(values, low=LOW, high=HIGH):
    values = np.asarray(values, dtype=float)
    return bool(np.all(np.isfinite(values)) and np.all((values >= low) & (values <= high)))


def test_damping_problem_names_the_input_and_the_range():
    assert damping_problem([0.0, 2500.0, 624.7], "x") is None
    for value in HOSTILE[:-1]:
        text = damping_problem(value, "--thing")
        assert text.startswith("--thing: ") and "[0, 2500] N s/m" in text, value
        assert "\n" not in text
    with pytest.raises(ValueError, match="outside the damper's range"):
        check_damping([1.0, 1e12, 2e12], "plan")


@pytest.mark.parametrize("lag", [0.0, 0.03])
def test_hostile_commands_never_leave_the_range(tmp_path, lag):
    config = load_runtime_config({"scenario": hold_scenario(tmp_path),
                                  "damper_time_constant": lag})
    rt = FlightRuntime(config)
    c2 = applied(rt, 10, lambda k: (HOSTILE[k % len(HOSTILE)], "fixed"))
    assert in_range(c2)
    assert c2.max() == pytest.approx(HIGH) if lag == 0.0 else c2.max() <= HIGH


def test_a_narrower_configured_damper_clips_to_its_own_range(tmp_path):
    config = load_runtime_config({"scenario": hold_scenario(tmp_path), "damper_min": 100.0,
                                  "damper_max": 900.0})
    c2 = applied(FlightRuntime(config), 10, lambda k: ((0.0, 5e3, 1e12)[k % 3], "fixed"))
    assert in_range(c2, 100.0, 900.0) and {100.0, 900.0} <= set(c2.tolist())


def hostile_gains(tmp_path, c_lo=100.0, c_hi=1e12):
    data = json.loads(data_file("switching_gains.json").read_text())
    data.update(c_lo=c_lo, c_hi=c_hi)
    path = tmp_path / "gains.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("c_lo, c_hi", [(100.0, 1e12), (100.0, 2600.0), (1e-300, 1e300)])
def test_the_gains_loader_refuses_levels_outside_the_damper(tmp_path, c_lo, c_hi):
    path = hostile_gains(tmp_path, c_lo, c_hi)
    with pytest.raises(SwitchingGainsError, match="outside the damper's range") as err:
        load_gains(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_the_law_with_hostile_levels_never_flies(tmp_path):
    # Through the loader: the flight is told why and holds the commands' constant c2.
    config = load_runtime_config({"scenario": hold_scenario(tmp_path),
                                  "damper_time_constant": 0.01})
    rt = FlightRuntime(with_switching(config, str(hostile_gains(tmp_path))))
    assert "outside the damper's range" in rt.law_problem()
    c2 = applied(rt, 6, lambda k: (624.7, SWITCHING_SOURCE))
    assert in_range(c2) and rt.damper_snapshot().mode == DamperMode.SWITCHING_REFUSED
    # Around the loader (gains built in code): the flight itself refuses the law.
    good = with_switching(config, str(data_file("switching_gains.json")))
    gains = good.per_sample[SWITCHING_SOURCE]
    law = gains.law
    bad = dataclasses.replace(good, per_sample={SWITCHING_SOURCE: dataclasses.replace(
        gains, law=SwitchingLaw(law.gain, law.c_lo, 1e12, law.observer, law.force_gain))})
    rt = FlightRuntime(bad)
    assert "outside the damper's range" in rt.law_problem()
    c2 = applied(rt, 6, lambda k: (624.7, SWITCHING_SOURCE))
    assert in_range(c2) and rt.damper_snapshot().mode == DamperMode.SWITCHING_REFUSED


def test_valid_gains_on_a_narrower_damper_are_refused_by_the_flight(tmp_path):
    config = load_runtime_config({"scenario": hold_scenario(tmp_path), "damper_max": 1000.0,
                                  "damper_time_constant": 0.01})
    rt = FlightRuntime(with_switching(config, str(data_file("switching_gains.json"))))
    assert "[0, 1000] N s/m" in rt.law_problem()
    assert in_range(applied(rt, 6, lambda k: (624.7, SWITCHING_SOURCE)), 0.0, 1000.0)


def test_the_law_in_range_flies_inside_it(tmp_path):
    config = load_runtime_config({"scenario": hold_scenario(tmp_path),
                                  "damper_time_constant": 0.01})
    rt = FlightRuntime(with_switching(config, str(data_file("switching_gains.json"))))
    c2 = applied(rt, 6, lambda k: (624.7, SWITCHING_SOURCE))
    assert rt.damper_snapshot().mode == DamperMode.SWITCHING
    assert in_range(c2) and np.unique(c2).size > 2


def test_a_sweep_outside_the_range_is_refused_before_it_flies(tmp_path):
    from aero_dva.flight.scenario_io import load_scenario

    def sweep(values):
        path = tmp_path / "sweep.yaml"
        path.write_text("name: sweep\nduration: auto\nblock_size: 50\n"
                        "airspeed: {kind: steps, start_ratio: 0.9, end_ratio: 0.9, "
                        f"step_ratio: 0.002}}\nsweep: {{dwell: 1.0, damping: {values}}}\n"
                        "excitation: {force_std: 1000.0, seed: 7}\n")
        return str(path)

    with pytest.raises(ValueError, match="outside the damper's range"):
        load_runtime_config({"scenario": sweep("[100.0, 1.0e+12]")})
    good = load_runtime_config({"scenario": sweep("[100.0, 200.0]")})
    assert in_range(applied(FlightRuntime(good), 40, lambda k: (1e12, "fixed")))
    scenario = dataclasses.replace(load_scenario(sweep("[100.0, 200.0]")),
                                   sweep_damping=(100.0, 1e12))
    with pytest.raises(ValueError, match="outside the damper's range"):
        FlightRuntime(dataclasses.replace(good, scenario=scenario))


def test_seed_batch_dampers_clip_hostile_commands(tmp_path):
    config = load_runtime_config({"scenario": hold_scenario(tmp_path)}).damper
    dampers = IdealDampers(config, len(HOSTILE))
    which = np.arange(len(HOSTILE))
    dampers.command(which, np.array(HOSTILE), 0.0)
    assert in_range(dampers.values(which, 0.01))


def schedule_dict(**change):
    data = {"format": "dva_airspeed_schedule", "version": 1, "a0": -2150.0, "a1": 31.5,
            "airspeed_min": 100.0, "airspeed_max": 120.0, "damping_min": 0.0,
            "damping_max": 2500.0,
            "units": {"a0": "N s/m", "a1": "N s^2/m^2", "airspeed": "m/s", "damping": "N s/m"}}
    data.update(change)
    return data


def test_schedules_outside_the_range_are_neither_read_nor_written(tmp_path):
    good = schedule_from_dict(schedule_dict())
    for change in ({"damping_max": 1e12}, {"damping_min": -1.0}, {"damping_max": 2600.0}):
        with pytest.raises(ScheduleFileError, match="outside the damper's range"):
            schedule_from_dict(schedule_dict(**change), "'s.json'")
    bad = dataclasses.replace(good, damping_range=(0.0, 1e12))
    with pytest.raises(ScheduleFileError, match="outside the damper's range"):
        save_schedule(bad, tmp_path / "s.json")
    assert not (tmp_path / "s.json").exists()
    save_schedule(good, tmp_path / "s.json")
    law = ScheduleLaw(load_schedule(tmp_path / "s.json"), DAMPER_RANGE, True, 1e4)
    assert in_range([law.command_for(u) for u in (0.0, 50.0, 100.0, 1e3, 1e4)])


def test_gains_outside_the_range_are_not_written(tmp_path):
    gains = load_gains(data_file("switching_gains.json"))
    law = gains.law
    bad = dataclasses.replace(gains, law=SwitchingLaw(law.gain, law.c_lo, 1e12, law.observer,
                                                      law.force_gain))
    with pytest.raises(SwitchingGainsError, match="outside the damper's range"):
        save_gains(bad, tmp_path / "g.json")
    assert not (tmp_path / "g.json").exists()


def test_plans_outside_the_range_are_refused_and_never_recorded(tmp_path):
    from dva_offline.training.plan import PlanSettings, TrainingPlan
    from dva_offline.training.plan_io import load_plan, plan_to_dict, save_plan
    from dva_offline.training.recording_io import record_plan

    with pytest.raises(ValueError, match="outside the damper's range"):
        PlanSettings(ratios=(1.0,), damping_range=(0.0, 1e12))
    settings = PlanSettings(ratios=(0.9,), factors=(1.0,), window=0.1)
    nan = np.full((1, 1), np.nan)
    plan = TrainingPlan(settings=settings, critical_airspeed=100.0, base_density=1.2,
                        optimal_damping=nan, stable_low=nan, stable_high=nan,
                        airspeed=np.array([90.0, 90.0]), density=np.array([1.2, 1.2]),
                        damping=np.array([500.0, 1e12]), condition=np.array([0, 0]))
    data = plan_to_dict(plan)
    (tmp_path / "plan.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match="a dwell.s c2: 1e\\+12 N s/m lies outside"):
        load_plan(tmp_path / "plan.json")
    with pytest.raises(ValueError, match="outside the damper's range"):
        save_plan(plan, tmp_path / "written.json")
    assert not (tmp_path / "written.json").exists()
    with pytest.raises(ValueError, match="outside the damper's range"):
        record_plan(tmp_path / "bag", None, plan)
    assert not (tmp_path / "bag").exists()


@pytest.mark.parametrize("argv", [
    ["switching", "design", "--c-hi", "1e12"],
    ["switching", "design", "--c-lo", "-5", "--c-hi", "2000"],
    ["switching", "design", "--c-hi", "nan"],
    ["control", "schedule", "--damping-range", "0:1e12"],
    ["control", "schedule", "--c2-range", "0:5000:51"],
    ["replay", "no_such_bag", "--controller", "fixed", "--damping", "1e12"],
    ["evaluate", "--controllers", "fixed", "--fixed-c2", "1e12"],
])
def test_design_and_run_commands_refuse_a_c2_outside_the_range(argv, tmp_path, capsys):
    out = tmp_path / "out"
    if argv[0] in ("switching", "control", "replay", "evaluate"):
        argv = argv + ["--out", str(out)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "outside the damper's range" in err[-1], err
    assert not out.exists()


@pytest.mark.parametrize("program", ["run_flight", "replay_flight"])
@pytest.mark.parametrize("damping", ["1e12", "-1", "nan", "2600"])
def test_graph_runners_refuse_a_damping_outside_the_range(program, damping, capsys):
    pytest.importorskip("dva_msgs.msg", reason="needs the built workspace")
    import importlib

    module = importlib.import_module(f"aero_dva_sim.{program}")
    argv = ["--controller", "fixed", "--damping", damping]
    if program == "replay_flight":
        argv = ["no_such_bag", *argv, "--out", "no_such_out"]
    assert module.main(argv) == 2  # refused before any node starts
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "outside the damper's range" in err[0], err
