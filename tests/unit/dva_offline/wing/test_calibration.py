"""The reference-wing calibration: parameter space, cost with trend penalties, search, script."""
from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from aero_dva.wing.flutter import flutter_speed
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing, reference_wing_path
from dva_offline.wing import calibration as wc

REFERENCE = load_wing(reference_wing_path())
SCRIPT = Path(__file__).resolve().parents[4] / "scripts" / "calibrate_reference_wing.py"

# The reference wing's ratios as `dva wing design` computes them (docs/wing.md table).
REFERENCE_RATIOS = {
    "6.1 rear_tip": 1.0914, "6.1 rear_middle": 1.0851, "6.1 front_middle": 1.0728,
    "front_tip m1/m=0.04 (tables 6.1-6.3)": 1.1405, "6.2 m1/m=0.01": 1.0615,
    "6.2 m1/m=0.02": 1.0917, "6.2 m1/m=0.03": 1.1172, "6.3 DVA(1)": 1.0209,
    "6.3 DVA(2)": 1.0675, "6.3 DVA(3)": 1.0484, "Maxwell design 1": 1.0389,
    "Maxwell design 2": 1.1447,
}


def test_unit_cube_round_trip_and_log_axes():
    rng = np.random.default_rng(0)
    for unit in rng.random((5, len(wc.BOUNDS))):
        p = wc.from_unit(unit)
        np.testing.assert_allclose(wc.to_unit(p), unit, atol=1e-12)
        for b in wc.BOUNDS:
            assert b.low <= p[b.name] <= b.high
    mid = wc.from_unit(np.full(len(wc.BOUNDS), 0.5))
    span = next(b for b in wc.BOUNDS if b.name == "span")
    assert mid["span"] == pytest.approx(math.sqrt(span.low * span.high))  # log axis
    assert wc.from_unit(np.full(len(wc.BOUNDS), 2.0)) == wc.from_unit(np.ones(len(wc.BOUNDS)))
    with pytest.raises(ValueError, match="unit"):
        wc.from_unit([0.5])
    with pytest.raises(ValueError, match="lack"):
        wc.to_unit({"span": 80.0})


def test_reference_wing_is_a_point_of_the_parameter_space():
    p = wc.params_from_wing(REFERENCE.wing)
    assert np.all((wc.to_unit(p) >= 0) & (wc.to_unit(p) <= 1))
    wing, aero, res = wc.build_wing(p, REFERENCE.aero.pitch_damping)
    assert res.critical_airspeed == pytest.approx(wc.TARGET_UCR, rel=1e-8)
    assert res.kind == "flutter"
    for name in ("inertia", "plunge_stiffness", "pitch_stiffness", "damping_factor", "chord",
                 "gravity_centre", "elastic_axis", "span", "lift_slope"):
        assert getattr(wing, name) == pytest.approx(getattr(REFERENCE.wing, name), rel=1e-4)


def test_stiffness_scaling_puts_any_flutter_shape_at_100_m_s():
    p = wc.params_from_wing(REFERENCE.wing)
    p["freq_ratio"] *= 0.7
    p["span"] *= 1.5
    wing, aero, res = wc.build_wing(p)
    again = flutter_speed(AeroelasticModel(wing, None, aero), wc.AIR_DENSITY)
    assert again.critical_airspeed == pytest.approx(100.0, rel=1e-8)


def test_a_shape_that_diverges_first_is_rejected_with_the_reason():
    p = wc.params_from_wing(REFERENCE.wing)
    p["ea_frac"] = 0.6  # elastic axis far behind the aerodynamic centre
    with pytest.raises(ValueError, match="diverges statically"):
        wc.build_wing(p)
    e = wc.evaluate(p)
    assert e.cost == wc.REJECTED_COST and not e.ratios and "diverges" in e.note


def test_cost_is_zero_at_the_seed_and_counts_errors_in_hundredths():
    exact = dict(wc.STUDY_TARGETS)
    cost = wc.calibration_cost(exact)
    assert cost.total == pytest.approx(0.0, abs=1e-9) and cost.wrong_trends == ()
    off = dict(exact)
    off["6.3 DVA(3)"] += 0.02
    c = wc.calibration_cost(off)
    assert c.squared_error == pytest.approx(4.0)
    assert c.max_error == pytest.approx(0.02)


