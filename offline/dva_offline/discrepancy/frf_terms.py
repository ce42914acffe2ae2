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
        ``wlf`` or ``arrhenius`` (shift), else the stage name.
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


def log_shift(term: Term, p) -> np.ndarray:
    """log10 a_T of a ``shift`` term at every point."""
    if term.kind == "arrhenius":
        return p[0] / (R_GAS * np.log(10.0)) * term.data["inv"]
    b, c2 = p
    dt = term.data["dt"]
    return -b * c2 * dt / (c2 + dt)


def compose(maxwell, terms, values, omega, mass, quantity):
    """Model values at all points.

    Parameters
    ----------
    maxwell : callable
        ``maxwell(w_material)`` -> K of the Maxwell part at (shifted) angular frequencies.
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
    pairs = list(zip(terms, values))
    w_mat = omega
    for t, p in pairs:
        if t.stage == "shift":
            w_mat = w_mat * 10.0 ** log_shift(t, p)
    stiff = maxwell(w_mat)
    for t, p in pairs:
        if t.stage == "element":
            ke, ce = p
            stiff = stiff + ke * ce * 1j * w_mat / (ke + ce * 1j * w_mat)
    for t, p in pairs:
        if t.stage == "level":
            sk, sd = p
            lev = t.data["log_level"]
            stiff = stiff.real * (1 + sk * lev) + 1j * stiff.imag * (1 + sd * lev)
    for t, p in pairs:
        if t.stage == "mass":
            stiff = stiff - p[0] * omega**2
    for t, p in pairs:
        if t.stage == "series":
            ff, zf, mf = p
            wf = 2 * np.pi * ff
            kf = mf * (wf**2 - omega**2 + 2j * zf * wf * omega)
            stiff = stiff * kf / (stiff + kf)
    if quantity == "stiffness":
        out = stiff
    else:
        d = stiff - mass * omega**2
        out = 1.0 / d if quantity == "receptance" else -(omega**2) / d
    for t, p in pairs:
        if t.stage == "output":
            out = out * np.exp(t.data["sign"] * 1j * omega * p[0])
    return out
