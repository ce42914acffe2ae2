"""Laws of a covariate effect from per-condition values (laws.py): the moving test, the
family, the held-out choice, and the plausibility of a fitted law."""
import numpy as np
import pytest

from dva_offline.discrepancy import laws
from dva_offline.discrepancy.fitting import Estimate, ModelFit

LEVELS = np.geomspace(2.0, 20.0, 5)


def level_cov(x=LEVELS, x0=None):
    x0 = float(x[len(x) // 2]) if x0 is None else x0
    groups = np.repeat(np.arange(x.size), 3)
    return laws.covariate_info("force_n", np.repeat(x, 3), groups, len(x) // 2, None)


def trend(values, rel_std=1e-3, x=LEVELS, cov=None, seed=0):
    rng = np.random.default_rng(seed)
    s = rel_std * np.abs(values)
    y = values + s * rng.standard_normal(values.size)
    return laws.find_law("amplitude_dependence", cov or level_cov(x), "stiffness", ("k",), x,
                         y, s)


def test_covariate_levels_merge_scattered_means_and_keep_the_reference():
    groups = np.repeat(np.arange(4), 2)
    col = np.array([6.3, 6.31, 6.29, 6.3, 20.0, 20.1, 2.0, 2.0])  # two sweeps at 6.3 N
    cov = laws.covariate_info("force_n", col, groups, 0, None)
    assert len(cov.levels) == 3 and cov.x0 == pytest.approx(6.305)
    assert cov.x0 in cov.levels and cov.n_free == 2
    np.testing.assert_array_equal(cov.level_index(np.array([2.0, 6.3, 20.05])), [0, -1, 1])


def test_a_constant_coordinate_does_not_move():
    t = trend(np.full(LEVELS.size, 3.0))
    assert not t.moving and t.law == "constant" and t.p_value > 1e-3


def test_a_coordinate_that_does_not_move_alone_can_be_offered_with_its_law():
    # a 3 % trend inside 2 % errors: no move at p = 0.001, but offered its law is fitted
    x = LEVELS
    y = 3.0 * (1 + 0.03 * np.log(x / x[2]) / np.log(10.0))
    s = 0.02 * y
    args = ("amplitude_dependence", level_cov(x), "stiffness", ("k",), x, y, s)
    alone = laws.find_law(*args)
    assert not alone.moving and not alone.offered and alone.scores == ()
    t = laws.find_law(*args, offer=True)
    assert not t.moving and t.offered and t.p_value == alone.p_value
    assert t.law != "constant" and t.scores and "full form" in t.reason


def test_a_power_change_is_found_with_its_exponent():
    # a hardening spring: k = k_lin (1 + 0.05 (a / 20 N)^2)
    t = trend(1e4 * (1 + 0.05 * (LEVELS / 20.0) ** 2), rel_std=2e-4)
    assert t.moving and t.law == "power_change"
    e = t.chosen.theta[1]
    assert e == pytest.approx(2.0, abs=4 * t.chosen.theta_std[1] + 0.02)
    # the other laws were scored on held-out conditions and predict them worse
    held = {sc.law: sc.loco for sc in t.scores}
    assert held["logarithmic"] > 10 * held["power_change"]
    assert np.isnan(held["free"])  # free per level cannot predict a left-out level


def test_a_linear_trend_is_linear_not_a_law_with_more_parameters():
    t = trend(5.0 * (1 + 0.01 * (LEVELS - LEVELS[2])), rel_std=1e-4)
    assert t.law in ("linear", "exponential")  # the same to first order, one parameter


def test_a_step_between_levels_is_free_per_level():
    # a joint that slips above 6 N: no smooth law predicts the left-out levels
    t = trend(np.where(LEVELS > 6.5, 0.93, 1.0), rel_std=2e-4)
    assert t.law == "free" and "no smooth law" in t.reason


def test_too_few_conditions_leave_the_law_free():
    x = np.array([2.0, 20.0])
    t = trend(np.array([1.0, 1.1]), x=x)
    assert t.moving and t.law == "free"


def test_temperature_laws_only_for_temperatures():
    temps = np.array([0.0, 10.0, 20.0, 30.0, 40.0])
    groups = np.repeat(np.arange(5), 2)
    cov_t = laws.covariate_info("temperature_c", np.repeat(temps, 2), groups, 2, 273.15)
    cov_p = laws.covariate_info("pressure", np.repeat(temps + 1, 2), groups, 2, None)
    assert laws.applicable("arrhenius", cov_t) and laws.applicable("wlf", cov_t)
    assert not laws.applicable("arrhenius", cov_p) and not laws.applicable("wlf", cov_p)
    # an Arrhenius shift factor is found as Arrhenius (or its first-order twin)
    ea = 8e4
    a_t = np.exp(ea / laws.R_GAS * (1 / (temps + 273.15) - 1 / 293.15))
    t = laws.find_law("covariate_shift", cov_t, "shift", ("shift",), temps, a_t, 1e-3 * a_t)
    assert t.law in ("arrhenius", "exponential", "power")
    if t.law == "arrhenius":
        assert t.chosen.theta[0] == pytest.approx(ea, rel=0.02)


def test_log_factor_is_one_at_the_reference_and_free_follows_the_level_index():
    cov = level_cov()
    for law in laws.SMOOTH[:5]:
        theta = [0.1, 1.5][:laws.n_params(law, cov)]
        assert laws.log_factor(law, theta, np.array([cov.x0]), cov)[0] == pytest.approx(0.0)
    f = laws.log_factor("free", [2.0, 3.0, 4.0, 5.0], LEVELS, cov)
    np.testing.assert_allclose(np.exp(f), [2.0, 3.0, 1.0, 4.0, 5.0])
    # many parameter vectors at once broadcast against the points
    many = laws.log_factor("power", [np.array([[0.5], [1.0]])], LEVELS, cov)
    assert many.shape == (2, LEVELS.size)


def _fit(names_values):
    est = tuple(Estimate(n, "-", v, 0.01) for n, v in names_values)
    return ModelFit("m", "amplitude_dependence", "force_n, law", est, len(est),
                    np.zeros(3), np.zeros(3), 0.1, 0.1, 0.1, 1.0, 1.0, 10, 5, True, 1)


def test_a_law_that_makes_a_stiffness_negative_in_the_measured_range_is_implausible():
    cov = level_cov()
    part = laws.LawPart("mode 1 stiffness", "linear", ("k1.s",))
    model = laws.LawModel("amplitude_dependence", cov, (part,))
    assert model.implausible(_fit([("k1.s", 0.01)])) == ""
    why = model.implausible(_fit([("k1.s", -0.2)]))  # 1 - 0.2 (20 - 6.3) < 0
    assert "not a positive factor" in why and "mode 1 stiffness" in why
    text = model.describe(_fit([("k1.s", 0.01)]))
    assert text.startswith("amplitude_dependence (force_n): mode 1 stiffness ~ 1 + s")


def test_param_specs_keep_a_linear_factor_positive_over_the_range():
    cov = level_cov()
    (s,) = laws.param_specs("linear", cov, [0.0], "k1")
    assert 1 + s.lower * (cov.hi - cov.x0) > 0 and 1 + s.upper * (cov.lo - cov.x0) > 0
    names = [p.name for p in laws.param_specs("power_change", cov, [0.1, 2.0], "storage")]
    assert names == ["storage.d", "storage.e"]
