"""The marching flutter search against a fine bisection and against the previous grid search."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.aerodynamics import QuasiSteadyAero, WagnerAero
from aero_dva.wing.flutter import NoFlutterError, flutter_speed, grid_flutter_speed
from aero_dva.wing.flutter_march import ModeSample, march_to_instability
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

RHO = 1.2


@pytest.fixture(scope="module")
def cfg():
    return load_wing()


def _eigenvalues(model, u):
    a0, a1, a2 = model.polynomial(RHO)
    return np.linalg.eigvals(a0 + np.multiply.outer(u, a1) + np.multiply.outer(u * u, a2))


def _fine_bisection(model, high, n=2001):
    """First zero crossing of the largest real part on an n-point grid over (0, high), then
    bisection to 1e-13. The grid ignores eigenvalues below 1e-7 (neutral ones); the bisection
    only those below 1e-12, so a real mode crossing zero (divergence) is followed through."""
    u = np.linspace(0.0, high, n)
    lam = _eigenvalues(model, u)
    growth = np.where(np.abs(lam) < 1e-7, -np.inf, lam.real).max(axis=1)
    above = np.flatnonzero(growth > 1e-9 * np.abs(lam).max())
    if above.size == 0:
        return None, u, lam
    a, b = u[above[0] - 1], u[above[0]]
    while b - a > 1e-13 * b:
        m = 0.5 * (a + b)
        lm = _eigenvalues(model, m)
        if lm[np.abs(lm) > 1e-12].real.max() > 0:
            b = m
        else:
            a = m
    return 0.5 * (a + b), u, lam


def _random_wing(cfg, rng):
    w = cfg.wing
    wing = w.replace(
        mass=w.mass * rng.uniform(0.6, 1.5), inertia=w.inertia * rng.uniform(0.6, 1.5),
        plunge_stiffness=w.plunge_stiffness * rng.uniform(0.4, 2.5),
        pitch_stiffness=w.pitch_stiffness * rng.uniform(0.4, 2.5),
        damping_factor=w.damping_factor * rng.uniform(0.0, 2.0),
        elastic_axis=rng.uniform(w.trailing_edge, w.leading_edge))
    dva = MaxwellAbsorber(
        mass=40.0 * rng.uniform(0.3, 3.0), stiffness=9e4 * rng.uniform(0.2, 5.0),
        series_stiffness=7e4 * rng.uniform(0.2, 5.0), damping=10 ** rng.uniform(0.0, 4.5),
        position=rng.uniform(wing.trailing_edge, wing.leading_edge))
    aero = QuasiSteadyAero() if rng.uniform() < 0.7 else WagnerAero()
    return AeroelasticModel(wing, dva, aero)


def test_random_wings_equal_a_fine_bisection(cfg):
    """Random physical wings with a Maxwell DVA (seed 2026): flutter and divergence alike."""
    rng = np.random.default_rng(2026)
    kinds = set()
    for _ in range(8):
        model = _random_wing(cfg, rng)
        ref, _, _ = _fine_bisection(model, 600.0)
        res = flutter_speed(model, RHO)
        assert ref is not None
        assert res.critical_airspeed == pytest.approx(ref, rel=1e-9)
        kinds.add(res.kind)
    assert kinds == {"flutter", "divergence"}  # both roots are exercised


def test_chapter6_wing_with_its_dva_switches_critical_mode_before_flutter(cfg):
    model = AeroelasticModel(cfg.wing, cfg.maxwell_design)
    ref, u, lam = _fine_bisection(model, 150.0)
    res = flutter_speed(model, RHO)
    assert res.critical_airspeed == pytest.approx(ref, rel=1e-9)
    assert res.critical_airspeed == pytest.approx(
        grid_flutter_speed(model, RHO).critical_airspeed, rel=1e-9)
    assert res.kind == "flutter"
    # The least damped mode below U_cr is not one mode throughout: its frequency jumps twice
    # (steps of a followed mode on this grid stay below 0.1 rad/s), the last time to the
    # flutter mode.
    below = u < res.critical_airspeed
    crit = np.take_along_axis(lam[below], lam[below].real.argmax(axis=1)[:, None], 1)[:, 0]
    freq = np.abs(crit.imag)
    assert np.count_nonzero(np.abs(np.diff(freq)) > 5.0) == 2
    assert abs(freq[-1] - 2 * np.pi * res.flutter_frequency) < 0.01 * freq[-1]


def test_no_flutter_in_range_agrees_with_the_fine_grid(cfg):
    model = AeroelasticModel(cfg.wing, cfg.maxwell_design)
    u_cr = flutter_speed(model, RHO).critical_airspeed
    ref, _, _ = _fine_bisection(model, 0.99 * u_cr)
    assert ref is None  # the fine grid sees no instability below 0.99 U_cr either
    with pytest.raises(NoFlutterError, match=r"no flutter or divergence between 0 and 1"):
        flutter_speed(model, RHO, (0.0, 0.99 * u_cr))
    # Without a damper the DVA's mode is undamped at every airspeed: neutral, never unstable.
    stiff = AeroelasticModel(cfg.wing.replace(pitch_stiffness=cfg.wing.pitch_stiffness * 1e6,
                                              plunge_stiffness=cfg.wing.plunge_stiffness * 1e6))
    with pytest.raises(NoFlutterError, match=r"below 100000 m/s"):
        flutter_speed(stiff, RHO)


def _absorbers(cfg):
    yield "bare", None
    yield "passive", PassiveAbsorber(40.0, 9.156e4, 860.0, cfg.wing.leading_edge)
    for c2 in (0.0, 1e-6, 500.0, 2500.0, np.inf):
        yield f"maxwell c2={c2:g}", cfg.maxwell_design.replace(damping=c2)


@pytest.mark.parametrize("aero", [QuasiSteadyAero(), WagnerAero()], ids=["qs", "wagner"])
def test_march_equals_the_grid_search(cfg, aero):
    """The cases of the Newton-versus-Brent test: the same answer as the grid search."""
    for name, absorber in _absorbers(cfg):
        model = AeroelasticModel(cfg.wing, absorber, aero)
        for rho in (0.6, 1.2):
            new, old = flutter_speed(model, rho), grid_flutter_speed(model, rho)
            assert new.critical_airspeed == pytest.approx(old.critical_airspeed, rel=1e-9), name
            assert new.flutter_frequency == pytest.approx(old.flutter_frequency, rel=1e-8), name
            assert new.kind == old.kind, name
        for span in ((20.0, 300.0), (0.0, 1000.0)):
            new, old = flutter_speed(model, 1.2, span), grid_flutter_speed(model, 1.2, span)
            assert new.critical_airspeed == pytest.approx(old.critical_airspeed, rel=1e-9), name


class _Modes:
    """Two modes given as functions (real part, slope): a falling one and ``f``."""

    def __init__(self, f, df):
        self.f, self.df, self.airspeeds = f, df, []

    def sample(self, u):
        self.airspeeds.append(u)
        real, slope = [-1.0 - 0.1 * u, self.f(u)], [-0.1, self.df(u)]
        c = int(np.argmax(real))
        return ModeSample(u, real[c], complex(real[c], 5.0), complex(slope[c]), real, slope)


@pytest.mark.parametrize("width", [0.2, 1e-3, 1e-6])
def test_a_concave_hump_narrower_than_a_step_is_found(width):
    """A mode above zero only within 1.1 +- width, between samples 0.5 apart."""
    k = 1e-3 / width**2
    modes = _Modes(lambda u: 1e-3 - k * (u - 1.1) ** 2, lambda u: -2.0 * k * (u - 1.1))
    a, b = march_to_instability(modes, 0.0, 2.0, lambda u: 0.5, True, 2e-9)
    assert a.growth < 0 < b.growth
    assert a.airspeed < 1.1 + width and b.airspeed > 1.1 - width
    assert len(modes.airspeeds) < 30


def test_a_bump_its_tangents_do_not_show_is_found_at_the_growth_maximum():
    """The excursion of the grid search's test (a narrow bump on a concave mode): the
    tangents at the samples are the broad mode's, the maximum between them is searched."""
    bump = lambda u: np.exp(-(((u - 1.05) / 0.01) ** 2))  # noqa: E731
    modes = _Modes(lambda u: -0.05 - 0.1 * (u - 1.05) ** 2 + 0.06 * bump(u),
                   lambda u: -0.2 * (u - 1.05) - 0.06 * bump(u) * 2 * (u - 1.05) / 0.01**2)
    a, b = march_to_instability(modes, 0.0, 2.0, lambda u: 0.1, True, 2e-9)
    assert a.growth < 0 < b.growth and 0.99 < a.airspeed < 1.05 <= b.airspeed <= 1.1
    # A stable mode stays stable: the march ends at the range's end.
    modes = _Modes(lambda u: -0.05 - 0.1 * (u - 1.05) ** 2, lambda u: -0.2 * (u - 1.05))
    assert march_to_instability(modes, 0.0, 2.0, lambda u: 0.1, True, 2e-9) is None
    assert modes.airspeeds[-1] == 2.0


