"""The FRF domain's effects as composable terms of one model (so effects can be stacked).

A model is the general Maxwell stiffness K(w) of order n (eq. 4.8) plus a list of terms, each
with its own parameters (the vector is [Maxwell parameters, term 1, term 2, ...]). Terms act
at fixed stages, whatever the order they were added in:

1. ``shift``: the material's frequency axis, w -> w a_T (WLF or Arrhenius, per covariate);
2. ``element``: one more Maxwell element of the material (at the shifted frequency);
3. ``level``: storage and loss parts scaled by a level covariate;
4. ``mass``: an unmodelled mass, K - dm w^2;
5. ``series``: a foundation in series, K K_f / (K + K_f);
6. then the measured quantity (receptance, accelerance or the stiffness itself);
7. ``output``: a delay of the response channel, H exp(-+ j w tau).

With one term each stage reproduces the single-effect formulas of the candidate library.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dva_offline.discrepancy import laws

R_GAS = 8.314462618  # J/(mol K)
STAGES = ("shift", "element", "level", "mass", "series", "output")

SIGNATURES = {
    "maxwell_element": "smooth, broad residual in magnitude and phase around the element's "
                       "corner frequency 1/(2 pi tau_e); no resonance",
    "sensor_delay": "phase of H_meas / H_model falls linearly with frequency (slope "
                    "-2 pi tau per Hz), magnitude unchanged; largest at high frequency",
    "fixture_mass": "resonance shifted by about -dm/(2m); above resonance the magnitude is off "
                    "by a constant factor m/(m + dm) (receptance ~ 1/((m+dm) w^2))",
    "foundation_mode": "narrow resonance/anti-resonance pair at the foundation frequency, above "
                       "the mount resonance; residual localised in one band",
    "amplitude_dependence": "residual changes with the excitation-level covariate: stiffness "
                            "and damping scale with ln(level), at all frequencies",
    "covariate_shift": "residual changes with the covariate as a shift along log frequency: "
                       "the relaxation (Maxwell) frequencies move by a_T(T)",
}


@dataclass(frozen=True)
class Term:
    """One effect in a model (module docstring).

    Attributes
    ----------
    effect, label : str
        Effect name and qualifier (covariate, form), as in the candidate library.
    stage : str
        One of :data:`STAGES`; ``kind`` picks the formula within a stage.
    size : int
        Number of parameters.
    kind : str
        ``wlf``, ``arrhenius`` or ``law`` (shift), ``law`` (level: laws of the storage and
        loss parts, :mod:`.laws`), else the stage name.
    data : dict
        Fixed arrays the formula needs (covariate offsets, log levels, the delay's sign).
    """

    effect: str
    label: str
    stage: str
    size: int
    kind: str = ""
    data: dict = field(default_factory=dict)


def absolute_temperature(name: str, col: np.ndarray) -> np.ndarray | None:
    """The covariate in kelvin if its name says it is a temperature (``*_k`` kelvin, other
    temperature names Celsius), else None (Arrhenius needs an absolute temperature)."""
    low = name.lower()
    if not (low.startswith("temp") or low in ("t", "t_c", "t_k")):
        return None
    kelvin = col if low.endswith("_k") else col + 273.15
    return kelvin if np.all(kelvin > 0) else None


def law_factors(term: Term, p) -> dict:
    """ln of each coordinate's factor of a ``law`` term (:mod:`.laws`) at every point:
    ``storage``, ``loss`` (level stage) or ``shift`` (a_T, shift stage)."""
    out, j = {}, 0
    for which, law, k in term.data["coords"]:
        out[which] = laws.log_factor(law, [p[j + q] for q in range(k)], term.data["x"],
                                     term.data["cov"], term.data["level_index"])
        j += k
    return out


def log_shift(term: Term, p) -> np.ndarray:
    """log10 a_T of a ``shift`` term at every point."""
    if term.kind == "law":
        return law_factors(term, p)["shift"] / np.log(10.0)
    if term.kind == "arrhenius":
        return p[0] / (R_GAS * np.log(10.0)) * term.data["inv"]
    b, c2 = p
    dt = term.data["dt"]
    return -b * c2 * dt / (c2 + dt)


def maxwell_parts(w, k, c, ks=(), cs=()):
    """Real and imaginary parts of K(w) = k + j w c + sum_i k_i j w c_i / (k_i + j w c_i)
    (eq. 4.8) at real angular frequencies ``w``; the parameters may be arrays that broadcast
    against ``w`` (many parameter vectors at once).

    Each element in real arithmetic, with a_i = w c_i: k_i a_i^2 / (k_i^2 + a_i^2) +
    j k_i^2 a_i / (k_i^2 + a_i^2), the same value as the complex quotient for a fraction of
    its cost (the fits evaluate it hundreds of thousands of times)."""
    re, im = k, c * w
    for ki, ci in zip(ks, cs):
        a = ci * w
        den = ki * ki + a * a
        re = re + ki * a * a / den
        im = im + ki * ki * a / den
    return re, im


def _complex(re, im):
    out = np.empty(np.broadcast_shapes(np.shape(re), np.shape(im)), dtype=complex)
    out.real, out.imag = re, im
    return out


def maxwell_stiffness(w, k, c, ks=(), cs=()):
    """K(w) of :func:`maxwell_parts`, complex."""
    return _complex(*maxwell_parts(w, k, c, ks, cs))


def compose(maxwell, terms, values, omega, mass, quantity):
    """Model values at all points.

    Parameters
    ----------
    maxwell : callable
        ``maxwell(w_material, parts=True)`` -> the real and imaginary parts of K of the
        Maxwell part at (shifted) angular frequencies.
    terms : sequence of Term
    values : sequence of numpy.ndarray
        Each term's parameter values.
    omega : numpy.ndarray
        Angular frequency of every point [rad/s].
    mass : float
        Isolated mass [kg].
    quantity : str
        ``receptance``, ``accelerance`` or ``stiffness``.
    """
    # Real and imaginary parts are carried separately up to the output stage: real
    # arithmetic costs a fraction of numpy's complex products and quotients.
    pairs = list(zip(terms, values))
    w_mat = omega
    for t, p in pairs:
        if t.stage == "shift":
            w_mat = w_mat * 10.0 ** log_shift(t, p)
    re, im = maxwell(w_mat, parts=True)
    elements = [p for t, p in pairs if t.stage == "element"]
    if elements:
        e_re, e_im = maxwell_parts(w_mat, 0.0, 0.0, [p[0] for p in elements],
                                   [p[1] for p in elements])
        re, im = re + e_re, im + e_im
    for t, p in pairs:
        if t.stage == "level" and t.kind == "law":
            lf = law_factors(t, p)
            if "storage" in lf:
                re = re * np.exp(lf["storage"])
            if "loss" in lf:
                im = im * np.exp(lf["loss"])
        elif t.stage == "level":
            sk, sd = p
            lev = t.data["log_level"]
            re, im = re * (1 + sk * lev), im * (1 + sd * lev)
    w2 = omega**2
    for t, p in pairs:
        if t.stage == "mass":
            re = re - p[0] * w2
    for t, p in pairs:
        if t.stage == "series":
            ff, zf, mf = p
            wf = 2 * np.pi * ff
            kf = mf * (wf**2 - w2 + 2j * zf * wf * omega)
            stiff = _complex(re, im)
            stiff = stiff * kf / (stiff + kf)
            re, im = stiff.real, stiff.imag
    if quantity == "stiffness":
        out = _complex(re, im)
    else:
        # 1 / (d_re + j im) = (d_re - j im) / |d|^2
        d_re = re - mass * w2
        scale = 1.0 / (d_re * d_re + im * im)
        if quantity == "accelerance":
            scale = -w2 * scale
        out = _complex(d_re * scale, -im * scale)
    for t, p in pairs:
        if t.stage == "output":
            out = out * np.exp(t.data["sign"] * 1j * omega * p[0])
    return out
