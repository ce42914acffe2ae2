"""Random Maxwell-Voigt test systems and complex FRF noise for tests and benchmarks.

A system is a mass on a spring k, a damper c and one Maxwell element (k_1, c_1). It is drawn
by its modal properties so that w_n and zeta cover the wanted ranges uniformly: w_n, zeta,
the stiffness ratio k_1 / k and w_n tau_1 are drawn, and (k, c) follow from "lambda is an
eigenvalue", which is linear in them. Draws with c < 0 are rejected.
"""
from __future__ import annotations

import numpy as np

from dva_offline.isolator.maxwell_model import MaxwellModel, target_eigenvalue


def random_mv_system(
    rng: np.random.Generator,
    mass: float = 1.0,
    damping_range: tuple[float, float] = (0.05, 0.45),
    frequency_range_hz: tuple[float, float] = (5.0, 35.0),
    stiffness_ratio_range: tuple[float, float] = (0.2, 3.0),
    omega_tau_range: tuple[float, float] = (0.2, 10.0),
) -> MaxwellModel:
    """Draw a Maxwell-Voigt system with w_n and zeta uniform in the given ranges.

    Parameters
    ----------
    rng : numpy.random.Generator
        ``numpy.random.default_rng(seed)``.
    mass : float
        Mass [kg].
    damping_range : (float, float)
        Range of the damping ratio zeta [-].
    frequency_range_hz : (float, float)
        Range of the natural frequency w_n / 2 pi [Hz].
    stiffness_ratio_range, omega_tau_range : (float, float)
        Log-uniform ranges of k_1 / k and w_n tau_1 [-].
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    for _ in range(1000):
        zeta = rng.uniform(*damping_range)
        wn = 2 * np.pi * rng.uniform(*frequency_range_hz)
        ratio = np.exp(rng.uniform(*np.log(stiffness_ratio_range)))
        tau = np.exp(rng.uniform(*np.log(omega_tau_range))) / wn
        lam = target_eigenvalue(wn, zeta)
        # m lam^2 + c lam + k (1 + ratio tau lam / (1 + tau lam)) = 0, real and imaginary parts.
        g = 1.0 + ratio * tau * lam / (1.0 + tau * lam)
        a = np.array([[lam.real, g.real], [lam.imag, g.imag]])
        rhs = -mass * lam**2
        c, k = np.linalg.solve(a, [rhs.real, rhs.imag])
        if c >= 0 and k > 0:
            return MaxwellModel(mass, float(k), float(c), (float(ratio * k),),
                                (float(ratio * k * tau),))
    raise RuntimeError("no system with c >= 0 found for these ranges")


def add_complex_noise(h, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """H (1 + alpha), alpha complex Gaussian with E|alpha|^2 = sigma^2 (sigma/sqrt 2 per part).

    ``sigma`` is the RMS relative noise, so a perfect model has a relative FRF error of about
    ``sigma`` against the noisy data.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    if not sigma >= 0:
        raise ValueError(f"sigma must be >= 0, got {sigma}")
    h = np.asarray(h, dtype=complex)
    alpha = (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2)
    return h * (1.0 + sigma * alpha)
