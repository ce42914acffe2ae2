"""General Maxwell isolator model: modal analysis, FRFs, and the study's modal tables.

The study's units are converted here at the boundary: kN/m -> N/m (x1000).
"""
import subprocess
import sys

import numpy as np
import pytest

from dva_offline.isolator.maxwell_model import (
    MaxwellModel,
    characteristic_function,
    dynamic_stiffness,
    frf,
    modal_properties,
    state_matrix,
)
from dva_offline.isolator.voigt_identification import voigt_model_k, voigt_model_m

KN = 1e3  # kN/m -> N/m


def mmv(c1, k1, c2, k2, c=40.0, k=12 * KN, m=1.0):
    return MaxwellModel(m, k, c, (k1, k2), (c1, c2))


# Table 4.1 (k_i in kN/m, c_i in N s/m); omega_n (rad/s, 3 decimals) and zeta (3 decimals).
TABLE_4_1 = {
    "A": ((12, 20), (24, 20), 112.684, 0.371),
    "B": ((12, 80), (24, 120), 216.050, 0.404),
    "C": ((12, 2000), (24, 2000), 219.718, 0.108),
    "D": ((24, 20), (12, 80), 152.126, 0.432),
    "E": ((24, 20), (12, 2000), 156.833, 0.203),
    "F": ((12, 80), (24, 2000), 214.806, 0.182),
}


def table_4_1_system(name):
    (k1, c1), (k2, c2), _, _ = TABLE_4_1[name]
    return mmv(c1, k1 * KN, c2, k2 * KN)


def test_table_3_1_mv_and_voigt_modal():
    mv = modal_properties(MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (40.0,)))
    assert mv.natural_frequency_rad_s == pytest.approx(119.03, abs=0.005)
    assert mv.damping_ratio == pytest.approx(0.36, abs=0.005)
    voigt = modal_properties(MaxwellModel(1.0, 12 * KN, 40.0))
    assert voigt.natural_frequency_rad_s == pytest.approx(109.54, abs=0.005)
    assert voigt.damping_ratio == pytest.approx(0.18, abs=0.005)
    # The study's remark: c = c1 and zeta_mv is (about) twice zeta_v.
    assert mv.damping_ratio / voigt.damping_ratio == pytest.approx(2.0, abs=0.03)


@pytest.mark.parametrize(
    "c1, omega, zeta", [(20, 111.56, 0.28), (80, 145.14, 0.36), (400, 156.16, 0.18)]
)
def test_table_3_3_experimental_mv_systems(c1, omega, zeta):
    modal = modal_properties(MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (c1,)))
    assert modal.natural_frequency_rad_s == pytest.approx(omega, abs=0.005)
    assert modal.damping_ratio == pytest.approx(zeta, abs=0.005)


@pytest.mark.parametrize("name", sorted(TABLE_4_1))
def test_table_4_1_mmv_systems(name):
    *_, omega, zeta = TABLE_4_1[name]
    modal = modal_properties(table_4_1_system(name))
    assert modal.natural_frequency_rad_s == pytest.approx(omega, abs=0.0005)
    if name == "F":
        # Printed 0.182; the parameters give 0.18146 (-> 0.181). The study's Table 4.4 fits all
        # have zeta = 0.18150, so it seems to have used 0.1815 rounded up.
        assert modal.damping_ratio == pytest.approx(0.18146, abs=5e-6)
        assert abs(modal.damping_ratio - zeta) < 0.0006
    else:
        assert modal.damping_ratio == pytest.approx(zeta, abs=0.0005)
    # n = 2 Maxwell elements: n real eigenvalues and one complex pair (section 4.1).
    assert np.sum(np.abs(modal.eigenvalues.imag) > 1e-6) == 2
    assert modal.is_stable


