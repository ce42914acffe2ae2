"""Constrained-optimisation identification (eq. 4.11-4.13): Tables 4.3, 4.4, 4.6, order selection.

FRF-error criterion for noisy data: the identified model's receptance is compared with the
noise-free system receptance, e = ||H_fit - H_0||_2 / ||H_0||_2. With eq. (4.13) noise of
standard deviation sigma, the data itself is ~sigma away from H_0; we require e < 0.3 sigma,
i.e. the fit removes most of the noise.
"""
import warnings

import numpy as np
import pytest

from dva_offline.isolator.maxwell_fit import (
    FitWarning,
    add_frf_noise,
    fit_maxwell_model,
    fit_unconstrained_least_squares,
    initial_guesses,
)
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties
from dva_offline.isolator.mv_curves import frf_error
from dva_offline.isolator.order_selection import select_model_order

KN = 1e3
OMEGA = np.linspace(0.0, 300.0, 300)  # section 4.3.1: 0-300 rad/s, 300 points


def fit_to(system, n, sigma=0.0, seed=0, **kw):
    modal = modal_properties(system)
    h0 = frf(system, OMEGA)
    h = add_frf_noise(h0, sigma, np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        fit = fit_maxwell_model(
            OMEGA, h, system.mass, system.k, n, modal.natural_frequency_rad_s,
            modal.damping_ratio, **kw,
        )
    return fit, h0


def params(model):
    return np.array([model.c, *model.maxwell_k, *model.maxwell_c])


TABLE_4_3_SYSTEMS = {"A": 20.0, "B": 80.0, "C": 400.0}  # c1 of Table 3.3
TABLE_4_3_SIGMA0 = {"A": (40.00, 12.00, 20.00), "B": (40.00, 12.00, 80.00),
                    "C": (40.01, 12.00, 400.0)}  # c, k1 (kN/m), c1 printed for sigma = 0


@pytest.mark.parametrize("name", sorted(TABLE_4_3_SYSTEMS))
def test_table_4_3_sigma0_recovers_parameters(name):
    system = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (TABLE_4_3_SYSTEMS[name],))
    fit, _ = fit_to(system, 1)
    c, k1, c1 = TABLE_4_3_SIGMA0[name]
    assert fit.model.c == pytest.approx(c, abs=0.015)  # printed 40.01 for C: 0.01 off
    assert fit.model.maxwell_k[0] / KN == pytest.approx(k1, abs=0.005)
    assert fit.model.maxwell_c[0] == pytest.approx(c1, abs=0.05)
    np.testing.assert_allclose(params(fit.model), params(system), rtol=1e-5)
    assert fit.constraint_error < 1e-9
    assert fit.frf_error < 1e-8


@pytest.mark.parametrize("name", sorted(TABLE_4_3_SYSTEMS))
@pytest.mark.parametrize("sigma", [0.01, 0.05])
def test_table_4_3_noisy_cases_recover_the_frf(name, sigma):
    system = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (TABLE_4_3_SYSTEMS[name],))
    fit, h0 = fit_to(system, 1, sigma, seed=43)
    err_true = frf_error(frf(fit.model, OMEGA), h0)
    assert err_true < 0.3 * sigma
    assert fit.constraint_error < 1e-8
    se = np.array([fit.c_std, *fit.maxwell_k_std, *fit.maxwell_c_std])
    assert np.all(np.isfinite(se)) and np.all(se > 0)


def test_table_4_3_noise_sensitivity_ordering_a_worse_than_c():
    """Section 4.3.1: identified parameters of Model A (Type A) change much more with noise
    than those of Model C (Type C). Checked through the standard errors of k1."""
    rel = {}
    for name in ("A", "C"):
        system = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (TABLE_4_3_SYSTEMS[name],))
        fit, _ = fit_to(system, 1, 0.05, seed=7)
        rel[name] = fit.maxwell_k_std[0] / fit.model.maxwell_k[0]
    assert rel["A"] > 10 * rel["C"]


def test_table_4_3_printed_noisy_fits_also_match_the_system_frf():
    """The study's own sigma > 0 parameters give FRFs within 1 % of the systems'."""
    printed = {20: [(35.41, 17.80, 24.45), (32.10, 22.72, 27.69)],
               80: [(39.70, 12.06, 80.02), (38.22, 12.36, 80.16)],
               400: [(39.99, 12.00, 399.4), (40.74, 12.00, 419.9)]}
    for c1_sys, rows in printed.items():
        h0 = frf(MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (c1_sys,)), OMEGA)
        for c, k1, c1 in rows:
            printed_model = MaxwellModel(1.0, 12 * KN, c, (k1 * KN,), (c1,))
            assert frf_error(frf(printed_model, OMEGA), h0) < 0.01


