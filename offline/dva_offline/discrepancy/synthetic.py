"""Test-data generator for the FRF domain: isolator FRFs hiding exactly one effect.

Separate from the loop on purpose: the effects are coded here from their physics (the
foundation as a 2-DOF chain solved directly, amplitude dependence as a Kraus/Payne law,
time-temperature superposition with universal WLF constants referred to a glass transition,
a Duffing oscillator by harmonic balance), not with the loop's candidate formulas, and the
loop never sees the labels.

Base systems: the M-M-V systems of the study's Table 4.1 (m = 1 kg) and the identified mounts
of Table 5.6 (m = 1.041 kg), each parameter perturbed by a random factor exp(N(0, 0.05^2)).
Frequencies: ``n_points`` log-spaced points from 3 to 300 Hz per condition. Noise:
H_meas = H (1 + eps), eps complex normal with E|eps|^2 = sigma^2 (each part sigma / sqrt(2)),
sigma uniform in [0.5, 2] % unless given.

Detectability thresholds (the magnitude of the hidden effect is drawn at random above them):

* every effect must change the noise-free FRF by an RMS relative amount
  sqrt(mean |H_effect / H_base - 1|^2) >= ``MIN_EFFECT_SNR`` x sigma (= 3 sigma); a draw below
  is redrawn. (No method can halve the held-out error of an effect smaller than ~1.7 sigma:
  the noise alone keeps the error at sigma.) For the single-sweep effects a Maxwell model with
  one element more can absorb part of the change, so there the part left after the isolator
  tool's unconstrained fit of such a model to the noise-free data must also be >= 3 sigma.
* ``maxwell_element``: a Type B + Type C system (Table 4.1 F or a Table 5.6 mount) whose
  model keeps one of the two elements (the loop is told ``elements=1``); the data have both.
  The study's section 4.2 shows no single element matches such a pair.
* ``sensor_delay``: tau in 0.1..1 ms.
* ``fixture_mass`` and ``foundation_mode`` use base systems resonating below f_max / 5 (not
  the 5.6 stud at 89 Hz): with only half a decade above resonance an extra mass and a series
  compliance look alike (on the stud the loop can name ``foundation_mode`` for a mass error).
* ``fixture_mass``: an unmodelled extra mass dm (fixture, accelerometer) of 3..15 % of m.
  (A mass *over*-estimate, dm < 0, is largely absorbed by a stiff Type C element of the
  automatically sized baseline, K ~ |dm| w^2 over the band, and is not a fair test.)
* ``foundation_mode``: f_f in [max(2 f_n, 20 Hz), 200 Hz] (so the coupled resonance above
  f_f stays in the band), zeta_f in 0.01..0.05, m_f / m in 0.05..0.5. (Broader, heavier
  foundations, zeta_f ~ 0.1 with m_f ~ m, act as a smooth extra compliance that the Maxwell
  family partly absorbs; they are not reliably detected.)
* ``amplitude_dependence``: 3 excitation levels 2, 6.3, 20 N (column ``excitation_n``); storage
  stiffness falls by a Kraus law, loss changes by its companion law; the storage factor changes
  by >= 5 % over the levels; the middle level is the nominal one (static stiffness).
* ``covariate_shift``: 3 temperatures T0 - dT, T0, T0 + dT (column ``temperature_c``),
  2 dT in 20..30 K, WLF C1 = 17.44, C2 = 51.6 K referred to a glass transition 80..110 K
  below T0 = 23 C (a shift of about 0.8..1.6 decades over the temperatures).

Effects outside the loop's library (for the "never a confident wrong name" tests):

* ``rocking_mode``: a second mode seen by an off-axis accelerometer: a parallel modal term with
  negative residue, f_r in [1.5 f_n, 200 Hz], zeta_r 0.01..0.05.
* ``cubic_stiffness``: a Duffing spring k3 x^3 at 3 force levels (harmonic balance, lower
  branch as in a downward sweep; (3/4) k3 X_lin^2 at resonance at the top level is 5..50 % of
  |K|, X_lin the linear amplitude there).

A clean data set has ``effect=None`` (optionally at several temperatures/levels without any
dependence on them). ``clean_covariate`` also repeats an effect's data set at three levels of a
covariate the data do not depend on: e.g. a temperature shift measured at three temperatures
x three excitation levels (two covariates, one of which matters).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from dva_offline.isolator.maxwell_model import (
    MaxwellModel,
    dynamic_stiffness,
    frf,
    modal_properties,
)

LIBRARY_EFFECTS = ("maxwell_element", "sensor_delay", "fixture_mass", "foundation_mode",
                   "amplitude_dependence", "covariate_shift")
OUTSIDE_EFFECTS = ("rocking_mode", "cubic_stiffness")
MIN_EFFECT_SNR = 3.0
# single-sweep effects that a baseline with an extra Maxwell element can partly absorb
ABSORBABLE_EFFECTS = ("sensor_delay", "fixture_mass", "foundation_mode")
F_MIN_HZ, F_MAX_HZ = 3.0, 300.0
KN = 1e3

# name: (mass kg, k N/m, c N s/m, ((k_i N/m, c_i N s/m), ...))
BASE_SYSTEMS = {
    "4.1-A": (1.0, 12 * KN, 40.0, ((12 * KN, 20.0), (24 * KN, 20.0))),
    "4.1-B": (1.0, 12 * KN, 40.0, ((12 * KN, 80.0), (24 * KN, 120.0))),
    "4.1-C": (1.0, 12 * KN, 40.0, ((12 * KN, 2000.0), (24 * KN, 2000.0))),
    "4.1-D": (1.0, 12 * KN, 40.0, ((24 * KN, 20.0), (12 * KN, 80.0))),
    "4.1-E": (1.0, 12 * KN, 40.0, ((24 * KN, 20.0), (12 * KN, 2000.0))),
    "4.1-F": (1.0, 12 * KN, 40.0, ((12 * KN, 80.0), (24 * KN, 2000.0))),
    "5.6-bubble": (1.041, 14.01 * KN, -55.49, ((64.44 * KN, 87.81), (18.23 * KN, 2297.39))),
    "5.6-plate": (1.041, 23.15 * KN, -29.15, ((45.21 * KN, 70.93), (26.05 * KN, 2402.82))),
    "5.6-stud": (1.041, 54.51 * KN, -70.18, ((389.70 * KN, 239.46), (224.11 * KN, 15507.4))),
}
# Type B + Type C element pairs (Table 4.1 F, Table 5.6): one element cannot stand in for both
MAXWELL_ELEMENT_SYSTEMS = ("4.1-F", "5.6-bubble", "5.6-plate", "5.6-stud")
# Resonance below f_max / 5 (all but the 5.6 stud at 89 Hz): a mass error or a foundation
# mode needs the band to reach well above the mount resonance to be told apart.
LOW_RESONANCE_SYSTEMS = tuple(n for n in sorted(BASE_SYSTEMS) if n != "5.6-stud")
LEVELS_N = (2.0, 2.0 * 10**0.5, 20.0)
T_REF_C = 23.0
WLF_C1, WLF_C2 = 17.44, 51.6


@dataclass(frozen=True)
class SyntheticCase:
    """A generated data set and the truth behind it (the loop gets only the data).

    Attributes
    ----------
    frequency_hz : numpy.ndarray
        Shape (N,) [Hz]; increasing within each condition, conditions stacked.
    values : numpy.ndarray
        Measured FRF, shape (N,), complex, of kind ``quantity``.
    clean_values : numpy.ndarray
        Noise-free FRF with the effect, shape (N,).
    base_values : numpy.ndarray
        Noise-free FRF of the base system without the effect, shape (N,).
    quantity : str
        ``receptance`` [m/N], ``accelerance`` [(m/s^2)/N] or ``stiffness`` [N/m].
    covariates : dict of str to numpy.ndarray
        Condition columns, each shape (N,) (empty for a single condition).
    effect : str or None
        The hidden effect.
    parameters : dict
        The effect's parameters (SI).
    system : str
        Base system name (:data:`BASE_SYSTEMS`).
    model : MaxwellModel
        The perturbed base system.
    sigma : float
        Noise RMS [-].
    effect_size : float
        RMS relative change of the noise-free FRF caused by the effect [-].
    """

    frequency_hz: np.ndarray
    values: np.ndarray
    clean_values: np.ndarray
    base_values: np.ndarray
    quantity: str
    covariates: dict
    effect: str | None
    parameters: dict
    system: str
    model: MaxwellModel
    sigma: float
    effect_size: float
    condition_columns: tuple[str, ...] = field(default=())

    @property
    def mass(self) -> float:
        """Isolated mass m [kg] (as weighed)."""
        return self.model.mass

    @property
    def static_stiffness(self) -> float:
        """Static stiffness k [N/m]."""
        return self.model.k

    @property
    def n_elements(self) -> int:
        """Maxwell elements of the model the loop should be given (the base system's; one
        fewer than the data's for ``maxwell_element``)."""
        return int(self.parameters.get("base_elements", self.model.n_elements))


def _loguniform(rng, lo, hi):
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _base_model(rng, system: str | None) -> tuple[str, MaxwellModel]:
    names = sorted(BASE_SYSTEMS)
    name = names[rng.integers(len(names))] if system is None else system
    if name not in BASE_SYSTEMS:
        raise ValueError(f"system must be one of {names}, got {system!r}")
    mass, k, c, elems = BASE_SYSTEMS[name]
    for _ in range(50):
        f = np.exp(0.05 * rng.standard_normal(2 + 2 * len(elems)))
        model = MaxwellModel(mass, k * f[0], c * f[1],
                             tuple(e[0] * g for e, g in zip(elems, f[2::2])),
                             tuple(e[1] * g for e, g in zip(elems, f[3::2])))
        try:
            if modal_properties(model).is_stable:
                return name, model
        except ValueError:
            continue
    raise ValueError(f"could not draw a stable perturbation of system {name}")


def _measure(stiffness, omega, mass, quantity):
    """What the test rig reports for a mount of complex stiffness K carrying mass m."""
    if quantity == "stiffness":
        return stiffness
    rec = 1.0 / (stiffness - mass * omega**2)
    return rec if quantity == "receptance" else -(omega**2) * rec


def _from_receptance(rec, omega, quantity):
    if quantity == "receptance":
        return rec
    if quantity == "accelerance":
        return -(omega**2) * rec
    raise ValueError(f"this effect needs receptance or accelerance data, got {quantity!r}")


def _stiffness(model: MaxwellModel, omega):
    return dynamic_stiffness(omega, model.k, model.c, model.maxwell_k, model.maxwell_c)


def _kraus(a, a_c, drop, rise):
    """Payne effect (Kraus): storage factor and loss factor at amplitude a."""
    x = (a / a_c) ** 1.2
    storage = 1.0 - drop * x / (1.0 + x)
    loss = 1.0 + rise * 2.0 * np.sqrt(x) / (1.0 + x)
    return storage, loss


def _duffing_receptance(d, beta, force):
    """Harmonic balance of m x'' + K x + k3 x^3 = F cos(wt): x/F = 1 / (D + (3/4) k3 |X|^2).

    Parameters: D = K - m w^2 (N,), beta = 3/4 k3, force amplitude F. Where several branches
    exist the lowest amplitude is taken (the response of a downward stepped-sine sweep).
    """
    out = np.empty(d.size, dtype=complex)
    for i, di in enumerate(d):
        # beta^2 u^3 + 2 beta Re(D) u^2 + |D|^2 u - F^2 = 0, u = |X|^2
        roots = np.roots([beta**2, 2 * beta * di.real, abs(di) ** 2, -(force**2)])
        real = roots[(np.abs(roots.imag) <= 1e-6 * np.abs(roots).max()) & (roots.real > 0)]
        u = real.real.min() if real.size else roots[np.argmin(np.abs(roots.imag))].real
        out[i] = 1.0 / (di + beta * u)
    return out


def _left_after_maxwell_fit(model: MaxwellModel, omega, clean, quantity) -> float:
    """RMS relative residual of the noise-free data after the isolator tool's unconstrained
    fit of a Maxwell model with one element more than the base system (what an automatically
    sized baseline could absorb of the effect)."""
    # imported here: the fit needs scipy, which `dva discrepancy --help` must not load
    from dva_offline.isolator.maxwell_fit import fit_unconstrained_least_squares

    modal = modal_properties(model)
    n = min(model.n_elements + 1, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = fit_unconstrained_least_squares(
            omega, clean, model.mass, model.k, n, modal.natural_frequency_rad_s,
            min(modal.damping_ratio, 0.8), quantity=quantity)
    h = frf(fit.model, omega, quantity)
    return float(np.sqrt(np.mean(np.abs(h / clean - 1.0) ** 2)))


def _draw_effect(effect, rng, model, omega, quantity, n_points, f_n):
    """One draw of the effect: (clean, base, covariates, parameters, columns)."""
    m = model.mass
    k0 = _stiffness(model, omega)
    base = _measure(k0, omega, m, quantity)
    if effect is None:
        return base, base, {}, {}, ()
    if effect == "maxwell_element":
        # The base keeps one element of a Type B + Type C pair; the data have both (the
        # the study's System F / Table 5.6 situation that no M-V model matches, section 4.2).
        keep = int(rng.integers(2))
        ks, cs = model.maxwell_k, model.maxwell_c
        base_model = MaxwellModel(m, model.k, model.c, (ks[keep],), (cs[keep],))
        base = _measure(_stiffness(base_model, omega), omega, m, quantity)
        ke, ce = ks[1 - keep], cs[1 - keep]
        return (_measure(k0, omega, m, quantity), base, {},
                {"k_e": ke, "c_e": ce, "corner_hz": ke / (2 * np.pi * ce),
                 "base_elements": 1}, ())
    if effect == "sensor_delay":
        tau = _loguniform(rng, 1e-4, 1e-3)
        sign = 1.0 if quantity == "stiffness" else -1.0
        return base * np.exp(sign * 1j * omega * tau), base, {}, {"tau": tau}, ()
    if effect == "fixture_mass":
        dm = m * rng.uniform(0.03, 0.15)
        return (_measure(k0 - dm * omega**2, omega, m, quantity), base, {},
                {"dm": dm, "dm_over_m": dm / m}, ())
    if effect == "foundation_mode":
        ff = _loguniform(rng, max(2.0 * f_n, 20.0), 200.0)
        zf = _loguniform(rng, 0.01, 0.05)
        mf = m * _loguniform(rng, 0.05, 0.5)
        wf = 2 * np.pi * ff
        kf, cf = mf * wf**2, 2 * zf * mf * wf
        if quantity == "stiffness":
            # displacement x imposed on the mount; node 2 = fixture mass on its spring
            kf_dyn = kf + 1j * omega * cf - mf * omega**2
            clean = k0 * kf_dyn / (k0 + kf_dyn)
        else:
            # 2-DOF chain: mass m on the mount on fixture m_f on (k_f, c_f); force on m
            z11 = k0 - m * omega**2
            z12 = -k0
            z22 = k0 + kf + 1j * omega * cf - mf * omega**2
            rec = z22 / (z11 * z22 - z12**2)
            clean = _from_receptance(rec, omega, quantity)
        return clean, base, {}, {"f_f": ff, "zeta_f": zf, "m_f": mf}, ()
    if effect in ("amplitude_dependence", "cubic_stiffness"):
        levels = np.asarray(LEVELS_N)
        col = np.repeat(levels, n_points)
        w_all = np.tile(omega, levels.size)
        k_all = np.tile(k0, levels.size)
        base_all = np.tile(base, levels.size)
        if effect == "amplitude_dependence":
            for _ in range(200):
                a_c = _loguniform(rng, levels[0], levels[-1])
                drop, rise = rng.uniform(0.1, 0.5), rng.uniform(-0.3, 0.5)
                g, h = _kraus(col, a_c, drop, rise)
                g0, h0 = _kraus(levels[1], a_c, drop, rise)
                gl = _kraus(levels, a_c, drop, rise)[0]
                if np.ptp(gl) / g0 >= 0.05:
                    break
            stiff = k_all.real * g / g0 + 1j * k_all.imag * h / h0
            return (_measure(stiff, w_all, m, quantity), base_all, {"excitation_n": col},
                    {"a_c": a_c, "storage_drop": drop, "loss_rise": rise}, ("excitation_n",))
        d = k0 - m * omega**2
        i_res = int(np.argmin(np.abs(d)))
        x_lin = levels[-1] / abs(d[i_res])
        ratio = rng.uniform(0.05, 0.5)
        beta = ratio * abs(k0[i_res]) / x_lin**2
        recs = [_duffing_receptance(d, beta, level) for level in levels]
        clean = _from_receptance(np.concatenate(recs), w_all, quantity)
        return (clean, base_all, {"excitation_n": col},
                {"k3": beta / 0.75, "stiffening_at_resonance": ratio}, ("excitation_n",))
    if effect == "covariate_shift":
        half = rng.uniform(10.0, 15.0)
        temps = T_REF_C + np.array([-half, 0.0, half])
        t_g = T_REF_C - rng.uniform(80.0, 110.0)

        def log_at(t):
            return -WLF_C1 * (t - t_g) / (WLF_C2 + t - t_g)

        col = np.repeat(temps, n_points)
        w_all = np.tile(omega, temps.size)
        shift = 10.0 ** (log_at(col) - log_at(T_REF_C))
        stiff = dynamic_stiffness(w_all * shift, model.k, model.c, model.maxwell_k,
                                  model.maxwell_c)
        base_all = np.tile(base, temps.size)
        return (_measure(stiff, w_all, m, quantity), base_all, {"temperature_c": col},
                {"glass_transition_c": t_g, "temperatures_c": temps.tolist(),
                 "log10_shift_span": float(log_at(temps[0]) - log_at(temps[-1]))},
                ("temperature_c",))
    if effect == "rocking_mode":
        fr = _loguniform(rng, 1.5 * f_n, 200.0)
        zr = _loguniform(rng, 0.01, 0.05)
        wr = 2 * np.pi * fr
        rec0 = 1.0 / (k0 - m * omega**2)
        i_r = int(np.argmin(np.abs(omega - wr)))
        q = _loguniform(rng, 0.1, 1.0)
        mr = 1.0 / (q * abs(rec0[i_r]) * 2 * zr * wr**2)
        rec = rec0 - 1.0 / (mr * (wr**2 - omega**2 + 2j * zr * wr * omega))
        return (_from_receptance(rec, omega, quantity), base, {},
                {"f_r": fr, "zeta_r": zr, "modal_mass": mr, "peak_ratio": q}, ())
    raise ValueError(
        f"effect must be None or one of {LIBRARY_EFFECTS + OUTSIDE_EFFECTS}, got {effect!r}"
    )


def generate_case(effect: str | None, rng: np.random.Generator, *,
                  quantity: str = "receptance", sigma: float | None = None,
                  n_points: int = 300, system: str | None = None,
                  clean_covariate: str | None = None) -> SyntheticCase:
    """Generate one data set hiding ``effect`` (module docstring).

    Parameters
    ----------
    effect : str or None
        One of :data:`LIBRARY_EFFECTS`, :data:`OUTSIDE_EFFECTS`, or None (clean).
    rng : numpy.random.Generator
        ``numpy.random.default_rng(seed)``.
    quantity : str
        ``receptance``, ``accelerance`` or ``stiffness`` (the outside effects need the first
        two).
    sigma : float, optional
        Noise RMS [-] (default uniform in [0.005, 0.02]).
    n_points : int
        Log-spaced points per condition, 3..300 Hz (>= 20).
    system : str, optional
        Base system (default: random from :data:`BASE_SYSTEMS`).
    clean_covariate : {"temperature_c", "excitation_n"}, optional
        Repeat the data set at three levels of this covariate, with no dependence on it
        (clean data at several temperatures or levels; with ``covariate_shift`` or
        ``amplitude_dependence``, a data set with two covariates of which one matters).

    Returns
    -------
    SyntheticCase
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    if quantity not in ("receptance", "accelerance", "stiffness"):
        raise ValueError(f"quantity must be receptance, accelerance or stiffness, "
                         f"got {quantity!r}")
    if not isinstance(n_points, (int, np.integer)) or n_points < 20:
        raise ValueError(f"n_points must be an integer >= 20, got {n_points!r}")
    if sigma is None:
        sigma = float(rng.uniform(0.005, 0.02))
    if not 0 <= sigma < 0.5:
        raise ValueError(f"sigma must be in [0, 0.5), got {sigma}")
    if clean_covariate not in (None, "temperature_c", "excitation_n"):
        raise ValueError(f"clean_covariate must be None, 'temperature_c' or 'excitation_n', "
                         f"got {clean_covariate!r}")
    if clean_covariate is not None and clean_covariate == {
            "amplitude_dependence": "excitation_n", "cubic_stiffness": "excitation_n",
            "covariate_shift": "temperature_c"}.get(effect):
        raise ValueError(f"clean_covariate {clean_covariate!r} is the covariate the effect "
                         f"{effect!r} depends on; choose the other one")
    if effect == "maxwell_element" and system is None:
        system = MAXWELL_ELEMENT_SYSTEMS[rng.integers(len(MAXWELL_ELEMENT_SYSTEMS))]
    if effect in ("fixture_mass", "foundation_mode") and system is None:
        system = LOW_RESONANCE_SYSTEMS[rng.integers(len(LOW_RESONANCE_SYSTEMS))]
    name, model = _base_model(rng, system)
    f = np.geomspace(F_MIN_HZ, F_MAX_HZ, n_points)
    omega = 2 * np.pi * f
    f_n = modal_properties(model).natural_frequency_rad_s / (2 * np.pi)
    for _ in range(100):
        clean, base, cov, params, cols = _draw_effect(effect, rng, model, omega, quantity,
                                                      n_points, f_n)
        size = float(np.sqrt(np.mean(np.abs(clean / base - 1.0) ** 2)))
        if effect is None or size < MIN_EFFECT_SNR * sigma:
            if effect is None:
                break
            continue
        if effect not in ABSORBABLE_EFFECTS:
            break
        left = _left_after_maxwell_fit(model, omega, clean, quantity)
        params = {**params, "left_after_maxwell_fit": left}
        if left >= MIN_EFFECT_SNR * sigma:
            break
    else:
        raise ValueError(f"could not draw a detectable {effect} for sigma = {sigma}")
    freq = np.tile(f, clean.size // f.size)
    if clean_covariate is not None:
        # the whole data set again at each level of a covariate it does not depend on
        levels = (np.asarray(LEVELS_N) if clean_covariate == "excitation_n"
                  else T_REF_C + np.array([-15.0, 0.0, 15.0]))
        size = clean.size
        cov = {**{name: np.tile(col, levels.size) for name, col in cov.items()},
               clean_covariate: np.repeat(levels, size)}
        cols = (*cols, clean_covariate)
        clean, base, freq = (np.tile(a, levels.size) for a in (clean, base, freq))
    eps = sigma / np.sqrt(2) * (rng.standard_normal(clean.size)
                                + 1j * rng.standard_normal(clean.size))
    return SyntheticCase(freq, clean * (1.0 + eps), clean, base, quantity, cov, effect,
                         params, name, model, float(sigma), size, tuple(cols))