def test_table_4_1_printed_tau_of_systems_d_e_is_a_typo():
    """Systems D and E print tau_1 = 1.67 ms, but k1 = 24 kN/m, c1 = 20 N s/m give 0.83 ms.

    The printed omega/zeta confirm k1 and c1 (not tau_1): with k1 = 12 kN/m (which would give
    1.67 ms) omega_n would be far from the printed value.
    """
    for name in ("D", "E"):
        model = table_4_1_system(name)
        assert model.time_constants[0] * 1e3 == pytest.approx(0.833, abs=0.001)
        assert abs(model.time_constants[0] * 1e3 - 1.67) > 0.8
        alt = model.with_elements((12 * KN, model.maxwell_k[1]), model.maxwell_c)
        assert abs(modal_properties(alt).natural_frequency_rad_s - TABLE_4_1[name][2]) > 1.0


TABLE_4_5_A = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 12 * KN, 24 * KN), (20.0, 80.0, 2000.0))
TABLE_4_5_B = MaxwellModel(
    1.0, 12 * KN, 40.0,
    (12 * KN, 24 * KN, 12 * KN, 24 * KN, 12 * KN, 24 * KN),
    (20.0, 20.0, 80.0, 120.0, 2000.0, 2000.0),
)
TABLE_4_6_A = MaxwellModel(1.0, 12 * KN, 49.54, (14.95 * KN, 24.65 * KN), (81.76, 2003.24))
TABLE_4_6_B = MaxwellModel(1.0, 12 * KN, 65.73, (40.69 * KN, 36.50 * KN), (209.15, 3797.60))


def test_table_4_5_system_a_printed_modal_values_contradict_its_parameters():
    """Table 4.5 prints 112.68 rad/s, 0.37 for general System A: Table 4.1 System A's values.

    The printed parameters give 220.34 rad/s, 0.224 -- and the study's own identified Model A
    (Table 4.6), which is constrained to the system's omega/zeta, gives the same 220.35, 0.224.
    """
    computed = modal_properties(TABLE_4_5_A)
    table_4_1_a = modal_properties(table_4_1_system("A"))
    assert round(table_4_1_a.natural_frequency_rad_s, 2) == 112.68  # where 112.68 comes from
    assert round(table_4_1_a.damping_ratio, 2) == 0.37
    assert computed.natural_frequency_rad_s == pytest.approx(220.34, abs=0.005)
    assert computed.damping_ratio == pytest.approx(0.224, abs=0.0005)
    assert abs(computed.natural_frequency_rad_s - 112.68) > 100
    model_a = modal_properties(TABLE_4_6_A)
    assert model_a.natural_frequency_rad_s == pytest.approx(
        computed.natural_frequency_rad_s, abs=0.01
    )
    assert model_a.damping_ratio == pytest.approx(computed.damping_ratio, abs=1e-4)


def test_table_4_5_system_b_printed_modal_values_match_model_not_system():
    """System B prints 293.87 rad/s, 0.26; its parameters give 295.21, 0.266.

    The printed values are those of the identified Model B of Table 4.6 (293.88, 0.262), so
    the study's identification used 293.87 / 0.26 as constraints, not the system's eigenvalue.
    """
    computed = modal_properties(TABLE_4_5_B)
    assert computed.natural_frequency_rad_s == pytest.approx(295.21, abs=0.005)
    assert computed.damping_ratio == pytest.approx(0.266, abs=0.0005)
    assert abs(computed.natural_frequency_rad_s - 293.87) > 1.0
    model_b = modal_properties(TABLE_4_6_B)
    assert model_b.natural_frequency_rad_s == pytest.approx(293.87, abs=0.015)
    assert round(model_b.damping_ratio, 2) == 0.26


def test_state_matrix_rows_follow_eq_4_1():
    model = MaxwellModel(2.0, 10.0, 3.0, (4.0, 5.0, 6.0), (1.0, 2.0, 3.0))
    a = state_matrix(model)
    assert a.shape == (5, 5)
    taus = model.time_constants
    for i, tau in enumerate(taus):
        row = np.zeros(5)
        row[1], row[2 + i] = 1 / tau, -1 / tau  # x_i' = (x - x_i) / tau_i
        np.testing.assert_allclose(a[2 + i], row)
    np.testing.assert_allclose(a[0], [-1.5, -(10 + 15) / 2, 2.0, 2.5, 3.0])
    # Eigenvalues are the zeros of D(s) = m s^2 + c s + k + sum k_i c_i s / (k_i + c_i s).
    eig = np.linalg.eigvals(a)
    scale = np.abs(model.mass * eig**2) + model.k
    assert np.all(np.abs(characteristic_function(model, eig)) < 1e-9 * scale)


