"""Flutter solver, modal analysis with mode tracking, and the textbook typical section."""
from __future__ import annotations

import numpy as np
import pytest

from aero_dva.wing.absorbers import PassiveAbsorber
from aero_dva.wing.aerodynamics import QuasiSteadyAero, TheodorsenAero, WagnerAero
from aero_dva.wing.flutter import (
    NoFlutterError,
    _first_bracket,
    _safeguarded_newton,
    flutter_speed,
    flutter_vs_density,
    growth_rate,
    reference_flutter_speed,
)
from aero_dva.wing.modal import modal_analysis
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.typical_section import TypicalSection, section_to_wing
from aero_dva.wing.wing_io import load_wing

# Hodges & Pierce, Introduction to Structural Dynamics and Aeroelasticity, 2nd ed. (2011),
# section 5.5, figs. 5.19-5.20 (p-k method with Theodorsen's function): a = -1/5, e = -1/10
# (x_alpha = e - a = 1/10), mu = 20, r^2 = 6/25, sigma = 2/5. The damping of the pitch-dominated
# branch crosses zero at U / (b omega_theta) ~ 2.17 on the figure's airspeed axis (read off the
# plot; AeroBeams.jl and Aeroelasticity.jl reproduce the same example at "around 2.2").
HODGES_PIERCE = TypicalSection(semichord=1.0, mass_ratio=20.0, radius_of_gyration_sq=6 / 25,
                               frequency_ratio=2 / 5, static_unbalance=0.1, elastic_axis=-0.2,
                               pitch_frequency=1.0, air_density=1.0)
HP_REDUCED_FLUTTER_SPEED = 2.17


@pytest.fixture(scope="module")
def reference():
    return load_wing()


def test_typical_section_theodorsen_matches_hodges_pierce():
    wing = section_to_wing(HODGES_PIERCE)
    res = flutter_speed(AeroelasticModel(wing, None, TheodorsenAero()), 1.0, (0.0, 4.0))
    v = res.critical_airspeed / HODGES_PIERCE.reference_speed
    assert v == pytest.approx(HP_REDUCED_FLUTTER_SPEED, rel=0.02)
    assert res.kind == "flutter"
    # Flutter frequency between the uncoupled plunge (0.4) and pitch (1.0) frequencies.
    assert 0.4 < 2 * np.pi * res.flutter_frequency < 1.0


def test_finite_state_wagner_agrees_with_theodorsen_and_quasi_steady_does_not():
    wing = section_to_wing(HODGES_PIERCE)
    wagner = flutter_speed(AeroelasticModel(wing, None, WagnerAero()), 1.0, (0.0, 4.0))
    theo = flutter_speed(AeroelasticModel(wing, None, TheodorsenAero()), 1.0, (0.0, 4.0))
    qs = flutter_speed(AeroelasticModel(wing, None, QuasiSteadyAero()), 1.0, (0.0, 4.0))
    assert wagner.critical_airspeed == pytest.approx(theo.critical_airspeed, rel=0.01)
    assert wagner.flutter_frequency == pytest.approx(theo.flutter_frequency, rel=0.01)
    assert abs(qs.critical_airspeed / theo.critical_airspeed - 1) > 0.1


def test_critical_airspeed_is_precise_to_1e_6(reference):
    model = AeroelasticModel(reference.wing)
    res = flutter_speed(model, 1.2)
    u = res.critical_airspeed
    g = growth_rate(model, np.array([u * (1 - 1e-7), u * (1 + 1e-7)]), 1.2)
    assert g[0] < 0 < g[1]
    # The unstable eigenvalue is on the imaginary axis at the flutter frequency.
    a, _ = model.matrices(u, 1.2)
    lam = np.linalg.eigvals(a)
    j = np.argmax(lam.real)
    assert abs(lam[j].real) < 1e-6 * abs(lam[j])
    assert abs(lam[j].imag) / (2 * np.pi) == pytest.approx(res.flutter_frequency, rel=1e-9)


def test_precision_with_maxwell_absorber_and_its_stiff_node(reference):
    for c2 in (0.0, 1e-6, 700.0, np.inf):
        model = AeroelasticModel(reference.wing, reference.absorber.replace(damping=c2))
        res = flutter_speed(model, 1.2)
        g = growth_rate(model, res.critical_airspeed * np.array([1 - 1e-7, 1 + 1e-7]), 1.2)
        assert g[0] < 0 < g[1], c2


def test_no_flutter_in_range_is_a_clear_error(reference):
    model = AeroelasticModel(reference.wing)
    with pytest.raises(NoFlutterError, match="no flutter"):
        flutter_speed(model, 1.2, (0.0, 50.0))
    with pytest.raises(ValueError, match="already unstable"):
        flutter_speed(model, 1.2, (150.0, 300.0))
    with pytest.raises(ValueError, match="density"):
        flutter_speed(model, -1.0)
    with pytest.raises(ValueError, match="airspeed_range"):
        flutter_speed(model, 1.2, (100.0, 50.0))


