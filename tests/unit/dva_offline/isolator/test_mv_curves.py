"""M-V identification by intersecting constant-omega and constant-zeta curves.

Tables 3.5-3.7 and 4.2.
"""
import numpy as np
import pytest

from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties
from dva_offline.isolator.mv_curves import (
    frf_error,
    max_primary_damping,
    modal_grid,
    mv_family,
    select_primary_damping,
    solve_mv_element,
)
from dva_offline.isolator.voigt_identification import voigt_model_k, voigt_model_m

KN = 1e3
M, K = 1.0, 12 * KN

# (system c1 of Table 3.3, rows (c, c1 N s/m, k1 kN/m) as printed)
TABLES = {
    "3.5": (20, [(-80, 139.36, 551.23), (0, 59.51, 102.25), (20, 39.63, 45.93),
                 (40, 19.99, 11.99), (60, 10.26, 0.41)]),
    "3.6": (80, [(-240, 310.89, 248.90), (-80, 160.7, 68.92), (0, 96.88, 23.54),
                 (40, 80.00, 12.00), (80, 138.43, 7.90), (100, 815.13, 8.64)]),
    "3.7": (400, [(-320, 363.95, 268.90), (-160, 216.41, 91.727), (-80, 153.69, 40.93),
                  (-40, 133.23, 24.99), (0, 141.04, 15.34), (20, 185.64, 12.88),
                  (40, 399.70, 12.00), (55, 25357, 12.37)]),
}
# Rows whose printed (c1, k1) differ from the exact intersection by more than 0.1 %: the last
# row of each table, next to the Voigt Model M limit of the family, where (c1, k1) move by 24 to
# 230 % per % of error in omega_n or zeta (Table 3.5 is ~50 %/% throughout, yet its other rows
# agree, so the study solved those accurately).
DISAGREEING_ROWS = {("3.5", 60), ("3.6", 100), ("3.7", 55)}


def system_modal(c1):
    modal = modal_properties(MaxwellModel(M, K, 40.0, (K,), (c1,)))
    return modal.natural_frequency_rad_s, modal.damping_ratio


def _decimals(value: float) -> int:
    text = repr(value)
    return len(text.split(".")[1]) if "." in text and not text.endswith(".0") else 0


@pytest.mark.parametrize("table", sorted(TABLES))
def test_each_printed_row_has_the_systems_omega_and_zeta(table):
    """Every printed row reproduces the system's w_n and zeta, to within the effect of rounding
    the printed c1 and k1 (half a unit of the last printed digit, propagated numerically)."""
    c1_sys, rows = TABLES[table]
    w, z = system_modal(c1_sys)
    for c, c1, k1 in rows:
        got = modal_properties(MaxwellModel(M, K, c, (k1 * KN,), (c1,)))
        dc1 = 0.5 * 10.0 ** -_decimals(c1)
        dk1 = 0.5 * 10.0 ** -_decimals(k1) * KN
        tol_w = tol_z = 0.0
        for dk, dc in ((dk1, 0.0), (0.0, dc1)):
            alt = modal_properties(MaxwellModel(M, K, c, (k1 * KN + dk,), (c1 + dc,)))
            tol_w += abs(alt.natural_frequency_rad_s - got.natural_frequency_rad_s)
            tol_z += abs(alt.damping_ratio - got.damping_ratio)
        assert abs(got.natural_frequency_rad_s - w) <= tol_w + 0.005, (table, c)
        assert abs(got.damping_ratio - z) <= tol_z + 0.0005, (table, c)
        # and to the 2 decimals Table 3.3 prints, for every row
        assert round(got.damping_ratio, 2) == round(z, 2)


@pytest.mark.parametrize("table", sorted(TABLES))
def test_closed_form_intersection_matches_printed_rows(table):
    c1_sys, rows = TABLES[table]
    w, z = system_modal(c1_sys)
    for sol, (c, c1, k1) in zip(mv_family(M, K, w, z, [r[0] for r in rows]), rows):
        assert sol.physical
        rel = max(abs(sol.c1 / c1 - 1), abs(sol.k1 / (k1 * KN) - 1))
        if (table, c) in DISAGREEING_ROWS:
            assert rel > 1e-3 and sol.sensitivity >= 10, (table, c, rel, sol.sensitivity)
        else:
            assert rel <= 1e-3, (table, c, sol.c1, sol.k1)
        # The exact solution has the system's omega and zeta (to solver precision).
        got = modal_properties(sol.model(M, K))
        assert got.natural_frequency_rad_s == pytest.approx(w, rel=1e-10)
        assert got.damping_ratio == pytest.approx(z, rel=1e-9)


def test_table_3_7_c55_row_c1_25357_vs_exact():
    """Printed c1 = 25357 N s/m; the exact intersection is 26564 N s/m (4.8 % away). Both give
    the system's omega/zeta to about 0.01 rad/s: the row sits where omega and zeta hardly depend
    on c1 (Type C, w_n tau ~ 300), so c1 is barely identifiable there."""
    w, z = system_modal(400)
    sol = solve_mv_element(M, K, 55.0, w, z)
    assert sol.c1 == pytest.approx(26564, rel=1e-3)
    assert abs(sol.c1 - 25357) / 25357 > 0.04
    assert sol.sensitivity > 100
    printed = modal_properties(MaxwellModel(M, K, 55.0, (12.37 * KN,), (25357.0,)))
    assert printed.natural_frequency_rad_s == pytest.approx(w, abs=0.01)