def test_complex_stiffness_and_frf_relations():
    model = table_4_1_system("F")
    w = np.linspace(0.0, 600.0, 301)
    k_dyn = dynamic_stiffness(w, model.k, model.c, model.maxwell_k, model.maxwell_c)
    expected = model.k + 1j * w * model.c + sum(
        1j * w * ci * ki / (ki + 1j * w * ci) for ki, ci in zip(model.maxwell_k, model.maxwell_c)
    )
    np.testing.assert_allclose(k_dyn, expected, rtol=1e-12)
    rec = frf(model, w, "receptance")
    np.testing.assert_allclose(rec * (k_dyn - model.mass * w**2), 1.0, rtol=1e-12)
    np.testing.assert_allclose(frf(model, w, "accelerance"), -(w**2) * rec, rtol=1e-12)
    np.testing.assert_allclose(frf(model, w, "transmissibility"), k_dyn * rec, rtol=1e-12)
    np.testing.assert_allclose(frf(model, w, "stiffness"), k_dyn, rtol=1e-12)
    # Static stiffness is k: Maxwell elements carry no static load.
    assert rec[0] == pytest.approx(1.0 / model.k)
    assert model.static_stiffness == model.k
    # Passivity: Im K(w) >= 0 for positive c and c_i.
    assert np.all(k_dyn.imag >= 0)
    # Limits: tau -> 0 is a damper c + c_i, tau -> inf a spring k + k_i (section 3.3).
    rigid = MaxwellModel(1.0, 12 * KN, 40.0, (1e12,), (40.0,))
    np.testing.assert_allclose(frf(rigid, w), frf(MaxwellModel(1.0, 12 * KN, 80.0), w),
                               rtol=1e-6)
    locked = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (1e12,))
    np.testing.assert_allclose(frf(locked, w[1:]), frf(MaxwellModel(1.0, 24 * KN, 40.0), w[1:]),
                               rtol=1e-6)


def test_maxwell_element_always_raises_natural_frequency():
    """Section 3.2.1: the Maxwell element always makes omega_mv > omega_v."""
    voigt = modal_properties(MaxwellModel(1.0, 12 * KN, 40.0)).natural_frequency_rad_s
    for tau in np.logspace(-4, 1, 30):
        model = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (12 * KN * tau,))
        assert modal_properties(model).natural_frequency_rad_s > voigt


@pytest.mark.parametrize(
    "c1, mk, mc, km, kc",
    [(20, 12.45, 61.45, 0.96, 59.25), (80, 21.07, 104.56, 0.57, 59.56),
     (400, 24.38, 55.25, 0.49, 27.19)],
)
def test_table_3_4_voigt_models(c1, mk, mc, km, kc):
    """Table 3.4 from Table 3.3: the printed c_v values need zeta rounded to 4 decimals.

    With the unrounded zeta, c_v of Systems A and C miss the printed last digit (e.g. Model M
    of System C: 55.236 vs 55.25 printed); with zeta rounded to 4 decimals all 12 values match.
    """
    modal = modal_properties(MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (c1,)))
    w, z = modal.natural_frequency_rad_s, round(modal.damping_ratio, 4)
    model_m = voigt_model_m(1.0, w, z)
    model_k = voigt_model_k(12 * KN, w, z)
    assert model_m.mass == 1.0 and model_k.k == 12 * KN
    assert model_m.k / KN == pytest.approx(mk, abs=0.005)
    assert model_m.c == pytest.approx(mc, abs=0.005)
    assert model_k.mass == pytest.approx(km, abs=0.005)
    assert model_k.c == pytest.approx(kc, abs=0.005)
    exact_m = voigt_model_m(1.0, w, modal.damping_ratio)
    if c1 == 400:
        assert abs(exact_m.c - mc) > 0.005