SYSTEM_F = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 24 * KN), (80.0, 2000.0))


def test_table_4_4_sigma0_recovers_system_f():
    fit, _ = fit_to(SYSTEM_F, 2)
    # Printed (sigma = 0): 39.9903, 12.0025, 79.9205, 24.0041, 1999.97 -- within 0.1 % of the
    # true values; our fit is within 1e-5.
    printed = np.array([39.9903, 12.0025 * KN, 24.0041 * KN, 79.9205, 1999.97])
    np.testing.assert_allclose(printed, params(SYSTEM_F), rtol=1e-3)
    np.testing.assert_allclose(params(fit.model), params(SYSTEM_F), rtol=1e-5)
    assert [t.label for t in fit.element_types] == ["B", "C"]


@pytest.mark.parametrize("sigma", [0.01, 0.05])
def test_table_4_4_noisy_fit_recovers_frf(sigma):
    fit, h0 = fit_to(SYSTEM_F, 2, sigma, seed=44)
    assert frf_error(frf(fit.model, OMEGA), h0) < 0.3 * sigma
    assert fit.constraint_error < 1e-8


GENERAL_A = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 12 * KN, 24 * KN), (20.0, 80.0, 2000.0))
GENERAL_B = MaxwellModel(
    1.0, 12 * KN, 40.0, (12 * KN, 24 * KN, 12 * KN, 24 * KN, 12 * KN, 24 * KN),
    (20.0, 20.0, 80.0, 120.0, 2000.0, 2000.0),
)
TABLE_4_6_A = MaxwellModel(1.0, 12 * KN, 49.54, (14.95 * KN, 24.65 * KN), (81.76, 2003.24))
TABLE_4_6_B = MaxwellModel(1.0, 12 * KN, 65.73, (40.69 * KN, 36.50 * KN), (209.15, 3797.60))


@pytest.mark.parametrize("system, printed", [(GENERAL_A, TABLE_4_6_A), (GENERAL_B, TABLE_4_6_B)])
def test_table_4_6_mmv_models_match_general_systems(system, printed):
    """An M-M-V model (one Type B, one Type C element) reproduces 3- and 6-element systems."""
    fit, h0 = fit_to(system, 2)
    assert fit.frf_error < 0.02
    assert [t.label for t in fit.element_types] == ["B", "C"]
    assert fit.constraint_error < 1e-8
    # The study's printed models match the systems' FRFs about as well as ours.
    assert frf_error(frf(printed, OMEGA), h0) < 0.02


def test_table_4_6_a_reproduced_with_seed_objective():
    """With the study's objective (eq. 4.11: sum |H(kappa) - H_j|, unweighted) the identified
    Model A is the printed one to ~0.3 %."""
    fit, _ = fit_to(GENERAL_A, 2, objective="l1", weighting="none")
    np.testing.assert_allclose(params(fit.model), params(TABLE_4_6_A), rtol=3e-3)


def test_table_4_6_b_needs_the_printed_system_b_modal_values():
    """Table 4.6 Model B follows from constraints 293.87 rad/s / 0.2617 (Table 4.5's printed
    values, = Model B's own), not from System B's true 295.21 / 0.266: fitting with the printed
    values lands within 2 % of the printed parameters, with the true ones up to 4 % away."""
    h = frf(GENERAL_B, OMEGA)
    kwargs = dict(objective="l1", weighting="none")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        printed_cons = fit_maxwell_model(OMEGA, h, 1.0, 12 * KN, 2, 293.87, 0.2617, **kwargs)
        modal = modal_properties(GENERAL_B)
        true_cons = fit_maxwell_model(OMEGA, h, 1.0, 12 * KN, 2, modal.natural_frequency_rad_s,
                                      modal.damping_ratio, **kwargs)
    target = params(TABLE_4_6_B)
    dev_printed = np.max(np.abs(params(printed_cons.model) / target - 1))
    dev_true = np.max(np.abs(params(true_cons.model) / target - 1))
    assert dev_printed < 0.02
    assert dev_true > 1.5 * dev_printed


def test_standard_errors_shrink_with_noise_and_are_zero_without():
    fits = [fit_to(SYSTEM_F, 2, s, seed=5)[0] for s in (0.0, 0.01, 0.05)]
    se = [np.array([f.c_std, *f.maxwell_k_std, *f.maxwell_c_std]) for f in fits]
    assert np.all(se[0] < 1e-6 * params(SYSTEM_F))
    assert np.all(se[1] < se[2])


