"""The generic loop on a toy domain (no isolator): split, fits, scores, verdicts."""
import numpy as np
import pytest

from dva_offline.discrepancy import loop as eg

X = np.linspace(0.5, 20.0, 240)  # axis, e.g. rad/s


class ToyDomain:
    """y = 1 / (1 + j x p); library: a delay exp(-j x tau) and a gain drift (1 + g x)."""

    name = "toy"

    def __init__(self, y):
        self.observations = eg.Observations(y, 1 / np.abs(y), X, np.zeros(X.size, int))

    def baseline(self, train):
        return eg.ModelSpec("first-order", None, (eg.ParamSpec("p", "s", 0.3, 1e-3, 1e3,
                                                                log=True),),
                            0, lambda v: 1 / (1 + 1j * X * v[0]))

    def candidates(self, baseline, features):
        p = eg.ParamSpec("p", "s", baseline.value("p"), 1e-3, 1e3, log=True)
        return [
            eg.ModelSpec("first-order + delay", "sensor_delay",
                         (p, eg.ParamSpec("tau", "s", 0.0, -1.0, 1.0, scale=0.01)), 1,
                         lambda v: np.exp(-1j * X * v[1]) / (1 + 1j * X * v[0]),
                         starts=tuple(np.array([p.initial, t]) for t in (0.01, 0.05, 0.1))),
            eg.ModelSpec("first-order + drift", "parameter_drift",
                         (p, eg.ParamSpec("g", "s", 0.0, -0.04, 1.0, scale=0.01)), 1,
                         lambda v: (1 + v[1] * X) / (1 + 1j * X * v[0])),
            eg.NotApplicable("cubic_stiffness", "needs several excitation levels"),
        ]


def data(rng, tau=0.0, ripple=0.0, sigma=0.01):
    h = np.exp(-1j * X * tau) / (1 + 1j * X * 0.2) * (1 + ripple * np.sin(3 * X))
    eps = sigma / np.sqrt(2) * (rng.standard_normal(X.size) + 1j * rng.standard_normal(X.size))
    return h * (1 + eps)


def test_holdout_split_every_kth_and_random():
    groups = np.repeat([0, 1], 40)
    split = eg.holdout_split(groups, 4)
    assert split.held.sum() == 20 and not np.any(split.held & split.train)
    assert np.all(np.nonzero(split.held[:40])[0] == np.arange(2, 40, 4))
    rnd = eg.holdout_split(groups, 4, np.random.default_rng(0))
    assert rnd.held[:40].sum() == 10 and rnd.held[40:].sum() == 10
    with pytest.raises(ValueError):
        eg.holdout_split(groups, 1)


def test_delay_is_named_and_error_drops_to_noise():
    res = eg.run(ToyDomain(data(np.random.default_rng(0), tau=0.03)))
    assert res.verdict.status == "explained" and res.verdict.effect == "sensor_delay"
    assert res.augmented.value("tau") == pytest.approx(0.03, abs=4 * res.augmented.added[0].std)
    assert res.augmented.added[0].std < 0.003
    assert res.augmented.error < 0.5 * res.baseline.error
    assert res.augmented.error < 1.3 * res.noise.sigma
    assert [c.effect for c in res.candidates][-1] == "cubic_stiffness"  # not applicable last
    assert not res.candidates[-1].applicable


def test_clean_data_is_consistent():
    res = eg.run(ToyDomain(data(np.random.default_rng(1))))
    assert res.verdict.status == "consistent"
    assert res.verdict.effect is None and res.augmented is None
    assert res.baseline.error == pytest.approx(0.01, rel=0.25)


def test_effect_outside_library_is_unexplained():
    res = eg.run(ToyDomain(data(np.random.default_rng(2), ripple=0.05)))
    assert res.verdict.status == "unexplained"
    assert res.verdict.effect is None


def test_error_definition_is_held_out_relative_rms():
    y = data(np.random.default_rng(3), tau=0.02)
    dom = ToyDomain(y)
    res = eg.run(dom)
    held = res.split.held
    pred = res.baseline.prediction
    expected = np.sqrt(np.mean(np.abs(pred[held] - y[held]) ** 2 / np.abs(y[held]) ** 2))
    assert res.baseline.error == pytest.approx(expected)
    # the fit never saw the held-out points: changing them leaves the fit unchanged
    y2 = y.copy()
    y2[held] *= 1.5
    res2 = eg.run(ToyDomain(y2), split=res.split)
    assert res2.baseline.value("p") == pytest.approx(res.baseline.value("p"), rel=1e-9)