TABLE_5_1 = {"bubble": 14.013, "plate": 23.151, "stud": 54.507}  # kN/m
TABLE_5_2 = {"bubble": (187.15, 0.09), "plate": (229.59, 0.09), "stud": (559.29, 0.15)}
TABLE_5_3 = {  # (m, k kN/m, c) for Model K then Model M
    "bubble": ((0.40, 14.01, 13.37), (1.04, 36.46, 34.80)),
    "plate": ((0.44, 23.15, 18.07), (1.04, 54.87, 42.83)),
    "stud": ((0.17, 54.51, 29.53), (1.04, 325.63, 176.41)),
}
MASS_CH5 = 1.041  # kg, section 5.2


@pytest.mark.parametrize("mount", sorted(TABLE_5_3))
def test_table_5_3_voigt_models_from_tables_5_1_5_2(mount):
    w, zeta_printed = TABLE_5_2[mount]
    k_static = TABLE_5_1[mount] * KN
    (mk_m, mk_k, mk_c), (mm_m, mm_k, mm_c) = TABLE_5_3[mount]
    # Table 5.2 prints zeta to 2 decimals; the study used the unrounded value. Recover it from
    # Model M's c and check Model K's c with the same zeta (both models share zeta).
    zeta = mm_c / (2 * MASS_CH5 * w)
    assert zeta == pytest.approx(zeta_printed, abs=0.005)
    model_m = voigt_model_m(MASS_CH5, w, zeta)
    model_k = voigt_model_k(k_static, w, zeta)
    assert model_m.mass == pytest.approx(mm_m, abs=0.005)  # 1.041 printed as 1.04
    assert model_m.k / KN == pytest.approx(mm_k, abs=0.005)
    assert model_k.mass == pytest.approx(mk_m, abs=0.005)
    assert model_k.k / KN == pytest.approx(mk_k, abs=0.005)
    assert model_k.c == pytest.approx(mk_c, abs=0.06)
    # With the rounded zeta the c values miss the printed ones (bubble: 35.07 vs 34.80).
    if mount == "bubble":
        assert abs(voigt_model_m(MASS_CH5, w, zeta_printed).c - mm_c) > 0.2
    # m = 1.0 instead of 1.041 would not reproduce Model M's stiffness.
    assert abs(voigt_model_m(1.0, w, zeta).k / KN - mm_k) > 1.0


CH5_MODELS = {  # Tables 5.4 (Trial 1), 5.5 (Trial 2), 5.6 (M-M-V): (m, k, c, [(k_i kN/m, c_i)])
    ("5.4", "bubble"): (1.041, 14.01, 25.81, [(22.27, 1588.57)]),
    ("5.4", "plate"): (1.04, 23.15, 31.877, [(31.47, 1729.11)]),
    ("5.4", "stud"): (1.04, 54.51, 153.36, [(267.83, 10070.89)]),
    ("5.5", "bubble"): (1.04, 14.01, -40.0, [(28.68, 245.73)]),
    ("5.5", "plate"): (1.04, 23.15, -27.0, [(36.95, 318.44)]),
    ("5.5", "stud"): (1.04, 54.51, -125.0, [(324.86, 934.16)]),
    ("5.6", "bubble"): (1.04, 14.01, -55.49, [(64.44, 87.81), (18.23, 2297.39)]),
    ("5.6", "plate"): (1.04, 23.15, -29.15, [(45.21, 70.93), (26.05, 2402.82)]),
    ("5.6", "stud"): (1.04, 54.51, -70.18, [(389.70, 239.46), (224.11, 15507.4)]),
}


def ch5_model(key):
    m, k, c, els = CH5_MODELS[key]
    return MaxwellModel(m, k * KN, c, tuple(e[0] * KN for e in els), tuple(e[1] for e in els))


