"""Test data whose effect follows a law outside the library's fixed forms (and files with
no effect at all), for the laws the loop finds from its per-condition fits (:mod:`.laws`).

Separate from the loop on purpose: each law is coded from its physics, never with the
candidates' formulas. Magnitudes are drawn at random (redrawn until the noise-free change
is >= 3 sigma RMS); noise H (1 + eps), E|eps|^2 = sigma^2, sigma 0.5-2 % unless given.

Isolator mounts (``frf`` domain; a base system of :mod:`.synthetic`, 3-300 Hz, receptance):

* ``power_level``: five excitation levels 2-20 N (``excitation_n``); the storage stiffness
  changes as a power of the level, K'(a) = K'_lin (1 + d (a / 20 N)^e), e in 0.5..3,
  hardening (d > 0) or softening (d < 0), 3-20 % over the levels; the loss part likewise
  with its own exponent and 0-30 % (half of the cases without); the base system is the
  mount at the middle (nominal) level, as in :mod:`.synthetic`. Expected name:
  ``amplitude_dependence``.
* ``temperature_kink``: five temperatures 23 C +- 2 x (4-6 K) (``temperature_c``); the
  frequency axis shifts by log10 a_T = -b (T - 23 C) below 23 C and -b r (T - 23 C) above,
  b 0.02-0.04 /K, r 1.6-2.5 (0.3-1.7 decades in all): a kink that steepens with
  temperature, which neither WLF nor Arrhenius (both flatten with temperature) can follow.
  Expected: ``covariate_shift``.
* ``phase_offset``: one sweep whose phase is off by a constant 4-15 deg (an instrument's
  phase, e.g. a charge amplifier's), magnitude unchanged: no delay produces it (a delay's
  phase is zero at 0 Hz). Expected: no ``sensor_delay``; nothing in the library is it.

Structures (``modal`` domain; :mod:`.structure_synthetic`'s 3 modes, 5-200 Hz, accelerance,
levels 2-20 N recorded with 1 % scatter and a ``set`` column):

* ``structure_power_level``: one or two modes stiffen or soften as w_r^2 (1 + d (a/20 N)^e),
  e in 0.5..3, the frequency change 1-4 % over the levels, each mode with its own exponent;
  damping ratio rising as (1 + q (a / 20 N)^e_z), q in 0..1. Expected:
  ``amplitude_dependence``.
* ``structure_joint_slip``: one mode's stiffness drops by 3-10 % between two adjacent levels
  (a bolted joint that slips above some force) and its damping rises x 1.5-3 there; no
  smooth law follows a step. Expected: ``amplitude_dependence``.
* ``structure_phase``: one mode in a band of +- 4 half-power bandwidths (as a stepped sine
  around a resonance), its modal constant complex (phase 15-60 deg, either sign): in so
  narrow a band a delay matches it only through phase wraps. Expected: no
  ``sensor_delay``.

No effect: ``structure_clean`` (the 3 modes at four levels, no dependence) and
``replicates`` / ``structure_replicates`` (three sweeps of one nominal level, the level
recorded with 1 % scatter per point, a ``set`` column; a mount of :mod:`.synthetic` or
the 3 modes). Expected: ``consistent`` or ``no_covariate_effect``.
"""
from __future__ import annotations

import numpy as np

from dva_offline.discrepancy import structure_synthetic as ss
from dva_offline.discrepancy import synthetic
from dva_offline.isolator.maxwell_model import dynamic_stiffness

FRF_LAWS = ("power_level", "temperature_kink", "phase_offset")
STRUCTURE_LAWS = ("structure_power_level", "structure_joint_slip", "structure_phase")
NO_EFFECT = ("replicates", "structure_clean", "structure_replicates")
CASES = (*FRF_LAWS, *STRUCTURE_LAWS, *NO_EFFECT)
# the name the loop should give (None: no effect to name; phase cases: anything but a delay)
EXPECTED = {"power_level": "amplitude_dependence", "temperature_kink": "covariate_shift",
            "phase_offset": None, "structure_power_level": "amplitude_dependence",
            "structure_joint_slip": "amplitude_dependence", "structure_phase": None,
            "replicates": None, "structure_clean": None, "structure_replicates": None}
LEVELS_N = tuple(float(x) for x in np.geomspace(2.0, 20.0, 4))
FRF_LEVELS_N = tuple(float(x) for x in np.geomspace(2.0, 20.0, 5))
A_TOP = 20.0
T_REF_C = 23.0


def domain_of(case: str) -> str:
    """``frf`` or ``modal``: the domain a case is analysed in."""
    if case not in CASES:
        raise ValueError(f"case must be one of {CASES}, got {case!r}")
    return "modal" if case.startswith("structure") else "frf"


def _noise(rng, clean, sigma):
    eps = sigma / np.sqrt(2) * (rng.standard_normal(clean.size)
                                + 1j * rng.standard_normal(clean.size))
    return clean * (1.0 + eps)