def test_model_spec_validation():
    with pytest.raises(ValueError):
        eg.ModelSpec("x", "no_such_effect", (), 0, lambda v: v)
    with pytest.raises(ValueError):
        eg.ParamSpec("k", "N/m", 1.0, 0.0, 2.0, log=True)
    with pytest.raises(ValueError):
        eg.Observations(np.ones(20), -np.ones(20), np.arange(20.0), np.zeros(20, int))


class StackingToyDomain(ToyDomain):
    """The toy with effects that stack: the loop's later steps start from the model with the
    effects added so far (delay and gain drift multiply)."""

    def __init__(self, y):
        super().__init__(y)
        self.stack = []  # effects added, in order

    def _predict(self, v, effects):
        out = 1 / (1 + 1j * X * v[0])
        for i, e in enumerate(effects):
            out = out * (np.exp(-1j * X * v[1 + i]) if e == "sensor_delay" else 1 + v[1 + i] * X)
        return out

    def candidates(self, baseline, features):
        values = [e.value for e in baseline.estimates]
        params = [eg.ParamSpec("p", "s", values[0], 1e-3, 1e3, log=True)]
        params += [eg.ParamSpec(f"x{i}", "-", values[1 + i], -1.0, 1.0, scale=0.01)
                   for i in range(len(self.stack))]
        out = []
        for effect, spec in (("sensor_delay", eg.ParamSpec("tau", "s", 0.0, -1.0, 1.0,
                                                            scale=0.01)),
                             ("parameter_drift", eg.ParamSpec("g", "s", 0.0, -0.04, 1.0,
                                                               scale=0.01))):
            if effect in self.stack:
                continue
            effects = [*self.stack, effect]
            out.append(eg.ModelSpec(
                effect, effect, (*params, spec), 1,
                lambda v, effects=effects: self._predict(v, effects),
                starts=tuple(np.array([*values, t]) for t in (0.01, 0.05, 0.1, -0.02))))
        return out

    def augment(self, spec, fit):
        self.stack.append(spec.effect)


def test_loop_adds_two_effects_in_turn_until_the_noise():
    rng = np.random.default_rng(4)
    h = np.exp(-1j * X * 0.03) * (1 + 0.02 * X) / (1 + 1j * X * 0.2)
    eps = 0.01 / np.sqrt(2) * (rng.standard_normal(X.size) + 1j * rng.standard_normal(X.size))
    res = eg.run(StackingToyDomain(h * (1 + eps)))
    assert [s.effect for s in res.steps] == ["sensor_delay", "parameter_drift"] or \
        [s.effect for s in res.steps] == ["parameter_drift", "sensor_delay"]
    assert res.final.status == "consistent"
    assert res.final.error < 1.25 * res.final.noise
    assert res.verdict.status == "explained" and res.verdict.effect == res.steps[0].effect
    for a, b in zip(res.steps, res.steps[1:]):
        assert b.error_before == pytest.approx(a.error_after)
    assert res.steps[-1].error_after < 0.5 * res.baseline.error


def test_a_fit_on_its_bound_is_reported_with_its_meaning():
    rng = np.random.default_rng(5)
    h = (1 - 0.045 * X) / (1 + 1j * X * 0.2)  # needs g = -0.045, below the bound -0.04
    eps = 0.002 / np.sqrt(2) * (rng.standard_normal(X.size) + 1j * rng.standard_normal(X.size))
    res = eg.run(ToyDomain(h * (1 + eps)))
    drift = next(c for c in res.candidates if c.effect == "parameter_drift")
    hits = [h for h in drift.fit.bound_hits if h.added]
    assert len(hits) == 1 and hits[0].name == "g" and hits[0].side == "lower"
    assert hits[0].bound == pytest.approx(-0.04)
    assert "beyond its lower bound" in hits[0].meaning
    assert np.isnan(drift.fit.added[0].std)  # no standard error at a bound
    if res.verdict.effect == "parameter_drift":
        assert res.verdict.caveats and "bound" in res.verdict.evidence


class FailingCandidateDomain(ToyDomain):
    """The toy library plus a candidate whose model is not finite anywhere and one whose only
    start has no image in its bounds (a log parameter started at a negative value, as an
    informed start from a negative static modulus)."""

    def candidates(self, baseline, features):
        p = eg.ParamSpec("p", "s", baseline.value("p"), 1e-3, 1e3, log=True)
        never_finite = eg.ModelSpec(
            "first-order + mass", "fixture_mass",
            (p, eg.ParamSpec("dm", "kg", 0.0, -1.0, 1.0, scale=0.1)), 1,
            lambda v: np.full(X.size, np.nan + 0j))
        bad_start = eg.ModelSpec(
            "first-order + foundation", "foundation_mode",
            (p, eg.ParamSpec("m_f", "kg", -5.0, 1e-3, 1e3, log=True)), 1,
            lambda v: 1 / (1 + 1j * X * v[0]) * (1 + 0 * v[1]))
        return [*super().candidates(baseline, features), never_finite, bad_start]