def test_system_itself_is_the_c40_member_of_its_family():
    for c1_sys in (20, 80, 400):
        w, z = system_modal(c1_sys)
        sol = solve_mv_element(M, K, 40.0, w, z)
        assert sol.c1 == pytest.approx(c1_sys, rel=1e-9)
        assert sol.k1 == pytest.approx(K, rel=1e-9)


@pytest.mark.parametrize("c1_sys, printed_limit", [(20, 61.45), (80, 104.56), (400, 55.25)])
def test_family_upper_limit_is_voigt_model_m(c1_sys, printed_limit):
    """Section 3.4: no intersection for c above Voigt Model M's c_v; as c -> -inf the model
    approaches Voigt Model K (c + c1 -> c_v of Model K, k1 -> inf)."""
    w, z = system_modal(c1_sys)
    c_max = max_primary_damping(M, K, w, z)
    assert c_max == pytest.approx(voigt_model_m(M, w, z).c, rel=1e-6)
    assert c_max == pytest.approx(printed_limit, abs=0.015)
    assert not solve_mv_element(M, K, c_max + 0.5, w, z).physical
    far = solve_mv_element(M, K, -1e5, w, z)
    assert far.physical and far.k1 > 1e3 * K
    assert far.c + far.c1 == pytest.approx(voigt_model_k(K, w, z).c, rel=0.01)
    # Peak receptance grows as c decreases and stays between the two Voigt limits.
    omega = np.linspace(1, 300, 300)
    peaks = [np.abs(frf(s.model(M, K), omega)).max() for s in
             mv_family(M, K, w, z, np.linspace(-300, c_max - 1, 12))]
    assert np.all(np.diff(peaks) < 0)
    lo = np.abs(frf(voigt_model_m(M, w, z).as_maxwell_model(), omega)).max()
    hi = np.abs(frf(voigt_model_k(K, w, z).as_maxwell_model(), omega)).max()
    assert lo * 0.999 <= min(peaks) and max(peaks) <= hi * 1.001


TABLE_4_1 = {
    "A": ((12, 20), (24, 20)), "B": ((12, 80), (24, 120)), "C": ((12, 2000), (24, 2000)),
    "D": ((24, 20), (12, 80)), "E": ((24, 20), (12, 2000)), "F": ((12, 80), (24, 2000)),
}
TABLE_4_2 = {  # c, k1 (kN/m), c1
    "A": (49.702, 18.788, 30.447), "B": (40.382, 35.492, 196.437),
    "C": (39.724, 35.987, 3476.033), "D": (58.030, 12.695, 83.162),
    "E": (60.637, 12.420, 2072.516), "F": (61.395, 33.221, 1482.569),
}


def mmv_system(name):
    (k1, c1), (k2, c2) = TABLE_4_1[name]
    return MaxwellModel(M, K, 40.0, (k1 * KN, k2 * KN), (c1, c2))


@pytest.mark.parametrize("name", sorted(TABLE_4_2))
def test_table_4_2_mv_models_of_mmv_systems(name):
    system = mmv_system(name)
    sys_modal = modal_properties(system)
    w, z = sys_modal.natural_frequency_rad_s, sys_modal.damping_ratio
    c, k1, c1 = TABLE_4_2[name]
    printed = MaxwellModel(M, K, c, (k1 * KN,), (c1,))
    got = modal_properties(printed)
    # Printed M-V models have the system's omega and zeta (Table 4.1, 3 decimals).
    assert got.natural_frequency_rad_s == pytest.approx(w, abs=0.002)
    assert got.damping_ratio == pytest.approx(z, abs=0.0005)
    # Given the printed c, the exact intersection gives k1 to the printed 3 decimals (kN/m,
    # 0.1 % for A) and c1 within 0.4 %.
    sol = solve_mv_element(M, K, c, w, z)
    assert sol.k1 / KN == pytest.approx(k1, abs=0.0015 if name != "A" else 0.01)
    assert sol.c1 == pytest.approx(c1, rel=0.004)
    # Our choice of c (minimum FRF error over the family) fits at least as well as the study's.
    omega = np.linspace(0, 300, 300)
    h = frf(system, omega)
    best = select_primary_damping(omega, h, M, K, w, z)
    assert frf_error(frf(best.model(M, K), omega), h) <= frf_error(frf(printed, omega), h) + 1e-9


def test_table_4_2_mv_model_cannot_represent_system_f():
    """Fig. 4.2(f): a Type B + Type C system is not matched by any M-V model, others are."""
    omega = np.linspace(0, 300, 300)
    errors = {}
    for name in TABLE_4_1:
        system = mmv_system(name)
        modal = modal_properties(system)
        h = frf(system, omega)
        best = select_primary_damping(
            omega, h, M, K, modal.natural_frequency_rad_s, modal.damping_ratio
        )
        errors[name] = frf_error(frf(best.model(M, K), omega), h)
    assert errors["F"] > 0.05
    assert max(v for n, v in errors.items() if n != "F") < 0.02


def test_modal_grid_matches_scalar_modal_analysis():
    k1 = np.array([1e3, 12e3, 100e3])
    c1 = np.array([10.0, 40.0, 1000.0])
    omega, zeta = modal_grid(M, K, 40.0, k1, c1)
    assert omega.shape == (3, 3)
    for i, cc in enumerate(c1):
        for j, kk in enumerate(k1):
            ref = modal_properties(MaxwellModel(M, K, 40.0, (kk,), (cc,)))
            assert omega[i, j] == pytest.approx(ref.natural_frequency_rad_s, rel=1e-12)
            assert zeta[i, j] == pytest.approx(ref.damping_ratio, rel=1e-10)
