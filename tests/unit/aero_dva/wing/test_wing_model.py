"""Wing, absorbers and aerodynamics assembled into state space (Zhang (2006) eq. 6.1-6.16)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from aero_dva.wing.absorbers import N_PER_MM, NS_PER_MM, MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.aerodynamics import (
    QuasiSteadyAero,
    TheodorsenAero,
    WagnerAero,
    aero_from_name,
    theodorsen_function,
)
from aero_dva.wing.model import MAXWELL_RATE_LIMIT, AeroelasticModel, WingParameters

WING = WingParameters(mass=1000.0, inertia=650.0, plunge_stiffness=4.8e6, pitch_stiffness=2.0e6,
                      damping_factor=2e-4, chord=1.9, gravity_centre=1.53, elastic_axis=0.8,
                      aileron_position=-0.3, lift_slope=5.5, span=1.0)


def study_a_matrix(w: WingParameters, u: float, rho: float) -> np.ndarray:
    """The study's eq. 6.6, written out term by term (unit span)."""
    m, i, k, ka, b = w.mass, w.inertia, w.plunge_stiffness, w.pitch_stiffness, w.damping_factor
    c, c0, ce, a = w.chord, w.gravity_centre, w.elastic_axis, w.lift_slope
    r = c0 / c
    return np.array([
        [0, 0, 1, 0],
        [0, 0, 0, 1],
        [-k / m, k * ce / m - u**2 * rho * c / (2 * m) * a,
         -b * k / m - u * rho * c / (2 * m) * a,
         b * k * ce / m - u * rho * c**2 / (2 * m) * a * (0.75 - r)],
        [k * ce / i, -(ka + k * ce**2) / i - u**2 * rho * c**2 / (2 * i) * a * (0.25 - r),
         b * k * ce / i - u * rho * c**2 / (2 * i) * a * (0.25 - r),
         -b * (ka + k * ce**2) / i
         - u * rho * c**3 / (2 * i) * (a * (3 / 16 - r + r**2) + np.pi / 8)],
    ])


def test_bare_wing_matches_seed_eq_6_6():
    model = AeroelasticModel(WING)
    for u in (0.0, 37.0, 180.0):
        ss = model.state_space(u, 1.2)
        np.testing.assert_allclose(ss.a, study_a_matrix(WING, u, 1.2), rtol=1e-13, atol=1e-9)
        np.testing.assert_allclose(ss.b, [0, 0, 1 / WING.mass, 0.3 / WING.inertia], rtol=1e-14)


def test_printed_eq_6_2_couple_is_lift_slope_squared_times_larger():
    thin = AeroelasticModel(WING, aero=QuasiSteadyAero("thin_airfoil")).state_space(50, 1.2).a
    printed = AeroelasticModel(WING, aero=QuasiSteadyAero("printed_6_2")).state_space(50, 1.2).a
    couple = 50 * 1.2 * WING.chord**3 / (2 * WING.inertia) * np.pi / 8
    assert printed[3, 3] - thin[3, 3] == pytest.approx(-couple * (WING.lift_slope**2 - 1))
    np.testing.assert_array_equal(printed[:3], thin[:3])


def test_span_scales_the_aerodynamic_forces_only():
    a1 = AeroelasticModel(WING).state_space(60, 1.2).a
    a3 = AeroelasticModel(WING.replace(span=3.0)).state_space(60, 1.2).a
    a0 = AeroelasticModel(WING).state_space(0, 1.2).a
    np.testing.assert_allclose(a3 - a0, 3 * (a1 - a0), rtol=1e-12, atol=1e-9)


def test_passive_absorber_matrices_follow_eq_6_11():
    ab = PassiveAbsorber(mass=40.0, stiffness=9e4, damping=860.0, position=1.2)
    model = AeroelasticModel(WING, ab)
    a = model.state_space(0.0, 1.2).a
    m = np.diag([WING.mass, WING.inertia, 40.0])
    u = np.array([1.0, -1.2, -1.0])
    bare = AeroelasticModel(WING).state_space(0.0, 1.2).a
    # Stiffness and damping parts: M (A rows) = -(K_wing + k1 u u^T), -(C_wing + c1 u u^T).
    k_total = -m @ a[3:6, 0:3]
    c_total = -m @ a[3:6, 3:6]
    k_wing = np.zeros((3, 3))
    k_wing[:2, :2] = -np.diag([WING.mass, WING.inertia]) @ bare[2:4, 0:2]
    np.testing.assert_allclose(k_total - k_wing, 9e4 * np.outer(u, u), rtol=1e-12, atol=1e-6)
    c_wing = np.zeros((3, 3))
    c_wing[:2, :2] = -np.diag([WING.mass, WING.inertia]) @ bare[2:4, 2:4]
    np.testing.assert_allclose(c_total - c_wing, 860 * np.outer(u, u), rtol=1e-12, atol=1e-6)