def test_a_failing_candidate_is_listed_and_the_loop_goes_on():
    res = eg.run(FailingCandidateDomain(data(np.random.default_rng(0), tau=0.03)))
    assert res.verdict.status == "explained" and res.verdict.effect == "sensor_delay"
    failed = [c for c in res.candidates if c.failed]
    assert [c.effect for c in failed] == ["fixture_mass", "foundation_mode"]
    assert all(c.reason.startswith("failed: ") and not c.applicable for c in failed)
    assert "no start inside the parameter bounds" in failed[1].reason


def test_a_start_outside_the_bounds_is_replaced_by_a_valid_one():
    y = data(np.random.default_rng(3))
    obs = eg.Observations(y, 1 / np.abs(y), X, np.zeros(X.size, int))
    split = eg.holdout_split(obs.groups)
    spec = eg.ModelSpec("first-order", None,
                        (eg.ParamSpec("p", "s", -0.3, 1e-3, 1e3, log=True),), 0,
                        lambda v: 1 / (1 + 1j * X * v[0]), starts=(np.array([0.5]),))
    fit = eg.fit_model(spec, obs, split)
    assert fit.value("p") == pytest.approx(0.2, rel=0.02)
    only_bad = eg.ModelSpec("first-order", None, spec.params, 0, spec.predict)
    with pytest.raises(ValueError, match="no start inside the parameter bounds"):
        eg.fit_model(only_bad, obs, split)


class LevelToyDomain(ToyDomain):
    """Three conditions; a candidate whose pole moves with the level by a log law, which the
    data follow only in part (the rest is a level-dependent ripple no candidate has)."""

    def __init__(self, y, level):
        n = X.size
        groups = np.repeat([0, 1, 2], n)
        self.level = level
        self.observations = eg.Observations(y, 1 / np.abs(y), np.tile(X, 3), groups,
                                            {"force_n": level})
        self.x = np.tile(X, 3)

    def baseline(self, train):
        x = self.x
        return eg.ModelSpec("first-order", None, (eg.ParamSpec("p", "s", 0.3, 1e-3, 1e3,
                                                                log=True),),
                            0, lambda v: 1 / (1 + 1j * x * v[0]))

    def candidates(self, baseline, features):
        x, lev = self.x, np.log(self.level / 5.0)
        p = eg.ParamSpec("p", "s", baseline.value("p"), 1e-3, 1e3, log=True)
        return [eg.ModelSpec("first-order + level", "amplitude_dependence",
                             (p, eg.ParamSpec("s", "-", 0.0, -0.5, 0.5, scale=0.01)), 1,
                             lambda v: 1 / (1 + 1j * x * v[0] * (1 + v[1] * lev)),
                             label="force_n")]


def test_saturated_reference_lets_a_covariate_effect_explain_what_the_data_allow():
    rng = np.random.default_rng(4)
    level = np.repeat([1.0, 5.0, 25.0], X.size)
    x = np.tile(X, 3)
    lev = np.log(level / 5.0)
    ripple = 0.08 * np.sin(3 * x) * (level > 10)  # level-dependent, no candidate has it
    h = 1 / (1 + 1j * x * 0.2 * (1 + 0.05 * lev)) * (1 + ripple)
    eps = 0.005 / np.sqrt(2) * (rng.standard_normal(x.size) + 1j * rng.standard_normal(x.size))
    res = eg.run(LevelToyDomain(h * (1 + eps), level))
    ref = res.reference
    assert ref is not None and ref.n_fitted == 3 and res.reference_used
    assert ref.error < 0.8 * res.baseline.error and ref.error > 2 * res.noise.sigma
    cand = next(c for c in res.candidates if c.effect == "amplitude_dependence")
    assert cand.explained_fraction < 0.9 <= cand.achieved_fraction
    assert res.verdict.status == "explained" and res.verdict.effect == "amplitude_dependence"


def test_saturated_reference_is_not_used_when_the_levels_do_not_differ():
    rng = np.random.default_rng(5)
    level = np.repeat([1.0, 5.0, 25.0], X.size)
    x = np.tile(X, 3)
    h = 1 / (1 + 1j * x * 0.2) * (1 + 0.02 * np.sin(3 * x))  # same at every level
    eps = 0.005 / np.sqrt(2) * (rng.standard_normal(x.size) + 1j * rng.standard_normal(x.size))
    res = eg.run(LevelToyDomain(h * (1 + eps), level))
    assert res.reference is not None and not res.reference_used
    assert all(np.isnan(c.achieved_fraction) for c in res.candidates)
    assert res.verdict.status != "explained"