def _size(clean, base):
    return float(np.sqrt(np.mean(np.abs(clean / base - 1.0) ** 2)))


def _scattered(rng, nominal, n):
    """Per-point recorded levels of sweeps at ``nominal`` levels: 1 % RMS scatter."""
    value = np.repeat(np.asarray(nominal, float), n)
    return value * (1 + 0.01 * rng.standard_normal(value.size))


def _frf_case(case, rng, sigma, n_points):
    name, model = synthetic._base_model(rng, None)
    f = np.geomspace(synthetic.F_MIN_HZ, synthetic.F_MAX_HZ, n_points)
    m = model.mass
    for _ in range(200):
        params: dict = {}
        if case == "power_level":
            nominal = FRF_LEVELS_N
            cov_name = "excitation_n"
            col = np.repeat(np.asarray(nominal), f.size)
            w = 2 * np.pi * np.tile(f, len(nominal))
            e, e_l = rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0)
            u = (col / A_TOP)
            u_nom = np.asarray(nominal) / A_TOP
            change = rng.uniform(0.03, 0.2) * rng.choice([-1.0, 1.0])
            d = change / (u_nom[-1] ** e - u_nom[0] ** e)
            loss = rng.uniform(0.0, 0.3) if rng.uniform() < 0.5 else 0.0
            d_l = loss / (u_nom[-1] ** e_l - u_nom[0] ** e_l)
            if np.any(1 + d * u_nom**e <= 0.2):
                continue
            # the base mount is the one at the nominal (middle) level, as in synthetic
            g0, h0 = 1 + d * u_nom[2] ** e, 1 + d_l * u_nom[2] ** e_l
            k = dynamic_stiffness(w, model.k, model.c, model.maxwell_k, model.maxwell_c)
            stiff = k.real * (1 + d * u**e) / g0 + 1j * k.imag * (1 + d_l * u**e_l) / h0
            clean = synthetic._measure(stiff, w, m, "receptance")
            base = synthetic._measure(k, w, m, "receptance")
            params = {"exponent": float(e), "d": float(d), "storage_change": float(change),
                      "loss_exponent": float(e_l), "d_loss": float(d_l),
                      "loss_change": float(loss)}
            cov = {cov_name: col}
        elif case == "temperature_kink":
            step = rng.uniform(4.0, 6.0)
            temps = T_REF_C + step * np.arange(-2, 3)
            col = np.repeat(temps, f.size)
            w = 2 * np.pi * np.tile(f, temps.size)
            b, r = rng.uniform(0.02, 0.04), rng.uniform(1.6, 2.5)
            dt = col - T_REF_C
            log_at = np.where(dt < 0, -b * dt, -b * r * dt)
            k = dynamic_stiffness(w * 10.0**log_at, model.k, model.c, model.maxwell_k,
                                  model.maxwell_c)
            clean = synthetic._measure(k, w, m, "receptance")
            base = synthetic._measure(dynamic_stiffness(w, model.k, model.c, model.maxwell_k,
                                                        model.maxwell_c), w, m, "receptance")
            params = {"slope_below": float(b), "slope_above": float(b * r),
                      "temperatures_c": temps.tolist()}
            cov = {"temperature_c": col}
        elif case == "phase_offset":
            w = 2 * np.pi * f
            phi = np.radians(rng.uniform(4.0, 15.0)) * rng.choice([-1.0, 1.0])
            base = synthetic._measure(synthetic._stiffness(model, w), w, m, "receptance")
            clean = base * np.exp(1j * phi)
            params = {"phase_deg": float(np.degrees(phi))}
            cov = {}
        elif case == "replicates":
            nominal = (synthetic.LEVELS_N[1],) * 3
            w = 2 * np.pi * np.tile(f, 3)
            base = synthetic._measure(synthetic._stiffness(model, w), w, m, "receptance")
            clean = base
            cov = {"excitation_n": _scattered(rng, nominal, f.size),
                   "set": np.repeat(np.arange(3.0), f.size)}
            break
        if _size(clean, base) >= synthetic.MIN_EFFECT_SNR * sigma:
            break
    else:
        raise ValueError(f"could not draw a detectable {case} for sigma = {sigma}")
    freq = np.tile(f, clean.size // f.size)
    columns = tuple(c for c in cov if c != "set") if "set" not in cov else ("set",)
    return synthetic.SyntheticCase(freq, _noise(rng, clean, sigma), clean, base, "receptance",
                                   cov, case, params, name, model, float(sigma),
                                   _size(clean, base), columns)


def _structure_case(case, rng, sigma, n_points):
    n_modes = 3
    fr = ss._modes(rng, n_modes)
    zr = np.exp(rng.uniform(np.log(0.01), np.log(0.04), n_modes))
    ar = 1.0 / np.exp(rng.uniform(np.log(0.5), np.log(5.0), n_modes))
    nominal = LEVELS_N
    if case == "structure_replicates":
        nominal = (LEVELS_N[1],) * 3
    if case == "structure_phase":
        # one mode, a narrow band around it (a stepped sine at its resonance)
        r = int(rng.integers(n_modes))
        fr, zr, ar = fr[r:r + 1], zr[r:r + 1], ar[r:r + 1]
        half = 4 * 2 * zr[0] * fr[0]
        f = np.linspace(fr[0] - half, fr[0] + half, n_points // 4)
        nominal = (None,)
    else:
        f = np.linspace(5.0, 200.0, n_points)
    sweeps = len(nominal)
    freq = np.tile(f, sweeps)
    cov = {}
    if nominal[0] is not None:
        cov = {"excitation_n": _scattered(rng, nominal, f.size),
               "set": np.repeat(np.arange(float(sweeps)), f.size)}
    base = ss._receptance(freq, fr, zr, ar, 1.0, 1.0)
    for _ in range(200):
        f_fac = np.ones((fr.size, freq.size))
        z_fac = np.ones((fr.size, freq.size))
        a_c = ar.astype(complex)
        params: dict = {}
        if case == "structure_power_level":
            u = cov["excitation_n"] / A_TOP
            u_nom = np.asarray(nominal) / A_TOP
            modes = rng.choice(fr.size, size=int(rng.integers(1, 3)), replace=False)
            params = {"modes": []}
            for r in modes:
                e = rng.uniform(0.5, 3.0)
                change = rng.uniform(0.01, 0.04) * rng.choice([-1.0, 1.0])  # frequency
                d = ((1 + change) ** 2 - 1) / (u_nom[-1] ** e - u_nom[0] ** e)
                if np.any(1 + d * u_nom**e <= 0.5):
                    d = -0.5 / u_nom[-1] ** e
                e_z, q = rng.uniform(0.5, 3.0), rng.uniform(0.0, 1.0)
                f_fac[r] = np.sqrt((1 + d * u**e) / (1 + d * u_nom[1] ** e))
                z_fac[r] = (1 + q * u**e_z) / (1 + q * u_nom[1] ** e_z)
                params["modes"].append({"mode": int(r) + 1, "mode_hz": float(fr[r]),
                                        "exponent": float(e), "d": float(d),
                                        "frequency_change": float(change),
                                        "damping_exponent": float(e_z), "q": float(q)})
        elif case == "structure_joint_slip":
            r = int(rng.integers(fr.size))
            step = int(rng.integers(1, sweeps))  # slipped from this level on
            drop, rise = rng.uniform(0.03, 0.1), rng.uniform(1.5, 3.0)
            slipped = cov["set"] >= step
            f_fac[r] = np.where(slipped, np.sqrt(1 - drop), 1.0)
            z_fac[r] = np.where(slipped, rise, 1.0)
            params = {"mode": r + 1, "mode_hz": float(fr[r]), "slip_from_level":
                      float(nominal[step]), "stiffness_drop": float(drop),
                      "damping_factor": float(rise)}
        elif case == "structure_phase":
            phi = np.radians(rng.uniform(15.0, 60.0)) * rng.choice([-1.0, 1.0])
            a_c = a_c * np.exp(1j * phi)
            params = {"mode_hz": float(fr[0]), "phase_deg": float(np.degrees(phi))}
        w = 2 * np.pi * freq
        wr = 2 * np.pi * fr[:, None] * f_fac
        clean = np.sum(a_c[:, None] / (wr**2 - w**2 + 2j * zr[:, None] * z_fac * wr * w),
                       axis=0)
        if case in NO_EFFECT or _size(clean, base) >= synthetic.MIN_EFFECT_SNR * sigma:
            break
    else:
        raise ValueError(f"could not draw a detectable {case} for sigma = {sigma}")
    values = ss._convert(_noise(rng, clean, sigma), freq, "accelerance")
    return ss.StructureCase(freq, values, "accelerance", cov, case, params, tuple(fr.tolist()),
                            float(sigma), _size(clean, base), ("set",) if cov else ())


def generate(case: str, rng: np.random.Generator, *, sigma: float | None = None,
             n_points: int = 300):
    """One data set of ``case`` (module docstring): a
    :class:`~dva_offline.discrepancy.synthetic.SyntheticCase` (``frf`` cases) or a
    :class:`~dva_offline.discrepancy.structure_synthetic.StructureCase` (structures)."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (numpy.random.default_rng(seed))")
    if sigma is None:
        sigma = float(rng.uniform(0.005, 0.02))
    if not 0 <= sigma < 0.5:
        raise ValueError(f"sigma must be in [0, 0.5), got {sigma}")
    if not isinstance(n_points, (int, np.integer)) or n_points < 40:
        raise ValueError(f"n_points must be an integer >= 40, got {n_points!r}")
    if domain_of(case) == "frf":
        return _frf_case(case, rng, sigma, n_points)
    return _structure_case(case, rng, sigma, 400 if n_points == 300 else n_points)
