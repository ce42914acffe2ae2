"""Exact ZOH discretisation, vectorised (Zhang (2006) eq. 6.7-6.9 without inverting A)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import cont2discrete

from aero_dva.flight.discretize import check_sampling, expm_batch, zoh
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.wing.model import AeroelasticModel
from tests.unit.aero_dva.flight.test_simulators import DVA, WING


@pytest.mark.parametrize("scale", [1e-3, 0.3, 3.0, 40.0])
def test_expm_batch_matches_scipy(scale):
    rng = np.random.default_rng(1)
    m = rng.standard_normal((20, 8, 8)) * scale / 8
    ref = np.array([expm(x) for x in m])
    np.testing.assert_allclose(expm_batch(m), ref, rtol=1e-11, atol=1e-12 * np.abs(ref).max())


def test_expm_batch_of_a_transposed_stack_is_that_of_its_copy():
    m = np.random.default_rng(2).standard_normal((5, 6, 6)) * 0.5
    view = m.transpose(0, 2, 1)  # not C-contiguous
    np.testing.assert_array_equal(expm_batch(view), expm_batch(view.copy()))
    np.testing.assert_allclose(expm_batch(view)[0], expm(view[0]), rtol=1e-12, atol=1e-14)


def test_zoh_matches_scipy_and_survives_a_singular_a():
    model = AeroelasticModel(WING, DVA.replace(damping=np.inf))  # locked damper: A singular
    ss = model.state_space(80.0, 1.2)
    assert abs(np.linalg.det(ss.a)) < 1e-6 * np.abs(ss.a).max() ** ss.a.shape[0]
    phi, gam = zoh(ss.a, ss.b, 1e-3)
    ref = cont2discrete((ss.a, ss.b[:, None], np.eye(len(ss.b)), 0), 1e-3, "zoh")
    np.testing.assert_allclose(phi, ref[0], rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(gam, ref[1][:, 0], rtol=1e-9, atol=1e-15)


def test_zoh_of_a_very_stiff_maxwell_node_is_finite_and_stable():
    ss = AeroelasticModel(WING, DVA.replace(damping=1e-3)).state_space(80.0, 1.2)
    phi, gam = zoh(ss.a, ss.b, 1e-3)
    assert np.all(np.isfinite(phi)) and np.all(np.isfinite(gam))
    assert np.max(np.abs(np.linalg.eigvals(phi))) < 1.0


def test_sampling_below_nyquist_is_refused():
    a = AeroelasticModel(WING, DVA).state_space(0.0, 1.2).a
    with pytest.raises(ValueError, match="Nyquist"):
        check_sampling(a, 1.0 / 20.0)
    with pytest.raises(ValueError, match="Nyquist"):
        StreamingSimulator(WING, DVA, sample_rate=20.0).advance(np.zeros(5), 10.0, 1.2)
    with pytest.raises(ValueError, match="dt"):
        zoh(a, np.zeros(a.shape[0]), 0.0)
