"""Flight-log domain of the discrepancy loop: hidden plant, FRF estimator, domain, CLI.

The randomised acceptance rates, and the clean flights' "consistent" verdict, are in
test_discrepancy_flight_acceptance.py; here the pieces and the CLI on one named effect.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.hidden_plant import PlantOptions, PlantSimulator
from aero_dva.flight.scenario import AirspeedProfile, Scenario, ScenarioError
from aero_dva.flight.scenario_io import scenario_from_dict
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.wing.wing_io import load_wing
from dva_offline.cli import main
from dva_offline.discrepancy.flight_domain import FlightDomain, arrays_from_log
from dva_offline.discrepancy.flight_synthetic import generate_flight

WING = load_wing(None)
ABSORBER = WING.maxwell_design


def _scenario(plant=None, duration=2.0, **kw):
    return Scenario("t", duration, block_size=50,
                    airspeed=AirspeedProfile("constant", (60.0,)), seed=4, plant=plant, **kw)


def _fly(scenario):
    config = dataclasses.replace(load_runtime_config({}), scenario=scenario)
    runtime = FlightRuntime(config)
    blocks = []
    while not runtime.done:
        blocks.append(runtime.step())
    return runtime, (np.concatenate([b.accelerations for b in blocks], axis=1),
                     np.concatenate([b.displacements for b in blocks], axis=1))


# -- hidden plant ------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, word", [
    ({"actuator_lag": -1.0}, "actuator_lag"),
    ({"sensor_delay": 2.0}, "sensor_delay"),
    ({"cubic_stiffness": float("nan")}, "cubic_stiffness"),
    ({"unsteady_aero": 3.0}, "unsteady_aero"),
    ({"drift_parameter": "mass"}, "drift"),
    ({"sensor_noise": (0.1, -1.0, 0.0)}, "sensor_noise.pitch"),
    ({"sensor_gain": (1.0, 1.0)}, "sensor_gain"),
])
def test_plant_options_reject_bad_values(kwargs, word):
    with pytest.raises(ValueError, match=word):
        PlantOptions(**kwargs)


def test_plant_section_of_a_scenario_file():
    raw = {"duration": 10.0, "airspeed": {"kind": "constant", "value": 60.0},
           "excitation": {"force_std": 500.0, "levels": [1.0, 2.0], "level_dwell": 5.0},
           "plant": {"actuator_lag": {"time_constant": 0.5},
                     "drift": {"parameter": "absorber_stiffness", "rate": -0.01},
                     "sensor_noise": {"pitch": 0.2}}}
    s = scenario_from_dict(raw)
    assert s.plant == PlantOptions(actuator_lag=0.5, drift_parameter="absorber_stiffness",
                                   drift_rate=-0.01, sensor_noise=(0.0, 0.2, 0.0))
    assert s.force_levels == (1.0, 2.0) and s.level_dwell == 5.0
    for plant, word in (({"lag": {}}, "unknown plant effects"),
                        ({"actuator_lag": {"tau": 1}}, "unknown keys"),
                        ({"actuator_lag": {}}, "needs 'time_constant'"),
                        ({"sensor_delay": {"delay": "x"}}, "must be a number"),
                        ({"drift": {"parameter": "pitch_stiffness", "rate": 0.04}}, "50 %")):
        with pytest.raises(ScenarioError, match=word):
            scenario_from_dict({**raw, "duration": 20.0, "plant": plant})


def test_default_and_nominal_plant_fly_the_unchanged_simulator():
    _, (acc0, disp0) = _fly(_scenario())
    _, (acc1, disp1) = _fly(_scenario(PlantOptions()))  # all nominal: not active
    assert np.array_equal(acc0, acc1) and np.array_equal(disp0, disp1)
    # an active plant without effects on the dynamics gives the same wing motion
    _, (acc2, disp2) = _fly(_scenario(PlantOptions(sensor_gain=(1.0, 1.0, 1.0 + 1e-12))))
    assert np.allclose(disp2, disp0, rtol=0, atol=1e-12 * np.abs(disp0).max())


def test_force_levels_scale_the_excitation():
    # same random stream, scaled by the level in force
    r = FlightRuntime(dataclasses.replace(load_runtime_config({}), scenario=_scenario(
        force_levels=(1.0, 3.0), level_dwell=1.0)))
    f = np.concatenate([r.step().force for _ in range(40)])
    r0 = FlightRuntime(dataclasses.replace(load_runtime_config({}), scenario=_scenario()))
    f0 = np.concatenate([r0.step().force for _ in range(40)])
    assert np.allclose(f[:1000], f0[:1000]) and np.allclose(f[1000:], 3 * f0[1000:])


def test_sensor_delay_gain_and_noise_act_on_the_accelerometers_only():
    _, (acc0, disp0) = _fly(_scenario())
    _, (acc1, disp1) = _fly(_scenario(PlantOptions(sensor_delay=0.007,
                                                   sensor_gain=(1.0, 1.1, 1.0))))
    assert np.allclose(disp1, disp0, atol=1e-12 * np.abs(disp0).max())
    assert np.allclose(acc1[0, 7:], acc0[0, :-7]) and np.all(acc1[:, :7] == 0.0)
    assert np.allclose(acc1[1, 7:], 1.1 * acc0[1, :-7])
    _, (acc2, _) = _fly(_scenario(PlantOptions(sensor_noise=(0.5, 0.0, 0.0))))
    noise = acc2[0] - acc0[0]
    assert abs(noise.std() - 0.5) < 0.05 and np.allclose(acc2[1], acc0[1])


def test_actuator_lag_delays_the_c2_the_wing_feels():
    rng = np.random.default_rng(0)
    f = 1000 * rng.standard_normal(4000)
    c = np.r_[np.full(2000, 150.0), np.full(2000, 1200.0)]
    nominal = StreamingSimulator(WING.wing, ABSORBER, 1000.0, WING.aero).advance(f, 60.0, 1.2, c)
    lagged = PlantSimulator(WING.wing, ABSORBER, 1000.0, WING.aero,
                            PlantOptions(actuator_lag=0.5))
    out = np.concatenate([lagged.advance(f[i:i + 50], 60.0, 1.2, c[i:i + 50]).displacements
                          for i in range(0, 4000, 50)], axis=1)
    err = np.abs(out[3] - nominal.displacements[3])  # DVA stroke feels c2 most
    scale = np.abs(nominal.displacements[3]).max()
    assert err[:2000].max() < 1e-9 * scale  # same before the step
    assert err[2000:2500].max() > 0.05 * scale  # the lagged c2 differs right after it


def test_cubic_stiffness_hardens_the_pitch_spring_with_amplitude():
    rng = np.random.default_rng(1)
    f = rng.standard_normal(6000)

    def pitch(kappa, level):
        sim = PlantSimulator(WING.wing, ABSORBER, 1000.0, WING.aero,
                             PlantOptions(cubic_stiffness=kappa, sensor_noise=(0, 0, 1e-9)))
        return np.concatenate([sim.advance(level * f[i:i + 50], 40.0, 1.2, 300.0)
                               .displacements[1] for i in range(0, 6000, 50)])

    for level, low, high in ((50.0, 0.0, 0.01), (4000.0, 0.05, 0.9)):
        lin, cub = pitch(0.0, level), pitch(3e5, level)
        change = np.std(cub - lin) / np.std(lin)
        assert low <= change <= high, (level, change)  # nonlinear: only at large amplitude
        if level > 1000:
            assert cub.std() < lin.std()  # a stiffer pitch spring: less pitch


# -- the model through the estimator (output error) -----------------------------------------
@pytest.mark.parametrize("plant, effect", [
    (PlantOptions(), {}),
    (PlantOptions(cubic_stiffness=1.5e5), {"kappa": 1.5e5}),  # nonlinear: +65 % at 3 kN
    (PlantOptions(unsteady_aero=0.7), {"aero_scale": 0.7}),
    (PlantOptions(sensor_delay=0.004), {"delay": 0.004}),
])
def test_model_through_the_estimator_reproduces_a_noise_free_flight(plant, effect, tmp_path):
    """The simulated response to the logged force, through the same windows, equals the
    measured H1 estimates exactly when the model is the plant (no noise): no leakage or
    transient is left in the residual, only what the model lacks."""
    from aero_dva.bag.flight_log_io import load_flight_log
    from aero_dva.bag.runtime_recording import record_runtime

    scenario = Scenario("t", 16.0, block_size=50,
                        airspeed=AirspeedProfile("steps", (0.6, 0.75), relative=True),
                        dwell=4.0, sweep_damping=(200.0, 1200.0), force_std=1000.0, seed=3,
                        force_levels=(1.0, 3.0), level_dwell=8.0, plant=plant)
    config = dataclasses.replace(load_runtime_config({}), scenario=scenario)
    record_runtime(tmp_path / "bag", FlightRuntime(config))
    domain = FlightDomain(arrays_from_log(load_flight_log(tmp_path / "bag")), WING)
    nominal = (WING.wing.pitch_stiffness, WING.wing.plunge_stiffness, WING.wing.damping_factor)
    measured = domain.observations.values
    rel = np.abs(domain._predict(nominal, **effect) - measured) / np.abs(measured)
    assert rel.max() < 1e-6
    if effect:  # and the baseline does not: the effect is in the residual
        rel0 = np.abs(domain._predict(nominal) - measured) / np.abs(measured)
        assert np.median(rel0) > 0.01


# -- the domain on recorded flights ----------------------------------------------------------
@pytest.fixture(scope="module")
def delay_case(tmp_path_factory):
    return generate_flight("sensor_delay", 5, tmp_path_factory.mktemp("flight") / "bag")


def test_recorded_topics_do_not_name_the_plant(delay_case):
    blob = b"".join(p.read_bytes() for p in Path(delay_case.path).rglob("*") if p.is_file())
    # words of 5+ letters: short ones turn up by chance in the binary sample data
    for word in (b"delay", b"plant", b"actuator", b"cubic", b"drift", b"unsteady", b"hidden",
                 b"kappa", b"sensor"):
        assert word not in blob.lower()


def test_flight_cli_names_a_sensor_delay(delay_case, capsys, tmp_path):
    assert main(["discrepancy", "flight", str(delay_case.path), "--json",
                 "--plot-dir", str(tmp_path / "plots")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"]["status"] == "explained"
    assert out["verdict"]["effect"] == "sensor_delay"
    assert out["augmented"]["error"] < 0.5 * out["baseline"]["error"]
    (delay,) = out["augmented"]["parameters"]
    truth = delay_case.parameters["delay_s"]
    assert abs(delay["value"] - truth) < max(3 * delay["std"], 0.2e-3)
    assert {c["effect"] for c in out["candidates"]} >= {
        "actuator_lag", "sensor_delay", "cubic_stiffness", "unsteady_aero", "parameter_drift"}
    assert all("error" in c for c in out["candidates"])
    assert {"model", "error"} <= set(out["baseline"])
    assert all(Path(p).is_file() for p in out["plots"])


def test_flight_cli_errors_name_the_problem(tmp_path, capsys):
    assert main(["discrepancy", "flight", str(tmp_path / "missing.mcap")]) == 2
    assert "not found" in capsys.readouterr().err
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bad / "x.mcap").write_bytes(b"not an mcap file")
    assert main(["discrepancy", "flight", str(bad)]) == 2
    assert "error" in capsys.readouterr().err.lower()


def test_short_flight_and_missing_topics_are_refused(tmp_path, capsys):
    from aero_dva.bag.runtime_recording import record_runtime

    config = dataclasses.replace(load_runtime_config({}), scenario=_scenario(duration=2.5))
    record_runtime(tmp_path / "short", FlightRuntime(config))
    assert main(["discrepancy", "flight", str(tmp_path / "short")]) == 2
    assert "too short a log" in capsys.readouterr().err
    record_runtime(tmp_path / "nodamper", FlightRuntime(config), damper_state=False)
    assert main(["discrepancy", "flight", str(tmp_path / "nodamper")]) == 2
    assert "/dva/damper_state" in capsys.readouterr().err


def test_a_cut_flight_log_is_refused_or_read_with_allow_truncated(tmp_path, capsys):
    from aero_dva.bag.runtime_recording import record_runtime

    config = dataclasses.replace(load_runtime_config({}), scenario=_scenario(duration=2.5))
    record_runtime(tmp_path / "short", FlightRuntime(config))
    cut = tmp_path / "cut"
    cut.mkdir()
    data = next((tmp_path / "short").glob("*.mcap")).read_bytes()
    (cut / "cut_0.mcap").write_bytes(data[:len(data) // 2])
    assert main(["discrepancy", "flight", str(cut)]) == 2
    err = capsys.readouterr().err
    assert "dva bag recover" in err and "allow_truncated" not in err
    # With the flag the log is read up to the damage (and is then too short to analyse).
    assert main(["discrepancy", "flight", str(cut), "--allow-truncated"]) == 2
    err = capsys.readouterr().err
    assert "too short a log" in err and "warning: MCAP file" in err