def test_cost_penalises_a_wrong_trend_beyond_its_squared_error():
    # Table 6.1 with front middle below both rear positions (the current reference wing's
    # trend) but every number within 0.012 of the seed: small errors, wrong trend.
    ratios = dict(wc.STUDY_TARGETS)
    ratios.update({"6.1 front_middle": 1.078, "6.1 rear_tip": 1.082, "6.1 rear_middle": 1.07})
    c = wc.calibration_cost(ratios)
    assert c.max_error < 0.013
    assert c.ranking > c.squared_error > 0
    assert c.wrong_trends == ("6.1: 6.1 front_middle > 6.1 rear_tip",)
    right = dict(ratios, **{"6.1 front_middle": 1.09})
    assert wc.calibration_cost(right).ranking == 0.0


def test_cost_of_missing_ratios_bad_frequency_and_bad_input():
    ratios = dict(wc.STUDY_TARGETS, **{"Maxwell design 1": float("nan")})
    c = wc.calibration_cost(ratios)
    assert c.squared_error == pytest.approx(wc.NAN_PENALTY) and math.isinf(c.max_error)
    assert wc.calibration_cost(dict(wc.STUDY_TARGETS), flutter_frequency=3.0).frequency == 4.0
    assert wc.calibration_cost(dict(wc.STUDY_TARGETS), flutter_frequency=12.0).frequency == 0.0
    with pytest.raises(ValueError, match="lack"):
        wc.calibration_cost({"6.1 rear_tip": 1.07})


def test_fast_ratios_of_the_reference_wing_match_the_design_study():
    wing, aero, res = wc.build_wing(wc.params_from_wing(REFERENCE.wing))
    got = wc.study_ratios(wing, aero)
    assert set(got) == set(wc.STUDY_TARGETS)
    for key, value in REFERENCE_RATIOS.items():
        assert got[key] == pytest.approx(value, abs=6e-4), key


def _fake_evaluate(calls):
    """A cheap stand-in for `evaluate`: quadratic bowl around a known shape."""
    target = np.linspace(0.2, 0.8, len(wc.BOUNDS))

    def evaluate(params, pitch_damping="thin_airfoil", fast=True, phase=""):
        calls.append(params)
        u = wc.to_unit(params)
        cost = float(np.sum((u - target) ** 2)) * 100 + (pitch_damping != "thin_airfoil")
        return wc.Evaluation(dict(params), pitch_damping, cost, {"x": 1.0}, 10.0, cost, (),
                             phase=phase)
    return evaluate, target


def test_search_refines_the_random_phase_and_respects_its_budget():
    calls = []
    evaluate, target = _fake_evaluate(calls)
    done = wc.search(seed=1, n_random=20, restarts=2, local_iterations=200,
                     evaluate_fn=evaluate)
    best = min(done, key=lambda e: e.cost)
    random_best = min(e.cost for e in done if e.phase == "random")
    assert best.cost < 0.1 * random_best  # Nelder-Mead improved on the random phase
    assert best.pitch_damping == "thin_airfoil"
    calls.clear()
    wc.search(seed=1, n_random=20, max_evaluations=7, evaluate_fn=evaluate)
    assert len(calls) == 7


def test_search_resumes_from_its_history_without_evaluating_again():
    calls = []
    evaluate, _ = _fake_evaluate(calls)
    first = wc.search(seed=2, n_random=10, restarts=1, local_iterations=30,
                      evaluate_fn=evaluate)
    n_first = len(calls)
    seen = []
    again = wc.search(seed=2, n_random=10, restarts=1, local_iterations=30, history=first,
                      evaluate_fn=evaluate, on_evaluation=lambda e, b, fresh: seen.append(fresh))
    assert len(calls) == n_first  # everything came from the memo
    assert not any(seen)
    assert min(e.cost for e in again) == min(e.cost for e in first)


def test_script_writes_and_resumes_its_checkpoint(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("calibrate_reference_wing", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    ckpt, cand = tmp_path / "calib.jsonl", tmp_path / "candidate.yaml"
    args = ["--checkpoint", str(ckpt), "--candidate", str(cand), "--n-random", "0",
            "--restarts", "0", "--no-final-check"]
    assert script.main(args + ["--max-evaluations", "1"]) == 0
    lines = ckpt.read_text().splitlines()
    assert len(lines) == 1
    first = json.loads(lines[0])
    assert first["phase"] == "start" and first["ratios"]["6.1 rear_tip"] == pytest.approx(
        REFERENCE_RATIOS["6.1 rear_tip"], abs=6e-4)
    assert load_wing(cand).wing.chord == pytest.approx(REFERENCE.wing.chord)
    with open(ckpt, "a") as fh:
        fh.write('{"truncated": ')  # an interrupted write is skipped on resume
    assert script.main(args + ["--max-evaluations", "0"]) == 0
    assert "1 earlier evaluations" in capsys.readouterr().out
    assert len(script.read_checkpoint(ckpt)) == 1
