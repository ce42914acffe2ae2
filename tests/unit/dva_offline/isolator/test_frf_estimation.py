"""Chapter-5 front end: Welch H1/H2, stepped sine, zero crossing, half power, static stiffness."""
import numpy as np
import pytest
from scipy import signal

from dva_offline.isolator.frf_data import FrfData, check_units, estimate_modal, to_receptance
from dva_offline.isolator.frf_estimation import (
    estimate_frf,
    half_power_damping,
    natural_frequency_zero_crossing,
    static_stiffness_from_load_deflection,
    stepped_sine_frf,
)
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties

KN = 1e3
# Table 5.4 bubble-mount M-V model with the measured mass.
BUBBLE = MaxwellModel(1.041, 14.01 * KN, 25.81, (22.27 * KN,), (1588.57,))


def simulate_accelerance(model, force, fs):
    """Exact discrete simulation (zero-order hold) of acceleration for a force record."""
    from dva_offline.isolator.maxwell_model import state_matrix

    a = state_matrix(model)
    n = a.shape[0]
    b = np.zeros((n, 1))
    b[0, 0] = 1.0 / model.mass
    c = a[:1, :]  # acceleration = first row of x' = A x + B f
    d = b[:1, :]
    sys_d = signal.cont2discrete((a, b, c, d), 1.0 / fs, method="zoh")
    _, y, _ = signal.dlsim(sys_d[:4] + (1.0 / fs,), force)
    return y[:, 0]


def test_welch_h1_h2_recover_accelerance_with_seed_defaults():
    fs = 5000.0
    rng = np.random.default_rng(5)
    force = rng.standard_normal(int(fs * 20))
    acc = simulate_accelerance(BUBBLE, force, fs)
    noisy = np.vstack([acc + 0.02 * np.std(acc) * rng.standard_normal(acc.size) for _ in range(3)])
    est = estimate_frf(force, noisy)  # study defaults: fs 5000 Hz, nfft 10000, boxcar
    assert est.frequency_hz[1] == pytest.approx(0.5)
    band = (est.frequency_hz >= 5) & (est.frequency_hz <= 80)
    h_true = frf(BUBBLE, 2 * np.pi * est.frequency_hz[band], "accelerance")
    # ZOH sampling at 5 kHz is exact for piecewise-constant force; compare over 5-80 Hz.
    err1 = np.abs(est.h1[band] - h_true) / np.abs(h_true)
    err2 = np.abs(est.h2[band] - h_true) / np.abs(h_true)
    assert np.median(err1) < 0.05 and np.median(err2) < 0.05
    assert np.all(est.coherence[band] <= 1 + 1e-12) and np.median(est.coherence[band]) > 0.9
    # Output noise leaves H1 unbiased but biases H2 upwards: on average |H2| >= |H1|.
    assert np.mean(np.abs(est.h2[band])) >= np.mean(np.abs(est.h1[band]))


def test_stepped_sine_recovers_frf():
    fs = 5000.0
    t = np.arange(0, 2.0, 1 / fs)
    freqs = np.arange(3.0, 80.0, 7.5)
    h_true = frf(BUBBLE, 2 * np.pi * freqs, "accelerance")
    force = np.vstack([np.cos(2 * np.pi * f * t) for f in freqs])
    resp = np.vstack([np.real(h * np.exp(2j * np.pi * f * t)) + 0.3
                      for h, f in zip(h_true, freqs)])
    np.testing.assert_allclose(stepped_sine_frf(t, force, resp, freqs), h_true, rtol=1e-9)


def test_zero_crossing_and_half_power_on_voigt_model_are_exact_in_the_limit():
    model = MaxwellModel(1.0, 36.46 * KN, 3.0)
    modal = modal_properties(model)
    w = np.linspace(50, 350, 30001)
    h = frf(model, w)
    wn = natural_frequency_zero_crossing(w, h)
    assert wn == pytest.approx(np.sqrt(model.k / model.mass), rel=1e-6)
    hp = half_power_damping(w, h, wn)
    assert hp.damping_ratio == pytest.approx(modal.damping_ratio, rel=0.01)


