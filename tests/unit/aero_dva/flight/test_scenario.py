"""Flight scenarios: profiles, validation, YAML files."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.data_files import DATA_DIR
from aero_dva.flight.scenario import (
    AirspeedProfile,
    Scenario,
    ScenarioError,
    airspeed_at,
    density_at,
    excitation,
    resolve_airspeeds,
    sample_times,
    sweep_damping_at,
)
from aero_dva.flight.scenario_io import load_scenario, scenario_from_dict

CONFIG = DATA_DIR


def test_ramp_profile_is_linear_from_start_to_end():
    s = Scenario("r", 30.0, airspeed=AirspeedProfile("ramp", (80.0, 120.0)))
    t = sample_times(s)
    u = airspeed_at(s, t)
    assert u[0] == 80.0
    assert u[-1] == pytest.approx(120.0, abs=40.0 / 30000 + 1e-9)
    np.testing.assert_allclose(np.diff(u), 40.0 / 30000, rtol=1e-9)


def test_density_variation_is_eq_7_2():
    s = Scenario("d", 2.0, density=1.2, density_variation=0.1, density_frequency=1.0)
    t = np.array([0.0, 0.25, 0.5, 0.75])
    np.testing.assert_allclose(density_at(s, t), [1.2, 1.32, 1.2, 1.08], atol=1e-12)


def test_relative_airspeeds_need_resolving():
    s = Scenario("r", 30.0, airspeed=AirspeedProfile("ramp", (0.8, 1.2), relative=True))
    with pytest.raises(ScenarioError, match="resolve_airspeeds"):
        airspeed_at(s, [0.0])
    resolved = resolve_airspeeds(s, 100.0)
    assert airspeed_at(resolved, [0.0])[0] == pytest.approx(80.0)


def test_excitation_is_reproducible_and_blockwise_identical():
    s = Scenario("e", 1.0, force_std=1000.0, seed=42)
    whole = excitation(s)
    assert np.std(whole) == pytest.approx(1000.0, rel=0.1)
    np.testing.assert_array_equal(whole, excitation(s))
    # Drawing block by block from one generator (as the simulator node does) gives the same force.
    rng = np.random.default_rng(42)
    blocks = np.concatenate([1000.0 * rng.standard_normal(n) for n in (7, 300, 693)])
    np.testing.assert_array_equal(whole, blocks)


def test_sweep_holds_each_pair_for_a_dwell():
    s = Scenario("s", 12.0, airspeed=AirspeedProfile("steps", (80.0, 90.0)), dwell=2.0,
                 sweep_damping=(100.0, 200.0, 300.0))
    t = np.array([0.0, 1.99, 2.0, 5.99, 6.0, 11.99])
    np.testing.assert_array_equal(airspeed_at(s, t), [80, 80, 80, 80, 90, 90])
    np.testing.assert_array_equal(sweep_damping_at(s, t), [100, 100, 200, 300, 100, 300])


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"duration": -1.0}, "duration"),
    ({"duration": float("nan")}, "duration"),
    ({"density": 1200.0}, "kg/m.3 .air., got 1200"),
    ({"density_variation": 1.5}, "density_variation"),
    ({"airspeed": AirspeedProfile("ramp", (80.0,))}, "takes 2 value"),
    ({"airspeed": AirspeedProfile("constant", (3000.0,))}, "absurd"),
    ({"airspeed": AirspeedProfile("steps", (80.0,))}, "sweep_damping"),
    ({"force_std": -5.0}, "force_std"),
])
def test_bad_scenarios_name_the_field(kwargs, message):
    with pytest.raises(ScenarioError, match=message):
        Scenario("bad", **{"duration": 10.0, **kwargs})


def test_shipped_scenarios_load():
    files = sorted(CONFIG.glob("scenario_*.yaml"))
    assert len(files) >= 4
    for path in files:
        assert load_scenario(path).n_samples > 0
    sweep = load_scenario(CONFIG / "scenario_sweep.yaml")
    assert len(sweep.airspeed.values) == 171  # 0.8 .. 1.14 in 0.002 steps
    assert sweep.airspeed.values[-1] == pytest.approx(1.14)
    assert sweep.duration == pytest.approx(171 * 20 * 2.0)
    ramp = load_scenario(CONFIG / "scenario_ramp.yaml")
    assert ramp.airspeed.relative and ramp.airspeed.values == (0.8, 1.2)


def test_yaml_errors_name_file_and_key(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("duration: 10\nairspeed: {kind: ramp, start: 80, end_ratio: 1.2}\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml: airspeed mixes"):
        load_scenario(bad)
    with pytest.raises(ScenarioError, match="unknown scenario keys"):
        scenario_from_dict({"duration": 1, "airspeed": {"kind": "constant", "value": 1},
                            "airpseed": 3})
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "missing.yaml")
    (tmp_path / "broken.yaml").write_text("duration: [1,\n")
    with pytest.raises(ScenarioError, match="not valid YAML"):
        load_scenario(tmp_path / "broken.yaml")
