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
