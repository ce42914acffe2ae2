"""The study's chapter-6 DVA results on the reference wing (tables 6.1-6.3, section 6.3.2).

Each study number is held to the tolerance the calibrated reference wing reaches (see the
study-vs-project table in docs/wing.md); the trends the study describes are checked separately.
"""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.control import dva_design as dd
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.flight.divergence import divergence_airspeed, ramp_airspeed
from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.flutter import flutter_speed
from aero_dva.wing.modal import min_damping_ratio
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing, reference_wing_path

CFG = load_wing(reference_wing_path())
WING, RHO = CFG.wing, CFG.air_density

# Tolerances reached by the reference wing (absolute, on U / U_cr).
TOL_6_1 = {"rear_tip": 0.025, "rear_middle": 0.03, "front_middle": 0.02, "front_tip": 0.005}
TOL_6_2 = {0.01: 0.025, 0.02: 0.01, 0.03: 0.005, 0.04: 0.005}
TOL_6_3 = (0.005, 0.01, 0.01)  # constant DVA(1..3), DVA(2) against the text's 1.074
TOL_TUNED = 0.005
TOL_MAXWELL = (0.03, 0.01)


@pytest.fixture(scope="module")
def studies():
    return {
        "6.1": {r.label: r for r in dd.position_study(WING, RHO)},
        "6.2": {float(r.label): r for r in dd.mass_study(WING, RHO)},
        "6.3": dd.constant_absorber_study(WING, RHO),
        "maxwell": dd.maxwell_study(WING, RHO),
    }


def test_reference_wing_critical_airspeed_and_frequency():
    res = flutter_speed(AeroelasticModel(WING), RHO)
    assert res.critical_airspeed == pytest.approx(100.0, abs=0.01)
    assert 5.0 < res.flutter_frequency < 20.0  # inside the band of the study's spectra


@pytest.mark.parametrize("label", list(dd.STUDY_TABLE_6_1))
def test_table_6_1_positions(studies, label):
    got = studies["6.1"][label].ratio
    assert got == pytest.approx(dd.STUDY_TABLE_6_1[label], abs=TOL_6_1[label])


def test_table_6_1_front_tip_is_best(studies):
    ratios = {k: v.ratio for k, v in studies["6.1"].items()}
    assert max(ratios, key=ratios.get) == "front_tip"
    assert ratios["rear_tip"] > ratios["rear_middle"]  # seed: 1.07 > 1.06


@pytest.mark.parametrize("ratio", list(dd.STUDY_TABLE_6_2))
def test_table_6_2_masses(studies, ratio):
    got = studies["6.2"][ratio].ratio
    assert got == pytest.approx(dd.STUDY_TABLE_6_2[ratio], abs=TOL_6_2[ratio])


def test_table_6_2_heavier_is_better(studies):
    ratios = [studies["6.2"][r].ratio for r in sorted(studies["6.2"])]
    assert np.all(np.diff(ratios) > 0)


def test_table_6_3_constant_and_tunable_dvas(studies):
    *constant, tuned = studies["6.3"]
    for res, (_, _, seed), tol in zip(constant, dd.STUDY_TABLE_6_3, TOL_6_3):
        assert res.ratio == pytest.approx(seed, abs=tol), res.label
    assert tuned.ratio == pytest.approx(dd.STUDY_TUNED_RATIO, abs=TOL_TUNED)
    # Seed: DVA(2) is the best constant DVA, then DVA(3), then DVA(1); tuning beats them all.
    assert constant[1].ratio > constant[2].ratio > constant[0].ratio > 1.0
    assert tuned.ratio > constant[1].ratio


def test_maxwell_designs(studies):
    for res, design, tol in zip(studies["maxwell"], dd.STUDY_MAXWELL_DESIGNS, TOL_MAXWELL):
        assert res.ratio == pytest.approx(design[3], abs=tol), res.label
        assert 0.0 <= res.setting.damping <= design[2]
    # Seed: the second design beats the first and even the tunable passive DVA.
    tuned = studies["6.3"][-1].ratio
    assert studies["maxwell"][1].ratio > tuned > studies["maxwell"][0].ratio


def test_tuned_setting_really_is_the_best_nearby():
    model = AeroelasticModel(WING, PassiveAbsorber(40.0, 1e5, 1e3, 1.53))
    best = dd.optimise_passive(model, 106.0, RHO)
    around = dd.min_damping_map(model, 106.0, RHO, best.stiffness * np.array([0.9, 1.0, 1.1]),
                                best.damping * np.array([0.9, 1.0, 1.1]))
    assert around.max() <= best.min_damping_ratio + 1e-9
    assert around[1, 1] == pytest.approx(best.min_damping_ratio, abs=1e-9)


