"""The planned training sweep (``dva train plan|sweep``) and training on it with exact labels."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.control.dva_design import bare_critical_airspeed
from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.control.rbf_io import load_rbf_network
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing, reference_wing_path
from dva_offline import cli
from dva_offline.training.labels import LabelError, label_exact
from dva_offline.training.plan import (
    PlanSettings,
    make_training_plan,
    ratio_grid,
    stable_interval,
)
from dva_offline.training.plan_io import PLAN_FILE, load_plan, plan_from_dict, plan_to_dict
from dva_offline.training.rbf import build_dataset, train_network
from dva_offline.training.recording import simulate_dwells, stationary_draw

CFG = load_wing()
MODEL = AeroelasticModel(CFG.wing, CFG.absorber, CFG.aero)
U_CR = bare_critical_airspeed(CFG.wing, 1.2, CFG.aero)
# A mini plan: 17 airspeeds 0.8 .. 1.12 U_cr x 2 densities x 4 c2 = 132 dwells (two
# conditions left out), 264 s of flight.
MINI = ["--ratios", "0.8:1.12:0.02", "--factors", "1.0,1.1", "--n-damping", "4"]


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    """The mini plan recorded once through the CLI, and trained on with exact labels."""
    root = tmp_path_factory.mktemp("plan")
    assert cli.main(["train", "plan", *MINI, "--out", str(root / "plan.json")]) == 0
    assert cli.main(["train", "sweep", "--plan", str(root / "plan.json"), "--out",
                     str(root / "bag")]) == 0
    plan, wing = load_plan(root / "plan.json")
    return {"root": root, "plan": plan, "wing": wing, "bag": root / "bag",
            "log": load_flight_log(root / "bag")}


def test_stable_interval_is_the_run_around_the_optimum():
    grid = np.arange(0.0, 1000.0, 100.0)
    growth = np.array([0.1, -1, -1, 0.5, -1, -1, -1, -0.1, -1, -1])
    assert stable_interval(growth, grid, 520.0, 0.2) == (400.0, 600.0)
    assert stable_interval(growth, grid, 180.0, 0.2) == (100.0, 200.0)
    assert all(math.isnan(v) for v in stable_interval(growth, grid, 310.0, 0.2))
    assert all(math.isnan(v) for v in stable_interval(growth, grid, math.nan, 0.2))


def test_plan_puts_c2_around_the_exact_optimum_where_the_wing_decays(mini):
    plan = mini["plan"]
    s = plan.settings
    assert s.ratios == ratio_grid(0.8, 1.12, 0.02) and len(s.ratios) == 17
    assert plan.critical_airspeed == pytest.approx(U_CR) and plan.base_density == 1.2
    for i, factor in enumerate(s.factors):
        rho = factor * 1.2
        speeds = np.asarray(s.ratios) * U_CR
        exact = optimal_damping(MODEL, speeds, np.linspace(0, 2500, 126), rho)
        ok = np.isfinite(plan.optimal_damping[i])
        np.testing.assert_allclose(plan.optimal_damping[i][ok], exact.optimal_damping[ok])
        for j in np.flatnonzero(ok):
            on = plan.condition == i * len(s.ratios) + j
            c2 = plan.damping[on]
            one_point = plan.stable_low[i, j] == plan.stable_high[i, j]
            assert c2.size == (1 if one_point else s.n_damping) and np.all(np.diff(c2) > 0)
            assert c2[0] >= max(plan.stable_low[i, j], plan.optimal_damping[i, j] - 300) - 1e-9
            assert c2[-1] <= min(plan.stable_high[i, j], plan.optimal_damping[i, j] + 300) + 1e-9
            growth = stationary_rms(MODEL, speeds[j], rho, c2).growth_rate
            assert np.all(growth <= -s.min_decay)
            assert np.all(plan.airspeed[on] == speeds[j]) and np.all(plan.density[on] == rho)
    # at 1.12 U_cr and 1.1 rho0 no c2 decays fast enough: left out and listed
    assert (1.12, 1.1) in plan.skipped
    assert plan.n_dwells <= 4 * (2 * 17 - len(plan.skipped))


def test_plan_file_round_trip_and_errors(mini, tmp_path):
    plan = mini["plan"]
    data = plan_to_dict(plan, "wing.yaml")
    back = plan_from_dict(json.loads(json.dumps(data)))
    for name in ("airspeed", "density", "damping", "condition"):
        np.testing.assert_array_equal(getattr(back, name), getattr(plan, name))
    np.testing.assert_array_equal(np.isnan(back.stable_low), np.isnan(plan.stable_low))
    assert back.settings == plan.settings
    with pytest.raises(ValueError, match="not a dva_training_plan"):
        plan_from_dict({"format": "other"})
    bad = json.loads(json.dumps(data))
    bad["dwells"]["density"][0] = -1.0
    with pytest.raises(ValueError, match=r"dwells.density\[0\] must be in \[0.001, 2\]"):
        plan_from_dict(bad)
    (tmp_path / "p.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_plan(tmp_path / "p.json")


def test_bad_plan_options_are_one_line_errors(tmp_path, capsys):
    for argv, text in ((["--factors", "1,x"], "--factors"), (["--n-damping", "0"], "n_damping"),
                       (["--ratios", "0.8:1.1"], "--ratios")):
        assert cli.main(["train", "plan", *argv, "--out", str(tmp_path / "p.json")]) == 2
        err = capsys.readouterr().err
        assert text in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "p.json").exists()


def test_each_dwell_starts_stationary():
    """Mean square of the first samples over many dwells of one condition equals the exact
    stationary value (a dwell started from rest would start near zero)."""
    settings = PlanSettings(ratios=(1.0,), factors=(1.0,), n_damping=1, window=0.05, seed=3)
    plan = make_training_plan(MODEL, U_CR, 1.2, settings)
    plan = dataclasses.replace(plan, airspeed=np.repeat(plan.airspeed, 600),
                               density=np.repeat(plan.density, 600),
                               damping=np.repeat(plan.damping, 600),
                               condition=np.repeat(plan.condition, 600))
    first = np.concatenate([b.displacements[:, 2, 0] for b in simulate_dwells(MODEL, plan)])
    exact = stationary_rms(MODEL, plan.airspeed[0], 1.2, plan.damping[0]).output("leading_edge")
    # 600 independent draws: the mean square has a relative standard error of sqrt(2/600)
    assert np.mean(first ** 2) / exact ** 2 == pytest.approx(1.0, abs=4 * math.sqrt(2 / 600))
    # the same dwell gives the same data whatever else is simulated with it
    one = next(simulate_dwells(MODEL, plan, dwells=slice(5, 6)))
    again = next(simulate_dwells(MODEL, plan, batch=7))
    np.testing.assert_array_equal(one.force[0], again.force[5])


def test_stationary_draw_has_the_covariance():
    rng = np.random.default_rng(0)
    m = rng.standard_normal((3, 3))
    p = m @ m.T
    p[:, 2] = p[2, :] = 0.0  # singular: a Cholesky factor would fail
    x = stationary_draw(p, rng.standard_normal((20000, 3)))
    np.testing.assert_allclose(np.cov(x.T), p, atol=0.05 * np.abs(p).max())


def test_bag_holds_every_dwell_with_its_condition(mini):
    plan, log = mini["plan"], mini["log"]
    n = plan.settings.window_samples
    assert log.time.size == plan.n_dwells * n
    np.testing.assert_array_equal(log.airspeed[::n], plan.airspeed)
    np.testing.assert_array_equal(log.density[::n], plan.density)
    np.testing.assert_array_equal(log.applied_damping[::n], plan.damping)
    assert (mini["bag"] / PLAN_FILE).is_file()
    final = log.diagnostics[-1]
    assert final["message"] == "flight completed"
    assert float(final["values"]["critical_airspeed_no_dva"]) == pytest.approx(U_CR)
    # the recorded response is the simulated one (to round-off: batches of other sizes)
    first = next(simulate_dwells(MODEL, plan, dwells=slice(3, 4)))
    expected = first.accelerations[0]
    np.testing.assert_allclose(log.accelerations[:, 3 * n:4 * n], expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())
    np.testing.assert_array_equal(log.force[3 * n:4 * n], first.force[0])


def test_exact_labels_are_the_plans_optimum(mini):
    data = build_dataset(mini["log"])
    labels = label_exact(data, MODEL)
    plan = mini["plan"]
    np.testing.assert_allclose(labels.targets, plan.optimal_damping.ravel()[plan.condition],
                               rtol=1e-9)
    assert labels.n_conditions == np.unique(plan.condition).size
    np.testing.assert_array_equal(labels.n_damping, np.bincount(plan.condition)[
        np.unique(plan.condition)])


def test_exact_labels_refuse_an_unstable_condition(mini):
    data = build_dataset(mini["log"])
    fast = dataclasses.replace(data, airspeed=data.airspeed * 1.3)
    with pytest.raises(LabelError, match="no c2 in 0..2500 N s/m keeps the wing stable"):
        label_exact(fast, MODEL)


def test_train_rbf_reports_and_saves_a_network_that_learned(mini, tmp_path, capsys):
    out, plot = tmp_path / "net.npz", tmp_path / "fig.png"
    assert cli.main(["train", "rbf", str(mini["bag"]), "--out", str(out), "--plot", str(plot),
                     "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["labels"] == "exact" and summary["densities"] == [1.2, 1.32]
    network = load_rbf_network(out, expected_input_dim=33)
    data = build_dataset(mini["log"])
    outcome = train_network(data, label_exact(data, MODEL))
    val = outcome.validation_metrics
    assert summary["validation_r2"] == pytest.approx(val.r2, rel=1e-9)
    assert summary["output_min"] == pytest.approx(val.output_min, rel=1e-9)
    assert summary["output_max"] == pytest.approx(val.output_max, rel=1e-9)
    assert summary["median_peak_activation"] == pytest.approx(val.median_peak_activation)
    held = network.predict(data.inputs[~outcome.train_mask])
    assert held.min() == pytest.approx(val.output_min) and held.max() == pytest.approx(
        val.output_max)
    # even this mini data set teaches the network something on airspeeds it has not seen
    # (measured: R^2 0.64, activation 0.62, output 487..614 N s/m)
    assert val.r2 > 0.5 and val.median_peak_activation >= 0.1
    assert val.output_max - val.output_min > 30.0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_network_that_does_not_respond_is_refused(mini, tmp_path, capsys):
    out = tmp_path / "net.npz"
    assert cli.main(["train", "rbf", str(mini["bag"]), "--out", str(out), "--spreads",
                     "0.01"]) == 2
    err = capsys.readouterr().err
    assert "refused" in err and "median peak activation" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_labels_of_another_wing_are_refused(mini, tmp_path, capsys):
    assert cli.main(["train", "rbf", str(mini["bag"]), "--out", str(tmp_path / "n.npz"),
                     "--wing", str(reference_wing_path())]) == 2
    assert "flown with another wing" in capsys.readouterr().err