def test_table_5_2_procedure_on_table_5_4_models():
    """Applied to the study's identified M-V models (stepped-sine grid 3-80 Hz, 0.5 Hz), the
    zero crossing / half power give Table 5.2's w_n to 1 % and zeta to its 2 printed decimals."""
    for model, (wn_t, zeta_t), fmax in (
        (BUBBLE, (187.15, 0.09), 80.0),
        (MaxwellModel(1.041, 54.51 * KN, 153.36, (267.83 * KN,), (10070.89,)), (559.29, 0.15),
         160.0),
    ):
        f = np.arange(3.0, fmax + 0.25, 0.5)
        est = estimate_modal(2 * np.pi * f, frf(model, 2 * np.pi * f))
        assert est.natural_frequency_rad_s == pytest.approx(wn_t, rel=0.01)
        assert est.damping_ratio == pytest.approx(zeta_t, abs=0.01)


def test_static_stiffness_least_squares_with_window():
    rng = np.random.default_rng(2)
    x = np.concatenate([np.arange(0, 2e-3, 0.25e-3), np.arange(2e-3, -1e-9, -0.25e-3)])
    # softening then hardening like the bubble mount, linear around x0 = 0.75 mm
    load = 14013.0 * x + 2e8 * (x - 0.75e-3) ** 3 + rng.normal(0, 0.05, x.size)
    res = static_stiffness_from_load_deflection(x, load, center_m=0.75e-3, half_width_m=0.5e-3)
    assert res.stiffness_n_per_m == pytest.approx(14013.0, rel=0.02)
    assert res.n_points == 10  # 0.25-1.25 mm, loading and unloading
    all_points = static_stiffness_from_load_deflection(x, load)
    assert abs(all_points.stiffness_n_per_m - 14013.0) > abs(res.stiffness_n_per_m - 14013.0)
    with pytest.raises(ValueError, match="two distinct"):
        static_stiffness_from_load_deflection([1e-3, 1e-3], [1.0, 2.0])


def test_frf_data_validation_and_conversion():
    f = np.linspace(1, 80, 50)
    h = frf(BUBBLE, 2 * np.pi * f, "accelerance")
    data = FrfData(f, h, "accelerance")
    w, rec = to_receptance(data, BUBBLE.mass)
    np.testing.assert_allclose(rec, frf(BUBBLE, w), rtol=1e-12)
    stiff = FrfData(f, frf(BUBBLE, 2 * np.pi * f, "stiffness"), "stiffness")
    np.testing.assert_allclose(to_receptance(stiff, BUBBLE.mass)[1], rec, rtol=1e-12)
    with pytest.raises(ValueError, match="strictly increasing"):
        FrfData(f[::-1], h, "accelerance")
    with pytest.raises(ValueError, match="too few"):
        FrfData(f[:5], h[:5], "accelerance")
    bad = h.copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match="NaN.*point 7"):
        FrfData(f, bad, "accelerance")


def test_unit_checks_catch_factor_1000():
    f = np.arange(3.0, 80.0, 0.5)
    w = 2 * np.pi * f
    rec = frf(BUBBLE, w)
    wn = modal_properties(BUBBLE).natural_frequency_rad_s
    check_units(w, rec, BUBBLE.mass, BUBBLE.k, wn)  # consistent: no error
    with pytest.raises(ValueError, match="kN/m"):
        check_units(w, rec, BUBBLE.mass, BUBBLE.k / 1000, wn)  # static stiffness in kN/m
    with pytest.raises(ValueError, match="g instead of kg"):
        check_units(w, rec, BUBBLE.mass * 1000, BUBBLE.k, wn)  # mass in g
    with pytest.raises(ValueError, match="FRF units"):
        check_units(w, rec * 1000, BUBBLE.mass, BUBBLE.k, wn)  # receptance in mm/N