def test_a_short_excursion_between_grid_points_is_not_missed():
    """A mode unstable only within 1.05 +- 0.004, between negative grid samples, is found."""

    def g(u):
        return -0.05 - 0.1 * (u - 1.05) ** 2 + 0.06 * np.exp(-(((u - 1.05) / 0.01) ** 2))

    class Growth:
        def __call__(self, u):
            return g(u), 0j

    u = np.linspace(0.0, 2.0, 21)  # step 0.1: samples at 1.0 and 1.1 are negative
    samples = np.array([g(x) for x in u])
    assert np.all(samples < 0)
    a, b = _first_bracket(Growth(), u, samples, 2.0, 1e-12)
    assert g(a) < 0 < g(b) and 0.9 <= a < 1.046 < b <= 1.1


def test_flutter_speed_falls_as_density_rises(reference):
    model = AeroelasticModel(reference.wing)
    u, f = flutter_vs_density(model, [0.6, 0.9, 1.2, 1.5])
    assert np.all(np.diff(u) < 0)
    assert np.all(np.isfinite(f))


def test_modal_tracking_follows_the_flutter_mode(reference):
    model = AeroelasticModel(reference.wing)
    res_f = flutter_speed(model, 1.2)
    u_cr = res_f.critical_airspeed
    res = modal_analysis(model, np.linspace(0.0, 1.2 * u_cr, 241), 1.2)
    assert sorted(res.labels) == ["rotational", "translational"]
    assert res.frequency.shape == (2, 241)
    # Fig. 6.2: one tracked branch crosses zero damping at U_cr, at the flutter frequency.
    # (The grid holds U_cr itself, where the damping is zero to round-off: compare the
    # airspeeds just below and just above it.)
    below = int(np.searchsorted(res.airspeed, u_cr * (1 - 1e-6))) - 1
    above = int(np.searchsorted(res.airspeed, u_cr * (1 + 1e-6)))
    j = int(np.argmin(res.damping_ratio[:, above]))
    assert res.damping_ratio[j, below] > 0 > res.damping_ratio[j, above]
    assert res.frequency[j, above] == pytest.approx(res_f.flutter_frequency, rel=0.01)
    assert res.labels[j] == "rotational"  # as in the study's fig. 6.2
    # Tracking keeps the flutter branch continuous: no jumps between neighbouring airspeeds.
    # (A branch that splits into two real roots moves fast near the split, as it should.)
    steps = np.abs(np.diff(res.eigenvalues[j]))
    assert steps.max() < 0.02 * np.abs(res.eigenvalues[j]).max()
    assert res.min_damping_ratio[above] < 0 < res.min_damping_ratio[below]


def test_theodorsen_pk_handles_an_absorber(reference):
    wing = reference.wing
    bare = flutter_speed(AeroelasticModel(wing, None, TheodorsenAero()), 1.2)
    dva = PassiveAbsorber(40.0, 9.156e4, 860.0, wing.leading_edge)
    with_dva = flutter_speed(AeroelasticModel(wing, dva, TheodorsenAero()), 1.2)
    assert with_dva.critical_airspeed != pytest.approx(bare.critical_airspeed, rel=1e-3)


def _absorbers(cfg):
    yield "bare", None
    yield "passive", PassiveAbsorber(40.0, 9.156e4, 860.0, cfg.wing.leading_edge)
    for c2 in (0.0, 1e-6, 500.0, 2500.0, np.inf):
        yield f"maxwell c2={c2:g}", cfg.maxwell_design.replace(damping=c2)


@pytest.mark.parametrize("aero", [QuasiSteadyAero(), WagnerAero()], ids=["qs", "wagner"])
def test_newton_route_equals_the_previous_brent_route(reference, aero):
    """The eigenvalue-derivative Newton route gives the previous route's answer to 1e-9."""
    for name, absorber in _absorbers(reference):
        model = AeroelasticModel(reference.wing, absorber, aero)
        for rho in (0.6, 1.2):
            new = flutter_speed(model, rho)
            old = reference_flutter_speed(model, rho)
            assert new.critical_airspeed == pytest.approx(old.critical_airspeed, rel=1e-9), name
            assert new.flutter_frequency == pytest.approx(old.flutter_frequency, rel=1e-8), name
            assert new.kind == old.kind, name
    model = AeroelasticModel(reference.wing, reference.maxwell_design)
    new = flutter_speed(model, 1.2, (20.0, 300.0))
    old = reference_flutter_speed(model, 1.2, (20.0, 300.0))
    assert new.critical_airspeed == pytest.approx(old.critical_airspeed, rel=1e-9)


def test_safeguarded_newton_survives_a_kink_and_a_wrong_slope():
    """Growth = max of two modes (a kink) with a slope that is wrong by a factor 10: the
    bisection safeguard still converges to the root inside the bracket."""

    class Growth:
        def at(self, u):
            g = max(-1.0 + 0.5 * u, -5.0 + 2.0 * u)  # root 2 on the first, kink at 8/3
            return g, complex(g, 10.0), complex(5.0)  # slope 10x too large
    u, lam = _safeguarded_newton(Growth(), 0.0, 3.0, -1.0, 1.0, 1e-12)
    assert u == pytest.approx(2.0, rel=1e-11)
    assert lam.imag == 10.0


@pytest.mark.parametrize("field,value", [
    ("mass_ratio", -1.0), ("radius_of_gyration_sq", 0.001), ("elastic_axis", 1.5),
    ("pitch_frequency", float("nan")),
])
def test_bad_sections_are_named(field, value):
    with pytest.raises(ValueError, match=field if field != "radius_of_gyration_sq" else "radius"):
        HODGES_PIERCE.replace(**{field: value})
