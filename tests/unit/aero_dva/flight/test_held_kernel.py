"""The compiled parts of the batch simulator's few-flight route against their NumPy forms."""
import numpy as np
import pytest
from scipy.linalg import expm

from aero_dva.flight.discrete_model import held_values
from aero_dva.flight.discretize import TAYLOR, expm_batch
from aero_dva.flight.held_kernel import expm_stack, hold_rule


@pytest.mark.parametrize("quantum", [0.0, 2e-3, 0.05])
def test_the_compiled_hold_rule_equals_held_values(quantum):
    rng = np.random.default_rng(5)
    raw = np.stack([np.cumsum(rng.normal(0.0, 0.3, 500)) + 100.0,  # a wandering airspeed
                    np.full(500, 1.225),  # constant
                    np.repeat([300.0, 1200.0, 301.0, 0.0, 50.0], 100)], axis=-1)
    for held in (np.full(3, np.nan), np.array([100.05, 1.2251, 301.0])):
        ref = held_values(raw[None], held[None], quantum)[0]
        got = hold_rule(raw, held, quantum, np.empty_like(raw))
        np.testing.assert_array_equal(got, ref)
    assert len(np.unique(ref[:, 0])) < (500 if quantum else 501)


def test_the_compiled_exponential_equals_expm_batch_and_scipy():
    rng = np.random.default_rng(7)
    # norms from zero through 1 (no squaring) to 1e3 (ten squarings), as a flight's
    # augmented ZOH matrices (8 x 8) and other sizes
    stacks = [rng.standard_normal((40, 8, 8)) * np.logspace(-6, 2, 40)[:, None, None],
              rng.standard_normal((5, 3, 3)), np.zeros((2, 8, 8))]
    stacks[0][:, -1] = 0.0  # the augmented matrix's last row
    for m in stacks:
        got = expm_stack(np.ascontiguousarray(m), TAYLOR, np.empty_like(m))
        ref = np.array([expm(x) for x in m])
        scale = np.abs(ref).max(axis=(1, 2), keepdims=True)
        assert np.all(np.abs(got - ref) <= 1e-12 * scale)
        assert np.all(np.abs(got - expm_batch(m)) <= 1e-13 * scale)


def test_the_compiled_exponential_keeps_every_scale_of_a_graded_stack():
    # States of very different sizes (a stroke in metres beside a pitch in radians) make
    # D B D^-1 with a graded D; expm of it is D expm(B) D^-1, each entry on its own scale.
    # The balancing undoes D exactly, so each entry is right to its own scale, and an entry
    # 2^40 smaller than the largest is not lost in the largest's rounding.
    rng = np.random.default_rng(11)
    d = 2.0 ** rng.integers(-20, 21, 8)
    b = rng.standard_normal((30, 8, 8)) * 0.3
    m = b * d[:, None] / d[None, :]
    got = expm_stack(np.ascontiguousarray(m), TAYLOR, np.empty_like(m))
    eb = np.array([expm(x) for x in b])
    ref = eb * d[:, None] / d[None, :]
    bound = 1e-13 * np.abs(eb).max(axis=(1, 2), keepdims=True) * d[:, None] / d[None, :]
    assert np.all(np.abs(got - ref) <= bound)