def _oscillatory(a, tol=1e-6):
    lam = np.linalg.eigvals(a)
    return np.sort_complex(lam[np.abs(lam.imag) > tol])


def test_locked_maxwell_damper_is_a_spring_k1_plus_k2():
    locked = MaxwellAbsorber(40.0, 2.5e4, 1.5e5, math.inf, 1.53)
    spring = PassiveAbsorber(40.0, 1.75e5, 0.0, 1.53)
    a_m = AeroelasticModel(WING, locked).state_space(80.0, 1.2).a
    a_p = AeroelasticModel(WING, spring).state_space(80.0, 1.2).a
    np.testing.assert_allclose(_oscillatory(a_m), _oscillatory(a_p), rtol=1e-9)
    # The extra state is a free integrator (eigenvalue 0), not an instability.
    assert np.min(np.abs(np.linalg.eigvals(a_m))) < 1e-8


@pytest.mark.parametrize("c2", [0.0, 1e-9])
def test_free_maxwell_damper_leaves_spring_k1(c2):
    free = MaxwellAbsorber(40.0, 2.5e4, 1.5e5, c2, 1.53)
    spring = PassiveAbsorber(40.0, 2.5e4, c2, 1.53)
    a_m = AeroelasticModel(WING, free).state_space(80.0, 1.2).a
    a_p = AeroelasticModel(WING, spring).state_space(80.0, 1.2).a
    np.testing.assert_allclose(_oscillatory(a_m), _oscillatory(a_p), rtol=1e-9)
    assert np.all(np.isfinite(a_m))


def test_maxwell_is_continuous_across_the_plain_damper_limit():
    k2 = 1.5e5
    c_switch = k2 / MAXWELL_RATE_LIMIT
    lam = [_oscillatory(AeroelasticModel(WING, MaxwellAbsorber(40, 2.5e4, k2, c, 1.53))
                        .state_space(80.0, 1.2).a) for c in (0.999 * c_switch, 1.001 * c_switch)]
    np.testing.assert_allclose(lam[0], lam[1], rtol=1e-6)


def test_maxwell_dva_stiffness_lies_between_k1_and_k1_plus_k2():
    """Chapter 3 carried over: tuning c2 moves the DVA between k1 and k1 + k2 (eq. 6.14-6.16).

    The wing is made very heavy and stiff so the DVA sees a fixed base.
    """
    base = WING.replace(mass=1e9, inertia=1e9, plunge_stiffness=1e15, pitch_stiffness=1e15,
                        damping_factor=0.0)
    k1, k2, m1 = 2.5e4, 1.5e5, 40.0
    mags = []
    for c2 in (0.0, 300.0, 3e3, 3e4, math.inf):
        a = AeroelasticModel(base, MaxwellAbsorber(m1, k1, k2, c2, 1.53)).state_space(0, 1.2).a
        lam = _oscillatory(a)
        mags.append(np.min(np.abs(lam)))
    assert mags[0] == pytest.approx(math.sqrt(k1 / m1), rel=1e-9)
    assert mags[-1] == pytest.approx(math.sqrt((k1 + k2) / m1), rel=1e-9)
    assert all(mags[0] < x < mags[-1] for x in mags[1:-1])


def test_energy_conservative_without_damping_and_wind():
    wing = WING.replace(damping_factor=0.0)
    a = AeroelasticModel(wing, PassiveAbsorber(40, 9e4, 0.0, -0.2)).state_space(0.0, 1.2).a
    assert np.max(np.abs(np.linalg.eigvals(a).real)) < 1e-9


def test_outputs_leading_edge_and_stroke():
    ab = PassiveAbsorber(40.0, 9e4, 860.0, -0.1)
    ss = AeroelasticModel(WING, ab).state_space(50.0, 1.2)
    y = np.array([0.01, 0.02, 0.005, 0, 0, 0])
    disp = ss.c_displacement @ y
    assert disp[2] == pytest.approx(0.01 - WING.gravity_centre * 0.02)
    assert disp[3] == pytest.approx(0.005 - (0.01 + 0.1 * 0.02))
    acc = ss.c_acceleration @ y + ss.d_acceleration * 100.0
    full = ss.a @ y + ss.b * 100.0
    assert acc[0] == pytest.approx(full[3])
    assert acc[2] == pytest.approx(full[3] - WING.gravity_centre * full[4])


def test_vectorised_assembly_equals_single():
    model = AeroelasticModel(WING, MaxwellAbsorber(40, 2.5e4, 1.5e5, 500.0, 1.53), WagnerAero())
    u = np.array([10.0, 90.0])
    rho = np.array([1.0, 1.3])
    a, b = model.matrices(u, rho, damping=np.array([100.0, 2000.0]))
    for i in range(2):
        ss = model.state_space(u[i], rho[i], damping=[100.0, 2000.0][i])
        np.testing.assert_allclose(a[i], ss.a, rtol=1e-14)
        np.testing.assert_allclose(b[i], ss.b, rtol=1e-14)


