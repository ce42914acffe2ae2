"""Residual characterisation: noise floor, whiteness, localisation, phase trend, covariates."""
import numpy as np
import pytest

from dva_offline.discrepancy import residual as rs


def complex_noise(rng, n, sigma):
    return sigma / np.sqrt(2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))


def test_noise_floor_recovers_sigma_despite_a_smooth_error():
    rng = np.random.default_rng(1)
    f = np.geomspace(3, 300, 600)
    smooth = 0.2 * np.exp(-((np.log(f / 40)) ** 2)) * np.exp(1j * f / 50)  # 20 % model error
    for sigma in (0.005, 0.02):
        est = rs.noise_floor(smooth + complex_noise(rng, f.size, sigma)).sigma
        assert est == pytest.approx(sigma, rel=0.12)


def test_noise_floor_differences_stay_within_groups():
    rng = np.random.default_rng(2)
    n = 200
    r = complex_noise(rng, 2 * n, 0.01)
    r[n:] += 5.0  # a jump between two conditions must not count as noise
    groups = np.repeat([0, 1], n)
    assert rs.noise_floor(r, groups).sigma == pytest.approx(0.01, rel=0.15)
    assert rs.noise_floor(r).sigma > rs.noise_floor(r, groups).sigma


def test_ljung_box_white_vs_smooth():
    rng = np.random.default_rng(3)
    white = complex_noise(rng, 300, 0.01)
    assert rs.ljung_box(white).p_value > 1e-3
    smooth = white + 0.02 * np.sin(np.linspace(0, 6, 300))
    test = rs.ljung_box(smooth)
    assert test.p_value < 1e-6
    assert test.lag1_autocorrelation > 0.3  # mean of real (~0.8) and imaginary (~0) parts


def test_localise_finds_the_band_of_a_narrow_error():
    rng = np.random.default_rng(4)
    f = np.geomspace(3, 300, 400)
    r = complex_noise(rng, f.size, 0.01) + 0.1 * (np.abs(np.log(f / 150)) < 0.05)
    loc = rs.localise(f, r, 0.01, n_bands=8)
    assert loc.edges[loc.peak_band] <= 150 <= loc.edges[loc.peak_band + 1]
    assert loc.concentration > 0.9


def test_phase_trend_measures_a_delay():
    rng = np.random.default_rng(5)
    f = np.geomspace(3, 300, 300)
    tau = 2e-4
    ratio = np.exp(-2j * np.pi * f * tau) * (1 + complex_noise(rng, f.size, 0.01))
    trend = rs.phase_trend(f, ratio)
    assert trend.equivalent_delay_s == pytest.approx(tau, rel=0.03)
    assert abs(trend.log_magnitude_slope) < 5 * trend.log_magnitude_slope_std + 1e-6


def test_covariate_dependence_detects_level_effect_only_when_present():
    rng = np.random.default_rng(6)
    f = np.tile(np.geomspace(3, 300, 200), 3)
    level = np.repeat([1.0, 2.0, 4.0], 200)
    noise = complex_noise(rng, f.size, 0.01)
    indep = rs.covariate_dependence("level", level, f, noise + 0.05)  # same error at all levels
    assert indep.p_value > 1e-3
    dep = rs.covariate_dependence("level", level, f, noise + 0.03 * np.log(level))
    assert dep.p_value < 1e-10
    assert dep.explained_fraction > 0.25  # level-by-band share of all residual power (0.35)


def test_characterise_reports_all_parts():
    rng = np.random.default_rng(7)
    f = np.geomspace(3, 300, 300)
    r = complex_noise(rng, f.size, 0.01)
    feats = rs.characterise(f, r, ratio=1 + r, covariates={})
    assert feats.noise.sigma == pytest.approx(0.01, rel=0.15)
    assert feats.phase is not None and feats.covariates == ()
    assert feats.rms == pytest.approx(np.sqrt(np.mean(np.abs(r) ** 2)))


@pytest.mark.parametrize("call", [
    lambda: rs.noise_floor([1.0, 2.0]),
    lambda: rs.noise_floor(np.ones(5), groups=np.zeros(4)),
    lambda: rs.ljung_box(np.ones(20), lags=0),
    lambda: rs.localise(np.arange(5.0), np.ones(5), -1.0),
    lambda: rs.localise(np.arange(5.0), np.ones(5), 0.1),  # 0 Hz on a log axis
    lambda: rs.phase_trend(np.arange(5.0), np.zeros(5)),
])
def test_bad_inputs_raise_value_error(call):
    with pytest.raises(ValueError):
        call()
