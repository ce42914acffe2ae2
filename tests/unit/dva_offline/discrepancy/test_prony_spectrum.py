"""The Prony relaxation spectrum of a material (prony_spectrum.py) and its use by the loop
(frf_spectrum.py): non-negative moduli on fixed time constants, the shift searched alone,
the shift form chosen again when the spectrum replaces the Maxwell elements."""
import numpy as np
import pytest

from dva_offline.discrepancy import loop
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.discrepancy.prony_spectrum import (
    MAX_SPAN_DECADES,
    free_shift_values,
    nonnegative_moduli,
    pairwise_shifts,
    prony_columns,
    relaxation_times,
)
from dva_offline.isolator.frf_data import FrfData


def test_relaxation_times_cover_the_span_with_the_asked_density():
    lf = np.array([-3.0, 0.5, 4.0])
    taus = relaxation_times(lf, per_decade=2.0, margin=1.0)
    corners = np.log10(1.0 / (2 * np.pi * taus))
    assert corners.max() == pytest.approx(5.0) and corners.min() == pytest.approx(-4.0)
    assert np.allclose(np.diff(np.sort(corners)), 0.5)
    wide = relaxation_times(np.array([-100.0, 100.0]), per_decade=1.0)
    assert np.ptp(np.log10(wide)) == pytest.approx(MAX_SPAN_DECADES)
    with pytest.raises(ValueError, match="per_decade"):
        relaxation_times(lf, per_decade=0.0)


def test_nonnegative_moduli_recover_a_spectrum_on_its_own_grid():
    rng = np.random.default_rng(3)
    w = 2 * np.pi * np.logspace(-2, 3, 60)
    taus = relaxation_times(np.log10(w / (2 * np.pi)), 1.0)
    true = np.zeros(taus.size + 1)
    true[[0, 3, 5, 6]] = [2e6, 5e7, 1e8, 3e7]  # Pa: sparse, spanning decades
    cols = prony_columns(w, taus)
    y = cols @ true
    x = nonnegative_moduli(cols, y, 1 / np.abs(y), np.ones(w.size, bool))
    assert np.allclose(x, true, rtol=1e-6, atol=1e-3 * true.max())
    noisy = y * (1 + 0.05 * rng.standard_normal(w.size))
    x = nonnegative_moduli(cols, noisy, 1 / np.abs(noisy), np.ones(w.size, bool))
    assert np.all(x >= 0)
    fit = cols @ x
    r2 = 1 - np.sum(np.abs(fit - noisy) ** 2) / np.sum(np.abs(noisy - noisy.mean()) ** 2)
    assert r2 > 0.99


def test_free_shift_values_keep_the_reference_condition_at_zero():
    groups = np.array([0, 0, 1, 1, 2, 2])
    assert np.array_equal(free_shift_values(groups, 1, np.array([2.0, -3.0])),
                          [2.0, 2.0, 0.0, 0.0, -3.0, -3.0])


def master_curve_sweeps(c1=8.0, c2=120.0, seed=5):
    """Storage and loss moduli of a smooth spectrum (4 elements per decade over 6 decades, as a
    real material's is continuous), measured at 0.1-100 Hz
    at five temperatures shifted by a WLF law (reference 20 C), 1 % multiplicative noise."""
    rng = np.random.default_rng(seed)
    taus = np.logspace(-6, 0, 25)
    ks = 3e7 * np.exp(-0.5 * (np.log10(taus) + 3.5) ** 2)  # Pa: a log-normal spectrum
    f = np.logspace(-1, 2, 14)
    temps = np.array([0.0, 10.0, 20.0, 30.0, 40.0])
    sweeps, truth = [], []
    for t in temps:
        log_a = -c1 * (t - 20.0) / (c2 + t - 20.0)
        s = 1j * 2 * np.pi * f[:, None] * 10**log_a * taus
        e = 2e6 + (ks * s / (1 + s)).sum(axis=1)
        noise = 0.01 / np.sqrt(2) * (rng.standard_normal(f.size)
                                     + 1j * rng.standard_normal(f.size))
        sweeps.append(FrfData(f, e * (1 + noise), "stiffness",
                              {"temperature_c": np.full(f.size, t)}))
        truth.append(log_a)
    return sweeps, temps, np.array(truth)


def test_loop_replaces_the_elements_by_a_spectrum_and_finds_the_shift():
    sweeps, temps, truth = master_curve_sweeps()
    dom = FrfDomain(sweeps, modulus=True)
    res = loop.run(dom, rule=loop.DecisionRule(max_steps=2))
    assert res.steps[0].effect == "covariate_shift"
    second = res.steps[1]
    assert second.effect == "maxwell_element" and "Prony spectrum" in second.label
    assert second.error_after < 0.5 * second.error_before
    assert second.label.endswith("WLF")  # the generator's law, re-selected over Arrhenius
    assert res.final.status == "consistent"
    shifts = dom.shift_factors(res.final.fit)
    got = np.array([r["log10_aT"] for r in shifts["per_condition"]])
    levels = np.array([r["level"] for r in shifts["per_condition"]])
    assert np.allclose(levels, temps)
    rel = (got - got[2]) - (truth - truth[2])  # both relative to 20 C
    assert np.sqrt(np.mean(rel**2)) < 0.05  # decades (0.0003 measured)
    units = {e.name: e.unit for e in res.final.fit.estimates}
    assert units["k_inf"] == "Pa"


def test_pairwise_shifts_put_neighbouring_sweeps_on_one_curve():
    """Each sweep shifted onto its neighbour: on a generated WLF master curve, the chained
    shifts are the generator's within a fraction of a decade (a start, not a result)."""
    sweeps, temps, truth = master_curve_sweeps()
    f = np.concatenate([s.frequency_hz for s in sweeps])
    mag = np.concatenate([np.abs(s.values) for s in sweeps])
    groups = np.repeat(np.arange(len(sweeps)), sweeps[0].frequency_hz.size)
    got = pairwise_shifts(np.log10(f), np.log10(mag), groups, temps[groups], reference=2)
    assert got[2] == 0.0 and np.all(np.diff(got) < 0)  # warmer: lower frequency on the curve
    assert np.max(np.abs(got - (truth - truth[2]))) < 0.5