def test_tuned_critical_airspeed_is_a_zero_of_the_best_damping():
    model = AeroelasticModel(WING, MaxwellAbsorber(40.0, 9e4, 7e4, 500.0, 1.53))
    tc = dd.tuned_critical_airspeed(model, RHO, (80.0, 150.0), damping_bounds=(1.2, 1200.0))
    assert abs(tc.min_damping_ratio) < 1e-5
    below = dd.optimise_maxwell(model, 0.99 * tc.airspeed, RHO, damping_bounds=(1.2, 1200.0))
    above = dd.optimise_maxwell(model, 1.01 * tc.airspeed, RHO, damping_bounds=(1.2, 1200.0))
    assert below.min_damping_ratio > 0 > above.min_damping_ratio
    a, _ = model.matrices(tc.airspeed, RHO, damping=tc.damping)
    assert abs(min_damping_ratio(a)) < 1e-5
    assert 5.0 < dd.critical_frequency(model, tc, RHO) < 20.0


def test_design_errors_are_named():
    with pytest.raises(ValueError, match="PassiveAbsorber"):
        dd.optimise_passive(AeroelasticModel(WING), 80.0, RHO)
    with pytest.raises(ValueError, match="damping_bounds"):
        dd.optimise_maxwell(AeroelasticModel(WING, CFG.absorber), 80.0, RHO,
                            damping_bounds=(-1.0, 10.0))


def test_ramp_flights_diverge_in_the_studys_order():
    """Sections 6.1.3 and 6.3.3: 0.8 -> 1.2 U_cr in 30 s, 1 kN aileron noise, c2 tuned."""
    u_cr = flutter_speed(AeroelasticModel(WING), RHO).critical_airspeed
    u = ramp_airspeed(u_cr)
    force = 1000.0 * np.random.default_rng(11).standard_normal((4, u.size))
    tr = simulate_flights(WING, None, force=force, airspeed=u, density=RHO)
    bare = divergence_airspeed(tr.airspeed[0], tr.displacements[:, 2]) / u_cr
    tuned = []
    for k1, k2, c_max, _ in dd.STUDY_MAXWELL_DESIGNS:
        dva = MaxwellAbsorber(0.04 * WING.mass, k1, k2, c_max / 2, 1.53)
        grid = np.linspace(u[0], u[-1], 21)
        c2 = [s.damping for s in dd.best_damping_curve(AeroelasticModel(WING, dva), grid, RHO,
                                                       damping_bounds=(1e-3 * c_max, c_max))]
        tr = simulate_flights(WING, dva, force=force, airspeed=u, density=RHO,
                              damping=np.interp(u, grid, c2))
        tuned.append(divergence_airspeed(tr.airspeed[0], tr.displacements[:, 2]) / u_cr)
    # Seed: the bare wing grows right after U_cr; design 1 at 1.11, design 2 at 1.17 U_cr.
    assert np.all((bare > 1.0) & (bare < 1.06))
    assert np.median(tuned[1]) == pytest.approx(1.17, abs=0.03)
    assert np.median(tuned[0]) == pytest.approx(1.11, abs=0.05)
    assert np.median(bare) < np.median(tuned[0]) < np.median(tuned[1])


def test_optimal_passive_settings_above_u_cr():
    """Fig. 6.12 / table 6.3: above U_cr the best k1 rises and c1 falls; at 1.06 U_cr the study
    found k1 = 91.56 N/mm, c1 = 0.86 N-s/mm (held here to the 5 % and 30 % reached)."""
    front_tip = dd.STUDY_POSITIONS["front_tip"]
    model = AeroelasticModel(WING, PassiveAbsorber(40.0, 1e5, 1e3, front_tip))
    u_cr = flutter_speed(AeroelasticModel(WING), RHO).critical_airspeed
    best = [dd.optimise_passive(model, s * u_cr, RHO) for s in (1.0, 1.06, 1.12)]
    assert best[0].stiffness < best[1].stiffness < best[2].stiffness
    assert best[0].damping > best[1].damping > best[2].damping
    assert best[1].stiffness == pytest.approx(91.56e3, rel=0.05)
    assert best[1].damping == pytest.approx(0.86e3, rel=0.3)
