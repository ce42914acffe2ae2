"""Test data for the modal domain: vibration tests of a structure with several modes.

Separate from the modal domain on purpose: the level dependence is a Kraus-type softening
law of one mode (not the candidate's log law), the temperature effect an exponential stiffness
change of the whole structure. A case: 3 modes between 10 and 150 Hz (frequency ratios >= 1.4),
damping 1-4 %, driving-point modal constants 1/m_r with modal masses 0.5-5 kg; 400 points
from 5 to 200 Hz (0.49 Hz lines, as an FFT analyser gives) per sweep; noise H (1 + eps),
E|eps|^2 = sigma^2, sigma uniform 0.5-2 %; data as receptance, mobility or accelerance.

Hidden effects (magnitudes redrawn until the noise-free change is >= 3 sigma RMS):

* ``amplitude_dependence``: sweeps at 2, 6.3 and 20 N (``excitation_n``); one mode's
  frequency falls by f_r (1 - d x / (1 + x)), x = (a / a_c)^1.2, and its damping grows by
  (1 + e 2 sqrt(x) / (1 + x)), normalised to the middle level; 1-4 % frequency change over the
  levels, e in 0..1 (a bolted joint or a rubber part of the structure);
* ``covariate_shift``: sweeps at 8, 23 and 38 C (``temperature_c``); every frequency scales
  by exp(-kappa (T - 23 C)), kappa 0.5e-3..2e-3 1/K;
* ``sensor_delay``: 0.2..2 ms, one sweep.

``jitter=True`` records the covariates as an instrument does: the level per point within 1 %
(RMS) of the sweep's nominal value, the temperature drifting by up to 0.3 K within a sweep
plus 0.05 K noise; the effect acts at the recorded values; a ``set`` column numbers the sweeps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EFFECTS = ("amplitude_dependence", "covariate_shift", "sensor_delay")
LEVELS_N = (2.0, 2.0 * 10**0.5, 20.0)
TEMPERATURES_C = (8.0, 23.0, 38.0)
MIN_EFFECT_SNR = 3.0


@dataclass(frozen=True)
class StructureCase:
    """A generated vibration test and its truth (the domain gets only the data)."""

    frequency_hz: np.ndarray
    values: np.ndarray
    quantity: str
    covariates: dict
    effect: str | None
    parameters: dict
    modes_hz: tuple
    sigma: float
    effect_size: float
    condition_columns: tuple


def _modes(rng, n):
    for _ in range(200):
        f = np.sort(np.exp(rng.uniform(np.log(10.0), np.log(150.0), n)))
        if np.all(f[1:] / f[:-1] >= 1.4):
            return f
    raise ValueError("could not draw well-separated modes")


def _receptance(f_hz, fr, zr, ar, f_fac, z_fac):
    w = 2 * np.pi * f_hz
    wr = 2 * np.pi * fr[:, None] * f_fac
    return np.sum(ar[:, None] / (wr**2 - w**2 + 2j * zr[:, None] * z_fac * wr * w), axis=0)


def _convert(rec, f_hz, quantity):
    w = 2 * np.pi * f_hz
    if quantity == "receptance":
        return rec
    if quantity == "mobility":
        return 1j * w * rec
    if quantity == "accelerance":
        return -(w**2) * rec
    raise ValueError(f"quantity must be receptance, mobility or accelerance, got {quantity!r}")


def generate_structure(effect: str | None, rng: np.random.Generator, *,
                       quantity: str = "accelerance", sigma: float | None = None,
                       n_modes: int = 3, n_points: int = 400,
                       jitter: bool = False) -> StructureCase:
    """One test hiding ``effect`` (module docstring); None gives clean data at the three
    excitation levels."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    if effect not in (None, *EFFECTS):
        raise ValueError(f"effect must be None or one of {EFFECTS}, got {effect!r}")
    if sigma is None:
        sigma = float(rng.uniform(0.005, 0.02))
    f = np.linspace(5.0, 200.0, n_points)
    fr = _modes(rng, n_modes)
    zr = np.exp(rng.uniform(np.log(0.01), np.log(0.04), n_modes))
    ar = 1.0 / np.exp(rng.uniform(np.log(0.5), np.log(5.0), n_modes))
    if effect == "sensor_delay":
        nominal, column = (None,), None
    elif effect == "covariate_shift":
        nominal, column = TEMPERATURES_C, "temperature_c"
    else:
        nominal, column = LEVELS_N, "excitation_n"
    m = len(nominal)
    freq = np.tile(f, m)
    sweep = np.repeat(np.arange(m), f.size)
    cov = {}
    if column is not None:
        value = np.repeat(np.asarray(nominal, float), f.size)
        if jitter and column == "excitation_n":
            value = value * (1 + 0.01 * rng.standard_normal(value.size))
        elif jitter:
            drift = np.concatenate([np.linspace(0, rng.uniform(-0.3, 0.3), f.size)
                                    for _ in range(m)])
            value = value + drift + 0.05 * rng.standard_normal(value.size)
        cov[column] = value
    if jitter:
        cov["set"] = sweep.astype(float)
    base = _receptance(freq, fr, zr, ar, 1.0, 1.0)
    for _ in range(200):
        f_fac = np.ones((n_modes, freq.size))
        z_fac = np.ones((n_modes, freq.size))
        delay = 0.0
        params: dict = {}
        if effect == "amplitude_dependence":
            r = int(rng.integers(n_modes))
            a = cov["excitation_n"]
            a_c = float(np.exp(rng.uniform(np.log(LEVELS_N[0]), np.log(LEVELS_N[-1]))))
            change, e = rng.uniform(0.01, 0.04), rng.uniform(0.0, 1.0)

            def soft(level, a_c=a_c):
                x = (level / a_c) ** 1.2
                return x / (1 + x), 2 * np.sqrt(x) / (1 + x)

            g = np.array([soft(lv)[0] for lv in LEVELS_N])
            d = change / max(np.ptp(g), 1e-9)
            x_all, y_all = soft(a)
            x_mid, y_mid = soft(LEVELS_N[1])
            f_fac[r] = (1 - d * x_all) / (1 - d * x_mid)
            z_fac[r] = (1 + e * y_all) / (1 + e * y_mid)
            params = {"mode": r + 1, "mode_hz": float(fr[r]), "a_c": a_c,
                      "frequency_change": float(change), "damping_rise": float(e)}
        elif effect == "covariate_shift":
            kappa = rng.uniform(0.5e-3, 2e-3)
            f_fac = f_fac * np.exp(-kappa * (cov["temperature_c"] - TEMPERATURES_C[1]))
            params = {"kappa_per_k": float(kappa)}
        elif effect == "sensor_delay":
            delay = float(np.exp(rng.uniform(np.log(2e-4), np.log(2e-3))))
            params = {"tau": delay}
        clean = _receptance(freq, fr, zr, ar, f_fac, z_fac) * np.exp(-2j * np.pi * freq * delay)
        size = float(np.sqrt(np.mean(np.abs(clean / base - 1.0) ** 2)))
        if effect is None or size >= MIN_EFFECT_SNR * sigma:
            break
    else:
        raise ValueError(f"could not draw a detectable {effect} for sigma = {sigma}")
    eps = sigma / np.sqrt(2) * (rng.standard_normal(clean.size)
                                + 1j * rng.standard_normal(clean.size))
    values = _convert(clean * (1 + eps), freq, quantity)
    columns = ("set",) if jitter else ((column,) if column else ())
    return StructureCase(freq, values, quantity, cov, effect, params, tuple(fr.tolist()),
                         float(sigma), 0.0 if effect is None else size, columns)