@pytest.mark.parametrize("absorber", [None, PassiveAbsorber(40, 9e4, 800.0, 1.0),
                                      MaxwellAbsorber(40, 2.5e4, 1.5e5, 500.0, 1.53)])
def test_unchecked_assembly_of_the_simulators_equals_the_checked_one(absorber):
    model = AeroelasticModel(WING, absorber, WagnerAero())
    u = np.array([0.0, 35.0, 90.0, 120.0])
    rho = np.array([1.2, 0.9, 1.3, 1.2])
    # c2 = inf (locked), the plain-damper limit (k2/c2 > 1e8 1/s), c2 = 0 and a normal value
    c = None if absorber is None else np.array([np.inf, 1e-4, 0.0, 700.0])
    if isinstance(absorber, PassiveAbsorber):
        c = np.array([0.0, 10.0, 800.0, 5e3])
    a, b = model.matrices(u, rho, damping=c)
    a2, b2 = model.matrices_unchecked(u, rho, c)
    np.testing.assert_array_equal(a2, a)
    np.testing.assert_array_equal(b2, b)


def test_polynomial_form_is_exact():
    model = AeroelasticModel(WING, MaxwellAbsorber(40, 2.5e4, 1.5e5, 500.0, 1.53), WagnerAero())
    a0, a1, a2 = model.polynomial(1.1)
    for u in (0.0, 55.0, 130.0):
        np.testing.assert_allclose(a0 + u * a1 + u * u * a2, model.state_space(u, 1.1).a,
                                   rtol=1e-12, atol=1e-9)


def test_wagner_lag_states_match_jones_form_of_theodorsen():
    """Harmonic lift deficiency of the two lag states equals Jones' rational C(k)."""
    k = np.array([0.05, 0.2, 0.8])
    jones = 1 - 0.165 * 1j * k / (1j * k + 0.0455) - 0.335 * 1j * k / (1j * k + 0.3)
    exact = theodorsen_function(k)
    assert np.max(np.abs(jones - exact)) < 0.02  # Jones' fit is good to ~1-2 %
    assert theodorsen_function(0.0) == 1.0


def test_state_space_names_and_sizes():
    m = AeroelasticModel(WING, MaxwellAbsorber(40, 2.5e4, 1.5e5, 500.0, 1.53), WagnerAero())
    assert m.n_states == 9
    assert m.state_names[6:] == ("maxwell_deflection", "aero_lag_1", "aero_lag_2")
    with pytest.raises(ValueError, match="Theodorsen"):
        AeroelasticModel(WING, None, TheodorsenAero()).frequency_frozen(10, 1.2, None)


def test_study_unit_conversions():
    assert 29.38 * N_PER_MM == pytest.approx(29380.0)
    assert 1.88 * NS_PER_MM == pytest.approx(1880.0)


@pytest.mark.parametrize("field,value,error,match", [
    ("mass", -1.0, ValueError, "mass"),
    ("inertia", float("nan"), ValueError, "inertia"),
    ("chord", "wide", TypeError, "chord"),
    ("gravity_centre", 5.0, ValueError, "gravity_centre"),
    ("aileron_position", 3.0, ValueError, "aileron_position"),
    ("damping_factor", -1e-3, ValueError, "damping_factor"),
])
def test_bad_wing_parameters_are_named(field, value, error, match):
    with pytest.raises(error, match=match):
        WING.replace(**{field: value})


def test_absorber_outside_the_chord_is_refused():
    with pytest.raises(ValueError, match="outside the chord"):
        AeroelasticModel(WING, PassiveAbsorber(40, 9e4, 100, 1.6))
    with pytest.raises(ValueError, match="outside the chord"):
        AeroelasticModel(WING, PassiveAbsorber(40, 9e4, 100, WING.trailing_edge - 0.01))


@pytest.mark.parametrize("kwargs,match", [
    (dict(mass=-40.0), "mass"),
    (dict(stiffness=float("nan")), "stiffness"),
    (dict(damping=-1.0), "damping"),
])
def test_bad_absorbers_are_named(kwargs, match):
    base = dict(mass=40.0, stiffness=9e4, damping=100.0, position=0.0)
    with pytest.raises(ValueError, match=match):
        PassiveAbsorber(**{**base, **kwargs})


def test_bad_conditions_are_named():
    model = AeroelasticModel(WING)
    with pytest.raises(ValueError, match="airspeed"):
        model.matrices(-1.0, 1.2)
    with pytest.raises(ValueError, match="density"):
        model.matrices(10.0, float("nan"))
    with pytest.raises(ValueError, match="aero"):
        aero_from_name("vortex-lattice")