def test_initial_guesses_follow_section_4_3_2_rules():
    modal = modal_properties(SYSTEM_F)
    guesses = initial_guesses(1.0, 12 * KN, 2, modal.natural_frequency_rad_s, modal.damping_ratio)
    assert len(guesses) >= 3
    c, ks, cs = guesses[0]
    guess = MaxwellModel(1.0, 12 * KN, c, tuple(ks), tuple(cs))
    gm = modal_properties(guess)
    # Rule 2: guess has the measured omega and zeta; rule 1: one Type B and one Type C.
    assert gm.natural_frequency_rad_s == pytest.approx(modal.natural_frequency_rad_s, rel=1e-9)
    assert gm.damping_ratio == pytest.approx(modal.damping_ratio, rel=1e-8)
    from dva_offline.isolator.element_types import classify_elements

    assert sorted(t.label for t in classify_elements(guess)) == ["B", "C"]


def test_negative_damping_fit_is_flagged():
    """Table 5.6-like data: the fit has c < 0 and warns (non-physical primary damper)."""
    system = MaxwellModel(1.041, 14.01 * KN, -55.49, (64.44 * KN, 18.23 * KN), (87.81, 2297.39))
    modal = modal_properties(system)
    omega = 2 * np.pi * np.arange(3.0, 80.0, 0.5)
    with pytest.warns(FitWarning, match="negative"):
        fit = fit_maxwell_model(omega, frf(system, omega, "accelerance"), 1.041, 14.01 * KN, 2,
                                modal.natural_frequency_rad_s, modal.damping_ratio,
                                quantity="accelerance")
    assert fit.model.c < 0
    assert any("negative" in w for w in fit.warnings)
    np.testing.assert_allclose(params(fit.model), params(system), rtol=1e-4)


def test_overparameterised_fit_is_flagged_not_unique():
    """Fitting 3 elements to an M-V system cannot determine all parameters: warn."""
    system = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (80.0,))
    modal = modal_properties(system)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = fit_maxwell_model(OMEGA, frf(system, OMEGA), 1.0, 12 * KN, 3,
                                modal.natural_frequency_rad_s, modal.damping_ratio)
    assert fit.frf_error < 1e-3
    assert fit.warnings
    assert any(issubclass(w.category, FitWarning) for w in caught)


def test_unconstrained_baseline_fits_but_ignores_modal_constraints():
    h = add_frf_noise(frf(SYSTEM_F, OMEGA), 0.05, np.random.default_rng(3))
    modal = modal_properties(SYSTEM_F)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        base = fit_unconstrained_least_squares(
            OMEGA, h, 1.0, 12 * KN, 2, modal.natural_frequency_rad_s, modal.damping_ratio
        )
    assert base.method == "least_squares"
    assert base.frf_error < 0.06
    assert base.constraint_error > 1e-6  # the unconstrained fit does not honour eq. 4.12


def test_order_selection_picks_two_elements_for_system_f_and_one_for_mv():
    rng = np.random.default_rng(11)
    for system, expected in ((SYSTEM_F, 2),
                             (MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN,), (80.0,)), 1)):
        modal = modal_properties(system)
        h = add_frf_noise(frf(system, OMEGA), 0.01, rng)
        sel = select_model_order(OMEGA, h, 1.0, 12 * KN, modal.natural_frequency_rad_s,
                                 modal.damping_ratio, max_elements=3)
        assert sel.orders == (0, 1, 2, 3)
        assert sel.selected_order == expected
        assert sel.holdout_errors[0] > 2 * min(sel.holdout_errors)  # Voigt is clearly worse


def test_fit_input_validation():
    with pytest.raises(ValueError, match="n_elements"):
        fit_maxwell_model(OMEGA, frf(SYSTEM_F, OMEGA), 1.0, 12e3, 0, 200.0, 0.2)
    with pytest.raises(ValueError, match="NaN"):
        h = frf(SYSTEM_F, OMEGA)
        h[3] = np.nan
        fit_maxwell_model(OMEGA, h, 1.0, 12e3, 2, 200.0, 0.2)
    with pytest.raises(ValueError, match="too few"):
        fit_maxwell_model(OMEGA[:4], frf(SYSTEM_F, OMEGA[:4]), 1.0, 12e3, 2, 200.0, 0.2)
    with pytest.raises(ValueError, match="damping_ratio"):
        fit_maxwell_model(OMEGA, frf(SYSTEM_F, OMEGA), 1.0, 12e3, 2, 200.0, 1.2)
    with pytest.raises(TypeError, match="rng"):
        add_frf_noise(frf(SYSTEM_F, OMEGA), 0.1, 42)
