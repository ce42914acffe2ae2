"""The banded period carry, the compiled sample loop and the few-flight routes of the batch
simulator against the previous route (``reference_simulate_flights``) and a plain recurrence."""
import numpy as np
import pytest

from aero_dva.flight.batch_simulator import (
    _carry,
    _DiscreteCache,
    _shared_wing,
    forget_conditions,
    reference_simulate_flights,
    simulate_flights,
)
from aero_dva.flight.discrete_model import DiscreteWing
from aero_dva.flight.period_carry import period_starts
from aero_dva.wing.absorbers import PassiveAbsorber
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

CFG = load_wing()
WING, DVA, RHO = CFG.wing, CFG.maxwell_design, CFG.air_density  # U_cr about 112 m/s


def _peak_relative(got, ref):
    peak = np.max(np.abs(ref), axis=-1, keepdims=True)  # a channel may be all zero
    return float(np.max(np.abs(got - ref) / np.maximum(peak, 1e-300)))


@pytest.mark.parametrize("flights", [1, 3])
def test_period_starts_equal_the_recurrence(flights):
    rng = np.random.default_rng(2)
    nb, n = 300, 7
    p = 0.3 * rng.standard_normal((nb, n, n))
    g = rng.standard_normal((nb, n, flights))
    y = rng.standard_normal((n, flights))
    got = period_starts(p, g, y)
    s = y.copy()
    ref = [s]
    for b in range(nb):
        s = p[b] @ s + g[b]
        ref.append(s)
    np.testing.assert_allclose(got, np.array(ref), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got, _carry(p, g, y), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("scheduled", [False, True])
def test_one_flight_equals_the_previous_route(scheduled):
    # A ramp into flutter (it diverges, amplifying rounding): equal to 1e-9 of each channel's
    # peak, the first flight (nothing discretised) and a repeated one (conditions kept).
    rng = np.random.default_rng(3)
    n = 6000
    u = np.linspace(90.0, 135.0, n)
    c = np.interp(u, [90.0, 135.0], [1200.0, 300.0]) if scheduled else None
    force = 1000.0 * rng.standard_normal((2, n))
    ref = reference_simulate_flights(WING, DVA, force=force, airspeed=u, density=RHO,
                                     damping=c)
    forget_conditions()
    for _ in range(2):
        got = simulate_flights(WING, DVA, force=force, airspeed=u, density=RHO, damping=c)
        for name in ("displacements", "accelerations"):
            assert _peak_relative(getattr(got, name), getattr(ref, name)) < 1e-9, name
        assert _peak_relative(got.state, ref.state) < 1e-9
        np.testing.assert_array_equal(got.damping, ref.damping)
        np.testing.assert_array_equal(got.airspeed, ref.airspeed)
    assert np.abs(ref.displacements[:, 2, -500:]).max() > 10 * np.abs(
        ref.displacements[:, 2, :500]).max()  # it did diverge


def test_kept_conditions_do_not_leak_between_models():
    # The same schedule on a stiffer absorber must not reuse the first model's matrices.
    n = 800
    force = np.random.default_rng(4).standard_normal(n)
    other = DVA.replace(stiffness=1.5 * DVA.stiffness)
    for absorber in (DVA, other, DVA):
        got = simulate_flights(WING, absorber, force=force, airspeed=70.0, density=RHO)
        ref = reference_simulate_flights(WING, absorber, force=force, airspeed=70.0,
                                         density=RHO)
        assert _peak_relative(got.accelerations, ref.accelerations) < 1e-9


@pytest.mark.parametrize("flights", [1, 3])
def test_compiled_route_with_a_start_state_partial_periods_and_chunks(flights):
    # x0 set, a length that ends inside a hold period, and small chunks (each call starts
    # inside a period; the outputs of three flights are not contiguous per chunk).
    rng = np.random.default_rng(6)
    n = 2007
    u = np.linspace(60.0, 120.0, n)
    c = np.interp(u, [60.0, 120.0], [1500.0, 200.0])
    force = 500.0 * rng.standard_normal((flights, n))
    x0 = 1e-3 * rng.standard_normal(7)
    for chunk in (None, 37):
        kw = dict(force=force, airspeed=u, density=RHO, damping=c, x0=x0, chunk=chunk)
        ref = reference_simulate_flights(WING, DVA, **kw)
        got = simulate_flights(WING, DVA, **kw)
        for name in ("displacements", "accelerations", "state"):
            assert _peak_relative(getattr(got, name), getattr(ref, name)) < 1e-9, name
        np.testing.assert_array_equal(got.damping, ref.damping)


@pytest.mark.parametrize("absorber, aero, states, stacked", [
    (None, None, 4, True), (PassiveAbsorber(40.0, 9e4, 800.0, 1.0), None, 6, True),
    (DVA, None, 7, True), (DVA, WagnerAero(), 9, False)])
def test_every_model_size_takes_a_compiled_route_equal_to_the_previous(absorber, aero, states,
                                                                       stacked):
    # Up to 7 states: the stacked (16, 8) maps, padded; the Wagner lag's 9: the general loop.
    rng = np.random.default_rng(8)
    n = 3005
    u = np.linspace(40.0, 80.0, n)
    kw = dict(force=200.0 * rng.standard_normal((2, n)), airspeed=u, density=RHO, aero=aero,
              x0=1e-3 * rng.standard_normal(states))
    ref = reference_simulate_flights(WING, absorber, **kw)
    got = simulate_flights(WING, absorber, **kw)
    for name in ("displacements", "accelerations", "state"):
        assert _peak_relative(getattr(got, name), getattr(ref, name)) < 1e-9, name
    assert got.state.shape == (2, states)
    _, cache, _ = _shared_wing(WING, absorber, aero, 1000.0, 10, 2e-3)
    assert ("stack" in cache.arr) is stacked
    assert "period" not in cache.arr  # the compiled loop needs one-sample maps only


def test_the_kept_model_is_reused_and_bad_arguments_are_still_refused():
    first = _shared_wing(WING, DVA, None, 1000.0, 10, 2e-3)
    assert _shared_wing(WING, DVA, None, 1000.0, 10, 2e-3) is first
    assert _shared_wing(WING, DVA, None, 1000.0, 10, 0.0)[0] is not first[0]
    first = _shared_wing(WING, DVA, None, 1000.0, 10, 2e-3)
    assert _shared_wing(WING, DVA, None, np.float64(1000.0), np.int64(10), 2e-3) is first
    with pytest.raises(ValueError, match="hold"):
        _shared_wing(WING, DVA, None, 1000.0, True, 2e-3)  # equal to 1 as a key, not a hold
    with pytest.raises(ValueError, match="sample_rate"):
        _shared_wing(WING, DVA, None, -5.0, 10, 2e-3)
    with pytest.raises(TypeError, match="absorber"):
        _shared_wing(WING, [DVA], None, 1000.0, 10, 2e-3)  # unhashable: refused by name


def test_a_repeated_schedule_reuses_its_lookup_and_a_cleared_cache_does_not():
    cache = _DiscreteCache(DiscreteWing(AeroelasticModel(WING, DVA), 1000.0))
    rows = np.stack([np.linspace(60.0, 70.0, 50), np.full(50, RHO), np.full(50, 600.0)], -1)
    first = cache.lookup(rows)
    assert cache.lookup(rows.copy()) is first  # the same schedule again
    assert not first.flags.writeable  # handed out twice: nobody may change it
    moved = rows.copy()
    moved[10, 0] += 1.0
    assert cache.lookup(moved) is not first
    np.testing.assert_array_equal(cache.lookup(rows), first)
    assert not cache.done["carry"][first].any()
    carry = cache.lookup(rows, "carry")  # a higher level is computed, not taken from the memo
    assert cache.done["carry"][carry].all()
    assert cache.lookup(rows) is carry  # and serves the lower level
    cache.clear()
    again = cache.lookup(rows)
    assert again is not first and cache.size == len(np.unique(again))


def test_lookups_find_kept_conditions_and_add_only_the_new_ones():
    dw = DiscreteWing(AeroelasticModel(WING, DVA), 1000.0)
    cache = _DiscreteCache(dw, compiled=True)
    u = np.repeat(np.linspace(60.0, 70.0, 40), 3)  # runs of three periods
    rows = np.stack([u, np.full(u.size, RHO), np.linspace(300.0, 900.0, u.size)], -1)
    rows[:, 2] = np.repeat(rows[::3, 2], 3)
    first = cache.lookup(rows[:60])
    assert cache.size == 20
    # half kept, half new, the schedule out of order, and one condition twice
    mixed = np.concatenate([rows[90:], rows[30:60], rows[:3]])
    idx = cache.lookup(mixed)
    assert cache.size == 30  # ten new; rows 60-89 stay unasked
    np.testing.assert_array_equal(idx[30:60], first[30:60])
    ref = dw.discretise(mixed)
    np.testing.assert_allclose(cache.arr["phi"][idx], ref.ad, rtol=0, atol=1e-13)
    np.testing.assert_allclose(cache.arr["gam"][idx], ref.bd, rtol=0, atol=1e-13)
    assert len(np.unique(idx)) == 21 and cache.lookup(rows[:3]).tolist() == idx[-3:].tolist()