@pytest.mark.parametrize("key", sorted(CH5_MODELS))
def test_tables_5_4_to_5_6_consistent_with_tables_5_1_5_2(key):
    """Every printed chapter-5 model has the measured static stiffness, w_n and zeta.

    Static stiffness matches Table 5.1 to the printed 0.01 kN/m; zeta matches Table 5.2 to its
    printed 2 decimals; w_n matches to 0.05 % only (the models are quoted with 1.04 kg and
    rounded parameters; e.g. the plate mount gives 229.70 rad/s vs 229.59 printed). With the
    measured m = 1.041 kg (section 5.2) w_n matches Table 5.2 to 0.02 rad/s.
    """
    table, mount = key
    model = ch5_model(key)
    w, zeta = TABLE_5_2[mount]
    assert model.static_stiffness / KN == pytest.approx(TABLE_5_1[mount], abs=0.005)
    modal_printed_mass = modal_properties(model)
    assert modal_printed_mass.damping_ratio == pytest.approx(zeta, abs=0.005)
    assert modal_printed_mass.natural_frequency_rad_s == pytest.approx(w, rel=1e-3)
    modal = modal_properties(
        MaxwellModel(MASS_CH5, model.k, model.c, model.maxwell_k, model.maxwell_c)
    )
    assert modal.natural_frequency_rad_s == pytest.approx(w, abs=0.02)
    assert modal.damping_ratio == pytest.approx(zeta, abs=0.005)
    if model.mass == 1.04:
        # The printed 1.04 kg is the rounded 1.041 kg: with 1.04 w_n is 0.1-0.3 rad/s high.
        assert modal_printed_mass.natural_frequency_rad_s - w > 0.05
    # Printed tau_i (ms) equal c_i / k_i.
    printed_tau = {
        "5.4": {"bubble": [71.32], "plate": [55.09], "stud": [37.60]},
        "5.5": {"bubble": [8.57], "plate": [8.62], "stud": [2.88]},
        "5.6": {"bubble": [1.36, 126.01], "plate": [1.57, 92.24], "stud": [0.61, 69.20]},
    }[table][mount]
    tau_ms = model.time_constants * 1e3
    # Table 5.4 prints 55.09 ms for the plate mount, but 1729.11 / 31.47 = 54.94 ms. Elsewhere
    # the last printed digit is sometimes off by 1 (71.32 for 71.332, 126.01 for 126.022).
    rtol = 4e-3 if key == ("5.4", "plate") else 2e-4
    np.testing.assert_allclose(tau_ms, printed_tau, rtol=rtol, atol=0.006)
    if key == ("5.4", "plate"):
        assert abs(tau_ms[0] - 55.09) > 0.1


def test_model_validation_errors_name_the_argument():
    with pytest.raises(ValueError, match="mass"):
        MaxwellModel(0.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="maxwell_k"):
        MaxwellModel(1.0, 1.0, 1.0, (-1.0,), (1.0,))
    with pytest.raises(ValueError, match="same length"):
        MaxwellModel(1.0, 1.0, 1.0, (1.0, 2.0), (1.0,))
    with pytest.raises(TypeError, match="k"):
        MaxwellModel(1.0, "12", 1.0)
    with pytest.raises(ValueError, match="omega_rad_s"):
        frf(MaxwellModel(1.0, 1.0, 1.0), [-1.0])
    with pytest.raises(ValueError, match="quantity"):
        frf(MaxwellModel(1.0, 1.0, 1.0), [1.0], "mobility")
    with pytest.raises(ValueError, match="overdamped"):
        modal_properties(MaxwellModel(1.0, 1.0, 100.0))


def test_isolator_numerics_do_not_import_rclpy():
    code = (
        "import sys\n"
        "import dva_offline.isolator.maxwell_fit, dva_offline.isolator.mv_curves\n"
        "import dva_offline.isolator.order_selection, dva_offline.isolator.frf_estimation\n"
        "import dva_offline.isolator.cli, dva_offline.isolator.files\n"
        "assert 'rclpy' not in sys.modules and 'dva_msgs' not in sys.modules\n"
        "assert 'matplotlib' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
