"""Test data with two effects at once, and with covariates recorded as an instrument does.

Complements :mod:`.synthetic` (one hidden effect, exact covariate levels). The effects are the
same physics, coded here at the level of the mount's complex stiffness so that any two of them
compose exactly: the material's frequency axis is shifted (WLF, universal constants referred
to a glass transition 80-110 K below 23 C), its storage and loss parts scaled by a Kraus law
of the excitation level, an extra mass subtracted (K - dm w^2), a foundation put in series
(K K_f / (K + K_f), the 2-DOF chain of :mod:`.synthetic`), the response delayed. Magnitudes
are drawn from the single-effect ranges of :mod:`.synthetic`; each effect must change the
noise-free data by >= 3 sigma RMS on its own (with the other effect present), else redrawn.

``jitter=True``: the temperature per point drifts by up to 0.3 K within a sweep plus 0.05 K
noise, the excitation level per point scatters by 1 % RMS; the effects act at these recorded
values; a ``set`` column numbers the sweeps (the loop groups by it).
"""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy import synthetic
from dva_offline.isolator.maxwell_model import dynamic_stiffness, modal_properties

PAIRS = (
    ("sensor_delay", "fixture_mass"),
    ("sensor_delay", "foundation_mode"),
    ("covariate_shift", "sensor_delay"),
    ("amplitude_dependence", "sensor_delay"),
    ("covariate_shift", "fixture_mass"),
    ("amplitude_dependence", "fixture_mass"),
    ("covariate_shift", "amplitude_dependence"),
)
COMBINABLE = ("sensor_delay", "fixture_mass", "foundation_mode", "amplitude_dependence",
              "covariate_shift")


def _kraus_factors(level, a_c, drop, rise, nominal):
    g, h = synthetic._kraus(level, a_c, drop, rise)
    g0, h0 = synthetic._kraus(nominal, a_c, drop, rise)
    return g / g0, h / h0


def _draw(effect, rng, m, f_n):
    """Parameters of one effect (the ranges of :mod:`.synthetic`)."""
    if effect == "sensor_delay":
        return {"tau": synthetic._loguniform(rng, 1e-4, 1e-3)}
    if effect == "fixture_mass":
        return {"dm": m * rng.uniform(0.03, 0.15)}
    if effect == "foundation_mode":
        return {"f_f": synthetic._loguniform(rng, max(2.0 * f_n, 20.0), 200.0),
                "zeta_f": synthetic._loguniform(rng, 0.01, 0.05),
                "m_f": m * synthetic._loguniform(rng, 0.05, 0.5)}
    if effect == "amplitude_dependence":
        levels = np.asarray(synthetic.LEVELS_N)
        for _ in range(200):
            a_c = synthetic._loguniform(rng, levels[0], levels[-1])
            drop, rise = rng.uniform(0.1, 0.5), rng.uniform(-0.3, 0.5)
            g = _kraus_factors(levels, a_c, drop, rise, levels[1])[0]
            if np.ptp(g) >= 0.05:
                return {"a_c": a_c, "storage_drop": drop, "loss_rise": rise}
        raise ValueError("could not draw an amplitude dependence")
    if effect == "covariate_shift":
        return {"glass_transition_c": synthetic.T_REF_C - rng.uniform(80.0, 110.0)}
    raise ValueError(f"effect must be one of {COMBINABLE}, got {effect!r}")


def _response(model, omega, cov, quantity, effects, params):
    """Noise-free data with ``effects`` (each with ``params[effect]``) at every point."""
    w_mat = omega
    if "covariate_shift" in effects:
        t_g = params["covariate_shift"]["glass_transition_c"]

        def log_at(t):
            return -synthetic.WLF_C1 * (t - t_g) / (synthetic.WLF_C2 + t - t_g)

        w_mat = omega * 10.0 ** (log_at(cov["temperature_c"]) - log_at(synthetic.T_REF_C))
    stiff = dynamic_stiffness(w_mat, model.k, model.c, model.maxwell_k, model.maxwell_c)
    if "amplitude_dependence" in effects:
        p = params["amplitude_dependence"]
        g, h = _kraus_factors(cov["excitation_n"], p["a_c"], p["storage_drop"], p["loss_rise"],
                              synthetic.LEVELS_N[1])
        stiff = stiff.real * g + 1j * stiff.imag * h
    if "fixture_mass" in effects:
        stiff = stiff - params["fixture_mass"]["dm"] * omega**2
    if "foundation_mode" in effects:
        p = params["foundation_mode"]
        wf = 2 * np.pi * p["f_f"]
        kf = p["m_f"] * (wf**2 - omega**2 + 2j * p["zeta_f"] * wf * omega)
        stiff = stiff * kf / (stiff + kf)
    out = synthetic._measure(stiff, omega, model.mass, quantity)
    if "sensor_delay" in effects:
        sign = 1.0 if quantity == "stiffness" else -1.0
        out = out * np.exp(sign * 1j * omega * params["sensor_delay"]["tau"])
    return out


