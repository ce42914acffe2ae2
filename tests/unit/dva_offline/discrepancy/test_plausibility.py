"""Plausibility before a name (plausibility.py): a delay that is a phase wrap, a shift the
sweeps cannot determine, are listed as implausible and never added."""
from dataclasses import replace

import numpy as np
import pytest

from dva_offline.discrepancy import loop, plausibility, synthetic
from dva_offline.discrepancy.fitting import ModelSpec, fit_model, holdout_split
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.isolator.frf_data import split_conditions

F_MODE = 42.0


class OneMode:
    """One mode measured in a band of ``width`` Hz around it; library: a delay with the
    bounds and starts of the structure domain's (up to 2 / f_max)."""

    name = "one-mode"

    def __init__(self, y, f):
        self.f = f
        self.observations = loop.Observations(y, 1 / np.abs(y), f, np.zeros(f.size, int))

    def mode(self, v):
        w, wr = 2 * np.pi * self.f, 2 * np.pi * v[0]
        return v[2] / (wr**2 - w**2 + 2j * v[1] * wr * w)

    def params(self):
        return (loop.ParamSpec("f_1", "Hz", F_MODE, 30.0, 60.0, log=True),
                loop.ParamSpec("zeta_1", "-", 0.002, 1e-4, 0.5, log=True),
                loop.ParamSpec("A_1", "1/kg", 1.0, -np.inf, np.inf, scale=1.0))

    def baseline(self, train):
        return loop.ModelSpec("mode", None, self.params(), 0, self.mode)

    def candidates(self, baseline, features):
        start = np.array([e.value for e in baseline.estimates])
        f_max = float(self.f.max())
        lo, hi = -0.5 / f_max, 2.0 / f_max

        def delayed(v):
            return self.mode(v) * np.exp(-2j * np.pi * self.f * v[3])

        params = self.params() + (loop.ParamSpec("tau", "s", 0.0, lo, hi, scale=0.1 / f_max),)
        return [ModelSpec("mode + delay", "sensor_delay", params, 1, delayed,
                          tuple(np.r_[start, t] for t in np.linspace(lo, hi, 21)[1:-1]))]


def one_mode_data(f, phase_deg=0.0, tau=0.0, sigma=0.005, seed=0):
    rng = np.random.default_rng(seed)
    w, wr = 2 * np.pi * f, 2 * np.pi * F_MODE
    h = np.exp(1j * np.radians(phase_deg)) / (wr**2 - w**2 + 2j * 0.002 * wr * w)
    h = h * np.exp(-1j * w * tau)
    return h * (1 + sigma / np.sqrt(2) * (rng.standard_normal(f.size)
                                          + 1j * rng.standard_normal(f.size)))


def test_a_phase_in_a_narrow_band_is_no_delay():
    """The issue's beam: a phase on a 42 Hz mode in a 0.3 Hz band; a delay of tens of ms
    matches it through phase wraps. It is listed implausible, never added."""
    f = np.linspace(F_MODE - 0.15, F_MODE + 0.15, 160)
    res = loop.run(OneMode(one_mode_data(f, phase_deg=35.0), f))
    delay = next(c for c in res.candidates if c.effect == "sensor_delay")
    assert delay.implausible and not delay.applicable
    assert delay.reason.startswith("implausible: a constant phase offset fits")
    assert delay.fit.error < 0.5 * res.baseline.error  # it would have "explained" the phase
    # its standard error says what the band leaves of it: the slope shows no delay
    tau = delay.fit.added[0]
    assert tau.std >= 0.3 * abs(tau.value) and "slope alone shows" in delay.reason
    assert res.verdict.effect is None and not res.steps
    assert "listed implausible, never added: sensor_delay" in res.verdict.evidence


def test_a_delay_across_a_wide_band_is_plausible():
    f = np.linspace(30.0, 60.0, 300)
    dom = OneMode(one_mode_data(f, tau=0.002), f)
    res = loop.run(dom)
    assert res.verdict.status == "explained" and res.verdict.effect == "sensor_delay"
    assert res.augmented.value("tau") == pytest.approx(0.002, abs=1e-4)
    # the check itself, on the named fit: a constant phase does not do as well
    spec = dom.candidates(res.baseline, res.residual)[0]
    why, fit = plausibility.delay_check(spec, res.augmented, dom.observations, res.split)
    assert why == "" and fit is res.augmented


def test_a_shift_larger_than_the_sweeps_overlap_is_implausible():
    case = synthetic.generate_case("covariate_shift", np.random.default_rng(7), n_points=60)
    conds = split_conditions(case.frequency_hz, case.values, case.quantity, case.covariates,
                             list(case.condition_columns))
    dom = FrfDomain(conds, mass=case.mass, static_stiffness=case.static_stiffness)
    split = holdout_split(dom.observations.groups)
    base = fit_model(dom.baseline(split.train), dom.observations, split)
    lib = dom.candidates(base, loop._features(dom.observations, base))
    wlf = next(s for s in lib if isinstance(s, ModelSpec) and s.label == "temperature_c, WLF")
    fit = fit_model(wlf, dom.observations, split)
    assert dom.implausible(wlf, fit) == ""
    # a slope of 0.5 /K shifts sweeps 12-15 K apart by ~5 decades: a 2-decade band cannot
    b = next(i for i, e in enumerate(fit.estimates) if e.name == "b")
    far = replace(fit, estimates=tuple(replace(e, value=0.5) if i == b else e
                                       for i, e in enumerate(fit.estimates)))
    why = dom.implausible(wlf, far)
    assert "more than the sweeps span" in why and "temperature_c" in why