def test_the_searchs_polynomial_equals_the_checked_one(cfg):
    """``polynomial_unchecked`` (plain-Python features, one product) against ``polynomial``
    and against the assembly at an airspeed, for every kind of damper setting."""
    u = 83.0
    for name, absorber in _absorbers(cfg):
        for aero in (QuasiSteadyAero(), WagnerAero()):
            model = AeroelasticModel(cfg.wing, absorber, aero)
            for c in ((None,) if absorber is None else (None, 0.0, 1e-6, 500.0, np.inf)):
                if c == np.inf and not model.has_maxwell:
                    continue
                fast = model.polynomial_unchecked(RHO, c)
                for x, y in zip(fast, model.polynomial(RHO, c)):
                    np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-13 * np.abs(y).max())
                a, _ = model.matrices(u, RHO, c)
                np.testing.assert_allclose(fast[0] + u * fast[1] + u * u * fast[2], a,
                                           rtol=1e-12, atol=1e-12 * np.abs(a).max(), err_msg=name)


def test_the_grid_search_refuses_a_theodorsen_model(cfg):
    from aero_dva.wing.aerodynamics import TheodorsenAero

    model = AeroelasticModel(cfg.wing, cfg.maxwell_design, TheodorsenAero())
    with pytest.raises(ValueError, match="Theodorsen"):
        grid_flutter_speed(model, RHO)