def generate_combined(effects, rng: np.random.Generator, *, quantity: str = "receptance",
                      sigma: float | None = None, n_points: int = 300,
                      jitter: bool = False) -> synthetic.SyntheticCase:
    """A data set hiding every effect in ``effects`` (one or two of :data:`COMBINABLE`).

    Returns a :class:`~dva_offline.discrepancy.synthetic.SyntheticCase` whose ``effect`` is
    the effects joined by ``+`` and ``parameters`` maps each effect to its parameters.
    """
    effects = tuple(effects)
    if not 1 <= len(effects) <= 2 or len(set(effects)) != len(effects):
        raise ValueError(f"effects must be one or two different effects, got {effects!r}")
    for e in effects:
        if e not in COMBINABLE:
            raise ValueError(f"effect must be one of {COMBINABLE}, got {e!r}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    if sigma is None:
        sigma = float(rng.uniform(0.005, 0.02))
    system = None
    if {"fixture_mass", "foundation_mode"} & set(effects):
        system = synthetic.LOW_RESONANCE_SYSTEMS[
            rng.integers(len(synthetic.LOW_RESONANCE_SYSTEMS))]
    name, model = synthetic._base_model(rng, system)
    f_n = modal_properties(model).natural_frequency_rad_s / (2 * np.pi)
    f = np.geomspace(synthetic.F_MIN_HZ, synthetic.F_MAX_HZ, n_points)
    temps = ([synthetic.T_REF_C] if "covariate_shift" not in effects else
             list(synthetic.T_REF_C + np.array([-1.0, 0.0, 1.0]) * rng.uniform(10.0, 15.0)))
    levels = (list(synthetic.LEVELS_N) if "amplitude_dependence" in effects
              else [synthetic.LEVELS_N[1]])
    grid = [(t, a) for t in temps for a in levels]
    freq = np.tile(f, len(grid))
    sweep = np.repeat(np.arange(len(grid)), f.size)
    cov = {"temperature_c": np.repeat([t for t, _ in grid], f.size).astype(float),
           "excitation_n": np.repeat([a for _, a in grid], f.size).astype(float)}
    if jitter:
        drift = np.concatenate([np.linspace(0.0, rng.uniform(-0.3, 0.3), f.size)
                                for _ in grid])
        cov["temperature_c"] = (cov["temperature_c"] + drift
                                + 0.05 * rng.standard_normal(freq.size))
        cov["excitation_n"] = cov["excitation_n"] * (1 + 0.01 * rng.standard_normal(freq.size))
    omega = 2 * np.pi * freq
    for _ in range(100):
        params = {e: _draw(e, rng, model.mass, f_n) for e in effects}
        clean = _response(model, omega, cov, quantity, effects, params)
        sizes = {}
        for e in effects:
            without = _response(model, omega, cov, quantity, tuple(x for x in effects if x != e),
                                params)
            sizes[e] = float(np.sqrt(np.mean(np.abs(clean / without - 1.0) ** 2)))
        if min(sizes.values()) < synthetic.MIN_EFFECT_SNR * sigma:
            continue
        # as in synthetic: the part of a single-sweep effect that a Maxwell model with one
        # more element cannot absorb must be detectable too (at the reference condition)
        ref = sweep == len(grid) // 2
        left = {e: synthetic._left_after_maxwell_fit(
                    model, omega[ref], _response(model, omega[ref], {k: v[ref] for k, v in
                                                                     cov.items()},
                                                 quantity, (e,), params), quantity)
                for e in effects if e in synthetic.ABSORBABLE_EFFECTS}
        if all(v >= synthetic.MIN_EFFECT_SNR * sigma for v in left.values()):
            break
    else:
        raise ValueError(f"could not draw detectable {effects} for sigma = {sigma}")
    base = _response(model, omega, cov, quantity, (), params)
    columns = tuple(c for c, used in (("temperature_c", len(temps) > 1),
                                      ("excitation_n", len(levels) > 1)) if used)
    out_cov = {c: cov[c] for c in columns}
    if jitter:
        out_cov["set"] = sweep.astype(float)
    eps = sigma / np.sqrt(2) * (rng.standard_normal(clean.size)
                                + 1j * rng.standard_normal(clean.size))
    params = {e: {**p, "effect_size": sizes[e]} for e, p in params.items()}
    return synthetic.SyntheticCase(freq, clean * (1.0 + eps), clean, base, quantity, out_cov,
                                   "+".join(effects), params, name, model, float(sigma),
                                   float(min(sizes.values())),
                                   ("set",) if jitter else columns)
