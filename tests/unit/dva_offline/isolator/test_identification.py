"""Identification with w_n and zeta from the data (issue #18): acceptance on random
Maxwell-Voigt systems, Table 3.1 as UFF 58, degenerate elements, constraint check."""
import json

import numpy as np
import pytest

from dva_offline import cli
from dva_offline.isolator import files as isolator_files
from dva_offline.isolator.identification import identify
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties
from dva_offline.isolator.modal_fit import degenerate_elements
from dva_offline.isolator.synthetic_systems import add_complex_noise, random_mv_system

KN = 1e3
TABLE_3_1 = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (40.0,))  # w_n 119.03, zeta 0.361
SYSTEM_F = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 24 * KN), (80.0, 2000.0))
F_HZ = np.linspace(1.0, 60.0, 400)
SIGMA = 0.005


def run(capsys, *argv):
    code = cli.main(["isolator", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_random_systems_meet_the_done_when_criteria():
    """20 random M-V systems, zeta 0.05-0.45, 0.5 % complex noise, 400 points over 1-60 Hz,
    default identification (up to 2 elements): FRF error <= 2 x noise, w_n within 0.5 %, zeta
    within 2 % in >= 95 % of cases, no refusal."""
    rng = np.random.default_rng(2024)
    omega = 2 * np.pi * F_HZ
    ok, z_scores, zetas = [], [], []
    for _ in range(20):
        system = random_mv_system(rng)
        true = modal_properties(system)
        h = add_complex_noise(frf(system, omega), SIGMA, rng)
        result = identify(omega, h, system.mass, system.k)  # must not raise
        mf = result.modal_fit
        err_w = mf.natural_frequency_rad_s / true.natural_frequency_rad_s - 1
        err_z = mf.damping_ratio / true.damping_ratio - 1
        ok.append(result.fit.frf_error <= 2 * SIGMA and abs(err_w) <= 0.005
                  and abs(err_z) <= 0.02)
        z_scores += [(mf.natural_frequency_rad_s - true.natural_frequency_rad_s)
                     / mf.natural_frequency_std,
                     (mf.damping_ratio - true.damping_ratio) / mf.damping_ratio_std]
        zetas.append(true.damping_ratio)
        # The reported model is the unconstrained one: its own w_n, zeta are the targets.
        assert result.constraint_check is None
        assert result.fit.model.n_elements == 1  # the truth has one element
    assert max(zetas) > 0.35 and min(zetas) < 0.15  # heavy and light damping both covered
    assert np.mean(ok) >= 0.95, ok
    # Standard errors are honest: the errors against the truth are O(1) standard errors.
    rms_z = float(np.sqrt(np.mean(np.square(z_scores))))
    assert 0.5 < rms_z < 2.0, rms_z


def test_table_3_1_as_uff58_gives_the_study_modal_values(capsys, tmp_path):
    pytest.importorskip("pyuff")
    path = tmp_path / "table_3_1.uff"
    h = add_complex_noise(frf(TABLE_3_1, 2 * np.pi * F_HZ), SIGMA, np.random.default_rng(7))
    isolator_files.write_uff58(path, F_HZ, h, "receptance")
    code, out, err = run(capsys, "identify", path, "--quantity", "receptance", "--mass", 1,
                         "--static-stiffness", 12000, "--json")
    assert code == 0, err
    payload = json.loads(out)
    assert payload["natural_frequency_rad_s"] == pytest.approx(119.03, abs=0.1)
    assert payload["damping_ratio"] == pytest.approx(0.361, abs=0.002)
    assert payload["modal_estimate"]["damping_ratio_std"] < 0.001
    assert payload["frf_error"] < 2 * SIGMA
    # One element: the second of the two asked for has the first's time constant.
    assert payload["n_elements"] == 1 and payload["order"]["requested"] == 2
    assert "same time constant" in payload["order"]["reductions"][0]
    assert payload["elements"][0]["k"] == pytest.approx(12 * KN, rel=0.03)
    assert payload["elements"][0]["c"] == pytest.approx(40.0, rel=0.03)
    # The half-power estimate is biased for this heavily damped mount and is flagged.
    code, out, err = run(capsys, "identify", path, "--mass", 1, "--static-stiffness", 12000,
                         "--modal-estimate", "half-power", "--json")
    assert code == 0, err
    hp = json.loads(out)
    assert hp["target_damping_ratio"] > 0.45
    assert any("assumes light damping" in w for w in hp["warnings"])
    assert hp["constraint_check"]["rejected"]
    assert set(hp["constraint_check"]["constraints"]) == {"natural_frequency", "damping_ratio"}
    assert hp["frf_error"] > 10 * payload["frf_error"]


def test_degenerate_elements_are_merged_or_dropped():
    same_tau = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 500.0), (40.0, 500.0 * 40 / 12e3))
    tiny = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 1e-3), (40.0, 1.0))
    assert [d[2] for d in degenerate_elements(same_tau, 119.0)] == ["merge"]
    assert [d[2] for d in degenerate_elements(tiny, 119.0)] == ["drop"]
    assert degenerate_elements(SYSTEM_F, 214.8) == []
    omega = 2 * np.pi * F_HZ
    # Noise-free Table 3.1 data fitted with up to 3 elements: one element, exact.
    result = identify(omega, frf(TABLE_3_1, omega), 1.0, 12 * KN, n_elements=3)
    model = result.fit.model
    assert model.n_elements == 1 and len(result.reductions) == 2
    assert model.maxwell_k[0] == pytest.approx(12 * KN, rel=1e-6)
    assert model.maxwell_c[0] == pytest.approx(40.0, rel=1e-6)
    assert result.modal_fit.damping_ratio == pytest.approx(0.36092, abs=1e-5)
    # A real two-element system (Table 4.1 System F) keeps both elements.
    result = identify(omega, frf(SYSTEM_F, omega), 1.0, 12 * KN, n_elements=2)
    assert result.fit.model.n_elements == 2 and result.reductions == ()
    assert result.fit.model.maxwell_c[1] == pytest.approx(2000.0, rel=1e-4)


