"""Complex modal constants (LSFD form) in the modal domain: the baseline's form chosen by the
data, the named effect ``complex_modes`` when the phase shows only after another effect, and a
delay of the channel kept apart from them."""
import numpy as np
import pytest

from dva_offline.discrepancy import loop
from dva_offline.discrepancy.modal_domain import ModalDomain
from dva_offline.isolator.frf_data import FrfData


def modes_frf(f, fr, zr, a, b):
    """Receptance of modes with modal constants a_r + j (w / w_r) b_r (pole pairs)."""
    w = 2 * np.pi * np.asarray(f, float)
    h = np.zeros(w.size, complex)
    for f_r, z_r, a_r, b_r in zip(fr, zr, a, b):
        wr = 2 * np.pi * f_r
        h += (a_r + 1j * b_r * w / wr) / (wr**2 - w**2 + 2j * z_r * wr * w)
    return h


def noisy(h, sigma, rng):
    return h * (1 + sigma / np.sqrt(2) * (rng.standard_normal(h.size)
                                          + 1j * rng.standard_normal(h.size)))


def test_the_lsfd_form_has_a_real_impulse_response():
    # H(-w) = conj(H(w)) for a_r + j (w / w_r) b_r: the pole-pair form of EMA tools
    f = np.linspace(1.0, 50.0, 30)
    h = modes_frf(f, [20.0], [0.02], [1.0], [0.3])
    h_neg = modes_frf(-f, [20.0], [0.02], [1.0], [0.3])
    np.testing.assert_allclose(h_neg, np.conj(h), rtol=1e-12)


def non_proportional(seed, sigma=0.005):
    rng = np.random.default_rng(seed)
    f = np.linspace(10.0, 120.0, 240)
    # phases of 0.25-0.45 rad at resonance: non-proportional damping
    h = modes_frf(f, [30.0, 55.0, 90.0], [0.02, 0.015, 0.02], [1.0, -0.6, 0.8],
                  [0.4, 0.15, -0.35])
    return FrfData(f, noisy(h, sigma, rng), "receptance", {}), sigma


def test_non_proportional_modes_get_complex_constants_in_the_baseline():
    data, sigma = non_proportional(1)
    dom = ModalDomain([data])
    res = loop.run(dom, rule=loop.DecisionRule(max_steps=2))
    assert dom.complex_constants and dom.baseline_order == 3
    assert res.baseline.name == "modal(N=3, complex)"
    assert "complex modal constants" in dom.constants_reason
    assert res.verdict.status == "consistent" and not res.steps
    assert res.baseline.error == pytest.approx(sigma, rel=0.3)
    # the imaginary parts B_r / A_r at resonance are the generator's phases
    p = {e.name: e.value for e in res.baseline.estimates}
    np.testing.assert_allclose([p["B_1"] / p["A_1"], p["B_2"] / p["A_2"], p["B_3"] / p["A_3"]],
                               [0.4, -0.25, -0.4375], atol=0.03)


def test_real_constants_asked_for_leave_the_phase_to_the_named_effect():
    data, sigma = non_proportional(2)
    dom = ModalDomain([data], constants="real", modes=3)
    res = loop.run(dom, rule=loop.DecisionRule(max_steps=2))
    assert not dom.complex_constants
    assert res.steps and res.steps[0].effect == "complex_modes"
    assert res.verdict.status == "explained" and res.verdict.effect == "complex_modes"
    assert res.steps[0].error_after < 1.3 * sigma < 0.5 * res.baseline.error
    delay = next(c for c in res.candidates if c.effect == "sensor_delay")
    assert delay.fit.error > 2 * res.steps[0].error_after  # a delay does not make this phase


def test_a_delay_of_the_channel_is_not_taken_for_complex_constants():
    """To first order a delay is a set of complex constants (B_r = -w_r tau A_r): complex
    constants would absorb it. The baseline stays real when one delay explains the phase,
    and the loop names the delay."""
    rng = np.random.default_rng(3)
    f = np.linspace(5.0, 200.0, 300)
    tau = 4e-4
    h = modes_frf(f, [25.0, 70.0, 140.0], [0.02, 0.02, 0.015], [1.0, 0.7, -0.5], [0, 0, 0])
    data = FrfData(f, noisy(h * np.exp(-2j * np.pi * f * tau), 0.005, rng), "receptance", {})
    dom = ModalDomain([data])
    res = loop.run(dom, rule=loop.DecisionRule(max_steps=1))
    assert not dom.complex_constants and dom.baseline_order == 3
    assert "one delay of the channel explains the phase" in dom.constants_reason
    assert (res.verdict.status, res.verdict.effect) == ("explained", "sensor_delay")
    tau_fit = next(e for e in res.augmented.added if e.name == "tau")
    assert tau_fit.value == pytest.approx(tau, abs=3 * tau_fit.std + 1e-6)


def test_one_mode_at_four_drive_levels_with_a_complex_constant():
    """A resonator driven at four levels in a band of a few bandwidths (the issue's stepped
    sine): damping growing with the level and a modal constant turned by 0.4 rad. The phase
    goes into complex constants, not into a delay, and the level law reaches the noise."""
    rng = np.random.default_rng(1)
    f = np.linspace(41.85, 42.15, 41)
    conds = []
    for lev in (1.0, 2.0, 4.0, 8.0):
        a = np.exp(0.4j)
        h = modes_frf(f, [42.0 * (1 - 0.0005 * np.log(lev))], [0.001 * (1 + 0.4 * np.log(lev))],
                      [a.real], [a.imag])
        drive = lev * (1 + 0.01 * rng.standard_normal(f.size))
        conds.append(FrfData(f, noisy(h, 0.005, rng), "receptance", {"drive_v": drive}))
    dom = ModalDomain(conds, covariates=["drive_v"])
    res = loop.run(dom)
    assert dom.complex_constants
    assert (res.verdict.status, res.verdict.effect) == ("explained", "amplitude_dependence")
    assert all(s.effect != "sensor_delay" for s in res.steps)
    assert res.final.status == "consistent"
