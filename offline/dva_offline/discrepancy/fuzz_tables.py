"""Random measured-looking FRF tables at real scales, for fuzzing ``dva discrepancy``.

Each table is physically shaped but of random magnitude and band, so that no scale the loop
assumes can hold by accident:

* ``modulus``: a relaxation spectrum (generalised Maxwell model, 1-8 elements with time
  constants spread over up to 10 decades, equilibrium modulus possibly zero as for a melt)
  at 2-6 temperatures with a WLF shift; moduli anywhere in 1e4..1e10 Pa;
* ``isolator``: a mass on a mount with 0-3 Maxwell elements (receptance or accelerance,
  resonance inside the band), at 1-3 temperatures shifting the elements;
* ``receptance`` / ``accelerance`` / ``mobility``: 1-5 modes (damping 0.3-10 %) plus a
  residual stiffness, at 1-4 excitation levels (sometimes softening with the level), receptance
  magnitudes anywhere in 1e-9..1e-2 m/N.

Bands lie within 0.01 Hz..10 kHz, 1-4 decades wide, 12-60 points per sweep; complex noise of
0.2-5 % RMS relative. Pure numerics: :func:`random_table` returns arrays; the caller writes them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KINDS = ("modulus", "receptance", "accelerance", "mobility", "isolator")


@dataclass(frozen=True)
class FuzzTable:
    """One random table: quantity, frequency [Hz], complex values (SI), per-point covariates
    (``set`` numbers the sweeps) and the command-line flags that read it."""

    quantity: str
    frequency_hz: np.ndarray
    values: np.ndarray
    covariates: dict
    flags: tuple


def _band(rng) -> np.ndarray:
    decades = rng.uniform(1.0, 4.0)
    lo = 10 ** rng.uniform(-2.0, 4.0 - decades)
    return lo, lo * 10**decades


def _noise(rng, values, sigma) -> np.ndarray:
    z = rng.standard_normal(values.shape) + 1j * rng.standard_normal(values.shape)
    return values * (1 + sigma / np.sqrt(2) * z)


def _modulus(rng):
    lo, hi = _band(rng)
    n_f = int(rng.integers(12, 41))
    f = np.geomspace(lo, hi, n_f)
    temps = np.sort(rng.choice(np.arange(-40.0, 200.0, 5.0), int(rng.integers(2, 7)),
                               replace=False))
    t_ref = float(temps[len(temps) // 2])
    c1, c2 = rng.uniform(5, 25), rng.uniform(50, 200)
    n_el = int(rng.integers(1, 9))
    # time constants around the band's centre, over up to 10 decades
    centre = -np.log10(2 * np.pi * np.sqrt(lo * hi))
    taus = 10 ** (centre + rng.uniform(-5, 5, n_el))
    top = 10 ** rng.uniform(5.0, 10.0)
    moduli = top * 10 ** rng.uniform(-1.5, 0, n_el) / n_el
    e_inf = 0.0 if rng.random() < 0.4 else top * 10 ** rng.uniform(-4, -1)
    rows_f, rows_v, rows_t, rows_s = [], [], [], []
    for i, temp in enumerate(temps):
        log_a = -c1 * (temp - t_ref) / (c2 + temp - t_ref) if c2 + temp - t_ref > 5 else 0.0
        w = 2 * np.pi * f * 10 ** np.clip(log_a, -12, 12)
        wt = w[:, None] * taus[None, :]
        e = e_inf + np.sum(moduli * (1j * wt) / (1 + 1j * wt), axis=1)
        e = np.where(np.abs(e) > 0, e, 1e-3 * top)
        rows_f.append(f)
        rows_v.append(e)
        rows_t.append(temp + rng.normal(0, 0.05, n_f))
        rows_s.append(np.full(n_f, i + 1.0))
    return np.concatenate(rows_f), np.concatenate(rows_v), {
        "temperature_c": np.concatenate(rows_t), "set": np.concatenate(rows_s)}


def _structure(rng, quantity):
    lo, hi = _band(rng)
    n_f = int(rng.integers(20, 61))
    f = np.geomspace(lo, hi, n_f)
    n_modes = int(rng.integers(1, 6))
    # mode frequencies inside the band, at least 20 % apart
    fr = np.sort(np.geomspace(lo * 1.3, hi / 1.3, n_modes) * 10 ** rng.uniform(-0.05, 0.05,
                                                                             n_modes))
    zeta = 10 ** rng.uniform(np.log10(0.003), -1, n_modes)
    level_h = 10 ** rng.uniform(-9.0, -2.0)  # typical receptance magnitude at the modes
    wr = 2 * np.pi * fr
    amp = level_h * wr**2 * 2 * zeta * rng.uniform(0.3, 1.0, n_modes) * rng.choice(
        [-1, 1], n_modes)
    resid_k = 10 ** rng.uniform(0, 2) / level_h
    levels = np.sort(10 ** rng.uniform(-1, 2, int(rng.integers(1, 5))))
    soft = rng.uniform(0.0, 0.03) if rng.random() < 0.5 else 0.0
    rows_f, rows_v, rows_l, rows_s = [], [], [], []
    for i, lev in enumerate(levels):
        shift = 1 - soft * np.log(lev / levels[0]) if lev > 0 else 1.0
        w = 2 * np.pi * f
        wri = wr * shift
        h = np.sum(amp / (wri**2 - w[:, None] ** 2 + 2j * zeta * wri * w[:, None]), axis=1)
        h = h + 1 / resid_k
        if quantity == "mobility":
            h = 1j * w * h
        elif quantity == "accelerance":
            h = -(w**2) * h
        rows_f.append(f)
        rows_v.append(h)
        rows_l.append(lev * (1 + rng.normal(0, 0.01, n_f)))
        rows_s.append(np.full(n_f, i + 1.0))
    return np.concatenate(rows_f), np.concatenate(rows_v), {
        "force_n": np.concatenate(rows_l), "set": np.concatenate(rows_s)}


def _isolator(rng):
    lo, hi = _band(rng)
    n_f = int(rng.integers(20, 61))
    f = np.geomspace(lo, hi, n_f)
    wn = 2 * np.pi * 10 ** rng.uniform(np.log10(lo) + 0.2, np.log10(hi) - 0.3)
    k = 10 ** rng.uniform(0.0, 7.0) / 10 ** rng.uniform(-7.0, 0.0)  # N/m: 1/k in 1e-9..1e-2
    k = float(np.clip(k, 1e2, 1e9))
    m = k / wn**2
    c = 2 * rng.uniform(0.005, 0.1) * np.sqrt(k * m)
    n_el = int(rng.integers(0, 4))
    ks = k * 10 ** rng.uniform(-1.0, 0.5, n_el)
    taus = 10 ** rng.uniform(-1.0, 1.0, n_el) / wn
    temps = np.sort(rng.choice(np.arange(0.0, 80.0, 10.0), int(rng.integers(1, 4)),
                               replace=False))
    quantity = str(rng.choice(("receptance", "accelerance")))
    rows_f, rows_v, rows_t, rows_s = [], [], [], []
    for i, temp in enumerate(temps):
        a_t = 10 ** (-0.05 * (temp - temps[0]))
        w = 2 * np.pi * f
        wt = w[:, None] * taus[None, :] * a_t
        stiff = k + 1j * w * c + np.sum(ks * (1j * wt) / (1 + 1j * wt), axis=1)
        h = 1.0 / (stiff - m * w**2)
        if quantity == "accelerance":
            h = -(w**2) * h
        rows_f.append(f)
        rows_v.append(h)
        rows_t.append(temp + rng.normal(0, 0.05, n_f))
        rows_s.append(np.full(n_f, i + 1.0))
    return quantity, np.concatenate(rows_f), np.concatenate(rows_v), {
        "temperature_c": np.concatenate(rows_t), "set": np.concatenate(rows_s)}


def random_table(rng: np.random.Generator, kind: str | None = None) -> FuzzTable:
    """A random table of ``kind`` (one of :data:`KINDS`; random when None)."""
    kind = kind or str(rng.choice(KINDS))
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if kind == "modulus":
        f, v, cov = _modulus(rng)
    elif kind == "isolator":
        kind, f, v, cov = _isolator(rng)
    else:
        f, v, cov = _structure(rng, kind)
    v = _noise(rng, v, 10 ** rng.uniform(np.log10(0.002), np.log10(0.05)))
    flags = ("--quantity", kind, "--group-by", "set")
    return FuzzTable(kind, f, v, cov, flags)