def test_wrong_imposed_damping_ratio_is_flagged_and_json_has_both_fits(capsys, tmp_path):
    path = tmp_path / "t31.csv"
    rng = np.random.default_rng(11)
    h = add_complex_noise(frf(TABLE_3_1, 2 * np.pi * F_HZ), SIGMA, rng)
    isolator_files.write_frf_csv(path, F_HZ, h)
    true = modal_properties(TABLE_3_1)
    common = ["identify", path, "--mass", 1, "--static-stiffness", 12000,
              "--natural-frequency-rad-s", true.natural_frequency_rad_s, "--json"]
    code, out, err = run(capsys, *common, "--damping-ratio", 0.30)
    assert code == 0, err
    payload = json.loads(out)
    check = payload["constraint_check"]
    assert check["rejected"] and check["constraints"] == ["damping_ratio"]
    assert check["p_value"] < 1e-6 and check["z_damping_ratio"] < -10
    assert "damping ratio 0.3 " in check["message"] and check["message"] in payload["warnings"]
    # Both fits: the constrained one honours the user's value exactly, the other fits the data.
    assert payload["damping_ratio"] == pytest.approx(0.30, abs=1e-9)
    assert payload["unconstrained_fit"]["damping_ratio"] == pytest.approx(0.361, abs=0.002)
    assert payload["frf_error"] > 3 * payload["unconstrained_fit"]["frf_error"]
    assert payload["unconstrained_fit"]["frf_error"] < 1.2 * SIGMA
    # The true values, imposed, are consistent with the data.
    code, out, err = run(capsys, *common, "--damping-ratio", true.damping_ratio)
    assert code == 0, err
    payload = json.loads(out)
    assert not payload["constraint_check"]["rejected"]
    assert payload["constraint_check"]["p_value"] > 0.01
    assert payload["warnings"] == []
    # Text output names the rejected constraint too.
    code, out, err = run(capsys, *common[:-1], "--damping-ratio", 0.30)
    assert code == 0 and "constraint check" in out and "(rejected)" in out
    assert "the data contradict the imposed damping ratio" in out


def test_heavily_damped_system_with_no_half_power_point_is_not_refused(capsys, tmp_path):
    # zeta = 0.45 mount whose |H| never falls to the half-power level below the peak, while its
    # resonance lies inside the data: the old default (half power) refused it.
    system = random_mv_system(np.random.default_rng(0), damping_range=(0.45, 0.45))
    true = modal_properties(system)
    f = np.linspace(1.0, 60.0, 400)
    assert f[0] < true.natural_frequency_rad_s / (2 * np.pi) < f[-1]
    path = tmp_path / "heavy.csv"
    h = add_complex_noise(frf(system, 2 * np.pi * f, "accelerance"), SIGMA,
                          np.random.default_rng(4))
    isolator_files.write_frf_csv(path, f, h)
    args = ["identify", path, "--quantity", "accelerance", "--mass", 1, "--static-stiffness",
            system.k, "--json"]
    code, out, err = run(capsys, *args)
    assert code == 0, err
    payload = json.loads(out)
    assert payload["damping_ratio"] == pytest.approx(0.45, rel=0.02)
    assert payload["natural_frequency_rad_s"] == pytest.approx(true.natural_frequency_rad_s,
                                                               rel=0.005)
    code, _, err = run(capsys, *args, "--modal-estimate", "half-power")
    assert code == 2 and "does not fall to the half-power level (peak / sqrt 2) below" in err
    assert "--modal-estimate fit" in err and len(err.strip().splitlines()) == 1


# Table 4.1 M-M-V systems (k_i in kN/m, c_i in N s/m; m = 1 kg, k = 12 kN/m, c = 40 N s/m).
TABLE_4_1 = {"A": ((12, 20), (24, 20)), "B": ((12, 80), (24, 120)), "C": ((12, 2000), (24, 2000)),
             "D": ((24, 20), (12, 80)), "E": ((24, 20), (12, 2000)), "F": ((12, 80), (24, 2000))}


@pytest.mark.parametrize("name", sorted(TABLE_4_1))
def test_table_4_1_two_element_systems_from_noisy_data(name):
    """Two-element truths (zeta 0.11-0.43): w_n, zeta from 0.5 % noisy data as in the issue."""
    (k1, c1), (k2, c2) = TABLE_4_1[name]
    system = MaxwellModel(1.0, 12 * KN, 40.0, (k1 * KN, k2 * KN), (c1, c2))
    true = modal_properties(system)
    omega = np.linspace(0.0, 2.5 * true.natural_frequency_rad_s, 300)[1:]
    rng = np.random.default_rng(sorted(TABLE_4_1).index(name))
    h = add_complex_noise(frf(system, omega), SIGMA, rng)
    result = identify(omega, h, 1.0, 12 * KN, n_elements=2)
    mf = result.modal_fit
    assert result.fit.frf_error <= 2 * SIGMA
    assert mf.natural_frequency_rad_s == pytest.approx(true.natural_frequency_rad_s, rel=0.005)
    assert mf.damping_ratio == pytest.approx(true.damping_ratio, rel=0.02)
    assert abs(mf.damping_ratio - true.damping_ratio) < 4 * mf.damping_ratio_std
