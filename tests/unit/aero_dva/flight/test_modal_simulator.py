"""The modal simulator of the wing along a logged flight (the discrepancy loop's)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from aero_dva.flight.modal_simulator import ModalBlocks, simulate, simulate_vectorised
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

WING = load_wing(None)
MODEL = AeroelasticModel(WING.wing, WING.maxwell_design, WING.aero)
DT = 1e-3


def _stepped(a, b, c, d, condition, force, block):
    """Reference: exact ZOH, one sample at a time."""
    n_st = a.shape[1]
    x = np.zeros(n_st)
    out = np.empty((c.shape[1], force.size))
    for i, f in enumerate(force):
        k = condition[i // block]
        big = np.zeros((n_st + 1, n_st + 1))
        big[:n_st, :n_st], big[:n_st, n_st] = a[k] * DT, b[k] * DT
        e = expm(big)
        out[:, i] = c[k] @ x + d[k] * f
        x = e[:n_st, :n_st] @ x + e[:n_st, n_st] * f
    return out


@pytest.mark.parametrize("kinds", [3, 40])  # few conditions (one product each) and many
def test_simulation_equals_sample_by_sample_zoh(kinds):
    rng = np.random.default_rng(kinds)
    block, n = 20, 1234  # the last block is partial
    nb = -(-n // block)
    u = rng.uniform(40.0, 70.0, kinds)
    c2 = rng.uniform(100.0, 1500.0, kinds)
    a, b = MODEL.matrices(u, np.full(kinds, 1.2), c2)
    c, d = MODEL.acceleration_output(a, b)
    condition = rng.integers(0, kinds, nb)
    force = 1000.0 * rng.standard_normal(n)
    got = simulate(ModalBlocks(a, b, c[:, :2], d[:, :2], DT), condition, force, block)
    want = _stepped(a, b, c[:, :2], d[:, :2], condition, force, block)
    assert got.shape == (2, n)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(want).max())


def test_second_input_shares_the_modes():
    rng = np.random.default_rng(1)
    a, b = MODEL.matrices(np.array([50.0, 60.0]), np.full(2, 1.2), np.array([300.0, 900.0]))
    other = rng.standard_normal(b.shape)
    c, d = MODEL.acceleration_output(a, b)
    _, d2 = MODEL.acceleration_output(a, other)
    modes = ModalBlocks(a, b, c[:, :2], d[:, :2], DT)
    condition = np.array([0, 1, 1, 0, 1])
    moment = rng.standard_normal(250)
    got = simulate(modes.with_input(other, d2[:, :2]), condition, moment, 50)
    want = simulate(ModalBlocks(a, other, c[:, :2], d2[:, :2], DT), condition, moment, 50)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_condition_per_block_is_checked():
    a, b = MODEL.matrices(np.array([50.0]), np.array([1.2]), np.array([300.0]))
    c, d = MODEL.acceleration_output(a, b)
    with pytest.raises(ValueError, match="one entry per block"):
        simulate(ModalBlocks(a, b, c, d, DT), np.zeros(2, dtype=int), np.zeros(500), 50)



def test_compiled_pass_equals_the_vectorised_reference():
    # Same recursion, other order of the sums: equal to rounding, also for an unstable
    # condition (a candidate's fit may try one) and a partial last block.
    rng = np.random.default_rng(5)
    kinds, block, n = 6, 50, 4321
    u = rng.uniform(40.0, 110.0, kinds)  # above the flutter speed for some
    a, b = MODEL.matrices(u, np.full(kinds, 1.2), rng.uniform(100.0, 1500.0, kinds))
    c, d = MODEL.acceleration_output(a, b)
    modes = ModalBlocks(a, b, c[:, :3], d[:, :3], DT)
    condition = rng.integers(0, kinds, -(-n // block))
    force = 1000.0 * rng.standard_normal(n)
    got = simulate(modes, condition, force, block)
    want = simulate_vectorised(modes, condition, force, block)
    assert got.shape == want.shape == (3, n)
    scale = np.abs(want).max(axis=1, keepdims=True)
    np.testing.assert_allclose(got / scale, want / scale, rtol=0, atol=1e-12)
