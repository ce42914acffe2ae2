"""Two simultaneous effects and jittering measured covariates (FRF domain), small samples.

The rates over many seeds are measured by bench/bench_discrepancy_combined.py (docs).
"""
import numpy as np
import pytest

from dva_offline.discrepancy import loop, synthetic
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.discrepancy.synthetic_combined import generate_combined
from dva_offline.isolator.frf_data import split_conditions


def run(case, max_steps=12):
    conds = split_conditions(case.frequency_hz, case.values, case.quantity, case.covariates,
                             list(case.condition_columns))
    cov = [c for c in case.covariates if c != "set"]
    dom = FrfDomain(conds, mass=case.mass, static_stiffness=case.static_stiffness,
                    covariates=cov or None)
    return loop.run(dom, rule=loop.DecisionRule(max_steps=max_steps))


def test_generator_composes_effects_each_detectable():
    case = generate_combined(("covariate_shift", "fixture_mass"), np.random.default_rng(0))
    assert case.effect == "covariate_shift+fixture_mass"
    assert case.condition_columns == ("temperature_c",)
    for e in ("covariate_shift", "fixture_mass"):
        assert case.parameters[e]["effect_size"] >= synthetic.MIN_EFFECT_SNR * case.sigma
    # one effect alone: the single-effect generator's physics (mass: 1 / (K - (m+dm) w^2))
    one = generate_combined(("fixture_mass",), np.random.default_rng(1), sigma=0.0)
    w = 2 * np.pi * one.frequency_hz
    dm = one.parameters["fixture_mass"]["dm"]
    np.testing.assert_allclose(1 / one.clean_values, 1 / one.base_values - dm * w**2,
                               rtol=1e-10)
    with pytest.raises(ValueError, match="two different"):
        generate_combined(("sensor_delay", "sensor_delay"), np.random.default_rng(0))


def test_jitter_records_drifting_temperatures_and_a_set_column():
    case = generate_combined(("covariate_shift",), np.random.default_rng(2), jitter=True)
    assert case.condition_columns == ("set",)
    t, s = case.covariates["temperature_c"], case.covariates["set"]
    spreads = [np.ptp(t[s == k]) for k in np.unique(s)]
    assert 0.0 < max(spreads) < 0.6 and len(np.unique(t)) == t.size


def test_two_effects_both_named_in_turn():
    res = run(generate_combined(("sensor_delay", "fixture_mass"), np.random.default_rng(2001)))
    assert {s.effect for s in res.steps} == {"sensor_delay", "fixture_mass"}
    assert res.final.status == "consistent" and res.verdict.status == "explained"
    assert res.final.error < 0.5 * res.baseline.error


def test_jittering_temperature_still_names_the_shift_and_halves_the_error():
    res = run(generate_combined(("covariate_shift",), np.random.default_rng(2000), jitter=True),
              max_steps=1)
    assert res.verdict.status == "explained" and res.verdict.effect == "covariate_shift"
    assert res.augmented.error <= 0.5 * res.baseline.error
