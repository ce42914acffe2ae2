"""Design and in-process evaluation of the per-sample switching c2 law (`dva switching`).

Flights (all in process, :func:`aero_dva.flight.per_sample.flight.fly_switched`, exact ZOH per
1 ms sample, 1 kN white aileron force, seeds shared by both controllers):

- ramp 0.8 -> 1.4 U_cr in 45 s (the study's slope, 0.4 U_cr in 30 s, carried further because
  the law holds beyond 1.2): the *bounded* boundary (``divergence_airspeed``: RMS over 1 s
  windows stays above 10x its start) and the *practical* boundary (first |leading edge| above
  the peak limit, :data:`PEAK_FACTOR` x the fixed damper's leading-edge RMS over the first
  4.5 s, the median over the seeds);
- constant 1.1 U_cr for 20 s: leading-edge RMS (after 2 s), switches per second, damper power.

The reference ``fixed`` is the best constant c2 (the highest eigenvalue flutter airspeed over
the damper's range, :func:`aero_dva.control.dva_design.best_fixed_damping`), flown through the
same stepping code with a law that never switches. Every
comparison is paired by seed: mean and 95 % t-interval of the differences.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import linalg, stats

from aero_dva.control.clipped_optimal import schedule_airspeeds, scheduled_law
from aero_dva.control.switching_design import (
    SCHEDULED_DESIGN,
    desired_force_gain,
    kalman_filter_gain,
    law_gain,
    lead_rows,
    measured_rms,
    middle_damping,
)
from aero_dva.control.switching_io import SwitchingGains
from aero_dva.flight.divergence import divergence_airspeed, ramp_airspeed
from aero_dva.flight.peak_limit import peak_limit_airspeed
from aero_dva.flight.per_sample.flight import fly_switched
from aero_dva.flight.per_sample.switching_law import SwitchingLaw, maxwell_index
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.model import AeroelasticModel

__all__ = ["PEAK_FACTOR", "Setting", "design", "evaluate_setting",
           "mechanism", "paired"]

PEAK_FACTOR = 20.0
RAMP = (0.8, 1.4, 45.0)  # [U_cr], [U_cr], [s]
RMS_POINT = (1.1, 20.0, 2.0)  # [U_cr], flight [s], transient skipped [s]
SAMPLE_RATE = 1000.0
FORCE_STD = 1000.0
#: Density cases of `dva evaluate` (docs/evaluation.md): factor f, mu, f_rho [Hz]. Only the
#: constant ones: a varying density multiplies the held conditions, each with its c2 table
#: (memory grows with their number; the flight keeps every table of the flight at once).
DENSITY_CASES = {"rho0": (1.0, 0.0, 0.0), "x0.9": (0.9, 0.0, 0.0), "x1.1": (1.1, 0.0, 0.0)}


def paired(values) -> dict:
    """Mean and 95 % t-interval of the finite ``values`` (one per seed)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 2:
        return {"n": int(x.size), "mean": float(x.mean()) if x.size else math.nan,
                "low": math.nan, "high": math.nan}
    half = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    mean = float(x.mean())
    return {"n": int(x.size), "mean": mean, "low": mean - half, "high": mean + half}


def fixed_law(model: AeroelasticModel, damping: float) -> SwitchingLaw:
    """A law that never switches (gain 0: F h = 0): c2 = ``damping`` throughout."""
    return SwitchingLaw(np.zeros(model.n_states), damping, damping * (1 + 1e-9))


@dataclasses.dataclass(frozen=True)
class Setting:
    """One evaluated configuration: damper lag, sensor noise, plant mismatch, aerodynamics."""

    name: str
    time_constant: float
    noise: float  # sensor noise std as a fraction of each measured output's RMS at U_cr
    mismatch: float = 0.0  # plant's wing stiffnesses scaled by (1 + mismatch)
    aero: str = "model"  # "model" or "wagner" (the plant's aerodynamics)
    case: str = "rho0"  # density case, :data:`DENSITY_CASES`
    force_limit: float = math.inf  # [N] relief valve of the switched damper (not the fixed's)
    update_every: int = 1  # [samples] between the law's decisions
    yield_force: float = 0.0  # [N] Bingham yield force of both dampers (the same hardware)

    def density(self, rho0: float, n: int) -> np.ndarray:
        """[kg/m^3] per sample: f rho0 (1 + mu sin 2 pi f_rho t) (eq. 7.2)."""
        factor, mu, hz = DENSITY_CASES[self.case]
        t = np.arange(n) / SAMPLE_RATE
        return factor * rho0 * (1.0 + mu * np.sin(2 * np.pi * hz * t))


def plant_of(model: AeroelasticModel, setting: Setting) -> AeroelasticModel:
    """The flown wing: the controller's model with the setting's mismatch and aerodynamics."""
    wing = model.wing
    if setting.mismatch:
        s = 1.0 + setting.mismatch
        wing = wing.replace(plunge_stiffness=wing.plunge_stiffness * s,
                            pitch_stiffness=wing.pitch_stiffness * s)
    aero = WagnerAero() if setting.aero == "wagner" else model.aero
    return AeroelasticModel(wing, model.absorber, aero)


def _forces(seeds, n):
    return np.stack([np.random.default_rng(s).normal(0.0, FORCE_STD, n) for s in seeds])


def _noise(seeds, n, scale):
    if not np.any(scale):
        return None
    return np.stack([np.random.default_rng(10_000 + s).normal(0.0, 1.0, (n, 4)) * scale
                     for s in seeds])


def evaluate_setting(model: AeroelasticModel, gains: SwitchingGains, setting: Setting,
                     seeds, u_cr: float, fixed_c2: float, sensor_rms: np.ndarray) -> dict:
    """Fixed vs switching on the paired ``seeds`` for one setting (module docstring)."""
    plant = plant_of(model, setting)
    law = gains.law
    observer_model = model if law.observer is not None else plant
    start, stop, duration = RAMP
    u = ramp_airspeed(u_cr, start, stop, duration, SAMPLE_RATE)
    force = _forces(seeds, u.size)
    noise = _noise(seeds, u.size, setting.noise * sensor_rms)
    rho = setting.density(gains.density, u.size)
    fixed = fly_switched(plant, fixed_law(plant, fixed_c2), u, rho, force, time_constant=0.0,
                         initial_damping=fixed_c2, yield_force=setting.yield_force)
    switched = fly_switched(plant, law, u, rho, force, observer_model=observer_model,
                            time_constant=setting.time_constant, noise=noise,
                            force_limit=setting.force_limit,
                            update_every=setting.update_every,
                            yield_force=setting.yield_force)
    n_base = int(0.1 * u.size)
    limit = PEAK_FACTOR * float(np.median(np.sqrt(np.mean(fixed.leading_edge[:, :n_base] ** 2,
                                                          axis=1))))
    bounded = {k: divergence_airspeed(u, f.leading_edge) / u_cr
               for k, f in (("fixed", fixed), ("switching", switched))}
    practical = {k: peak_limit_airspeed(u, f.leading_edge, limit) / u_cr
                 for k, f in (("fixed", fixed), ("switching", switched))}
    ratio, flight_s, skip_s = RMS_POINT
    n = int(flight_s * SAMPLE_RATE)
    skip = int(skip_s * SAMPLE_RATE)
    force = _forces(seeds, n)
    noise = _noise(seeds, n, setting.noise * sensor_rms)
    rho = setting.density(gains.density, n)
    fixed_c = fly_switched(plant, fixed_law(plant, fixed_c2), ratio * u_cr, rho, force,
                           time_constant=0.0, initial_damping=fixed_c2,
                           yield_force=setting.yield_force)
    sw_c = fly_switched(plant, law, ratio * u_cr, rho, force, observer_model=observer_model,
                        time_constant=setting.time_constant, noise=noise,
                        force_limit=setting.force_limit,
                        update_every=setting.update_every, yield_force=setting.yield_force)
    # A fixed damper that flutters at this airspeed has no RMS to compare with: such seeds
    # (the last 2 s above 10x the RMS of the 2 s after the transient) are left out.
    bounded_f = (np.sqrt(np.mean(fixed_c.leading_edge[:, -2 * skip:] ** 2, axis=1))
                 < 10 * np.sqrt(np.mean(fixed_c.leading_edge[:, skip:2 * skip] ** 2, axis=1)))
    rms_f = np.sqrt(np.mean(fixed_c.leading_edge[:, skip:] ** 2, axis=1))
    rms_s = np.sqrt(np.mean(sw_c.leading_edge[:, skip:] ** 2, axis=1))
    power_f = fixed_c.damper_power[:, skip:].mean(axis=1)
    power_s = sw_c.damper_power[:, skip:].mean(axis=1)
    switches = np.count_nonzero(np.diff(sw_c.target[:, skip:], axis=1), axis=1) / (
        (n - skip - 1) / SAMPLE_RATE)

    def mean(x):
        x = np.asarray(x, dtype=float)
        return float(np.nanmean(x)) if np.isfinite(x).any() else math.nan

    return {
        "setting": dataclasses.asdict(setting),
        "seeds": len(seeds),
        "peak_limit_m": limit,
        "bounded": {"fixed": mean(bounded["fixed"]), "switching": mean(bounded["switching"]),
                    "difference": paired(bounded["switching"] - bounded["fixed"]),
                    "not_diverged": {k: int(np.isnan(v).sum()) for k, v in bounded.items()}},
        "practical": {"fixed": mean(practical["fixed"]),
                      "switching": mean(practical["switching"]),
                      "difference": paired(practical["switching"] - practical["fixed"]),
                      "not_reached": {k: int(np.isnan(v).sum()) for k, v in practical.items()}},
        "rms_at_1.1": {"fixed_m": mean(rms_f[bounded_f]), "switching_m": mean(rms_s[bounded_f]),
                       "change": paired((rms_s / rms_f - 1.0)[bounded_f]),
                       "fixed_fluttered": int(np.count_nonzero(~bounded_f))},
        "switches_per_second": paired(switches),
        "damper_power_w": {"fixed": mean(power_f[bounded_f]),
                           "switching": mean(power_s[bounded_f]),
                           "ratio": paired((power_s / power_f)[bounded_f])},
    }


def design(model: AeroelasticModel, fingerprint: str, density: float, u_cr: float,
           fixed_c2: float, *, design_name: str, design_ratio: float, c_lo: float,
           c_hi: float, time_constant: float, efforts, leads, seeds, noise: float,
           progress=None) -> tuple[SwitchingGains, np.ndarray]:
    """Gains for ``model``: observer from the model, law gain of each candidate ``effort`` and
    ``lead`` [s] (F and h on the state predicted that far ahead) flown on the ramp with the
    given lag and sensor noise, the best practical boundary kept.

    Returns the gains and the sensor RMS scale (4,) the noise fraction refers to.
    """
    sensor_rms = measured_rms(model, u_cr, density, fixed_c2, SAMPLE_RATE, FORCE_STD)
    airspeed = design_ratio * u_cr
    observer = kalman_filter_gain(model, airspeed, density, middle_damping(c_lo, c_hi),
                                  SAMPLE_RATE, FORCE_STD, np.maximum(noise, 0.01) * sensor_rms)
    setting = Setting("design", time_constant, noise)
    selection = []
    best = None
    for effort, lead in [(e, t) for e in efforts for t in leads]:
        if design_name == SCHEDULED_DESIGN:  # rows at every airspeed of the schedule
            law = scheduled_law(model, schedule_airspeeds(u_cr), density, c_lo, c_hi,
                                effort=effort, lead=lead, observer=observer)
        else:
            gain = law_gain(model, airspeed, density, c_lo, c_hi, design=design_name,
                            effort=effort)
            force_gain, gain = lead_rows(model, airspeed, density, c_lo, c_hi, gain, lead)
            law = SwitchingLaw(gain, c_lo, c_hi, observer, force_gain if lead else None)
        gains = SwitchingGains(law=law, design=design_name, wing_fingerprint=fingerprint,
                               design_airspeed=airspeed, density=density,
                               time_constant=time_constant, sample_rate=SAMPLE_RATE,
                               effort=float(effort), state_names=model.state_names,
                               lead=float(lead))
        row = evaluate_setting(model, gains, setting, seeds, u_cr, fixed_c2, sensor_rms)
        entry = {"effort": float(effort), "lead": float(lead),
                 "practical_switching": row["practical"]["switching"],
                 "practical_fixed": row["practical"]["fixed"],
                 "bounded_switching": row["bounded"]["switching"],
                 "rms_change_at_1.1": row["rms_at_1.1"]["change"]["mean"]}
        selection.append(entry)
        if progress:
            progress(entry)
        score = entry["practical_switching"]
        if best is None or (math.isfinite(score) and not score <= best[0]):
            best = (score, gains)
    chosen = dataclasses.replace(
        best[1], selection=selection,
        description=(f"{design_name} switching law designed at {design_ratio:g} U_cr "
                     f"(U_cr {u_cr:.3f} m/s"
                     + ("; the law's rows at 0.6..1.6 U_cr, its observer there"
                        if design_name == SCHEDULED_DESIGN else "")
                     + f"), c2 {c_lo:g}/{c_hi:g} N s/m, lag "
                     f"{time_constant:g} s; effort and lead chosen by the practical boundary of "
                     f"{len(seeds)} ramp flights; best constant c2 {fixed_c2:.1f} N s/m"))
    return chosen, sensor_rms


def _stationary(a, b, row, force_std: float) -> tuple[float, float]:
    """(least stable eigenvalue's real part [1/s], stationary RMS of ``row @ x``) of
    x' = a x + b f under a white force of ``force_std`` per sample (intensity std^2 / rate)."""
    growth = float(np.max(np.linalg.eigvals(a).real))
    if growth >= 0:
        return growth, math.inf
    cov = linalg.solve_continuous_lyapunov(a, -force_std**2 / SAMPLE_RATE * np.outer(b, b))
    return growth, float(math.sqrt(row @ cov @ row))


def mechanism(model: AeroelasticModel, laws: dict, u_cr: float, fixed_c2: float, seeds,
              sensor_rms: np.ndarray, effort: float, ratio: float = 1.1,
              noise: float = 0.05) -> dict:
    """What the per-sample laws do at ``ratio`` U_cr against the ideal force they approximate.

    ``ideal``: the desired force f_c = -K x of the clipped-optimal design at ``effort``
    applied exactly in place of the Maxwell element (its closed loop's least stable
    eigenvalue, stationary leading-edge RMS, force RMS, and the share of time it absorbs
    power: F times the stroke rate > 0, from its correlation with the stroke rate, Gaussian);
    ``fixed``: the best constant c2 the same way. ``flown``: per law of ``laws`` (name ->
    SwitchingGains) and for the constant c2, 20 s at ``ratio`` U_cr on ``seeds`` (2 s of
    transient left out; the laws with their lag and ``noise``): leading-edge RMS, RMS of the
    damper force F and of f_c on the true state, their correlation, the share of samples at
    c_hi, damper power, mean c2."""
    rho = next(iter(laws.values())).density if laws else 1.2
    speed = ratio * u_cr
    idx = maxwell_index(model)
    k2 = model.absorber.series_stiffness
    keep = [i for i in range(model.n_states) if i != idx]
    a, b = model.matrices(speed, rho, 1000.0)
    k = desired_force_gain(model, speed, rho, effort)
    b_f = a[keep, idx] / k2
    a_cl = a[np.ix_(keep, keep)] - np.outer(b_f, k[keep])
    growth, rms = _stationary(a_cl, b[keep], model.c_displacement[2][keep], FORCE_STD)
    cov = linalg.solve_continuous_lyapunov(a_cl, -FORCE_STD**2 / SAMPLE_RATE
                                           * np.outer(b[keep], b[keep]))
    stroke_rate = (model.c_displacement[3] @ a)[keep]  # d/dt of the absorber stroke
    f_row = -k[keep]
    corr = float(f_row @ cov @ stroke_rate / math.sqrt((f_row @ cov @ f_row)
                                                       * (stroke_rate @ cov @ stroke_rate)))
    ideal = {"effort": effort, "least_stable_real_part": growth, "leading_edge_rms_m": rms,
             "force_rms_n": float(math.sqrt(f_row @ cov @ f_row)),
             "force_stroke_rate_correlation": corr,
             "absorbing_share": 0.5 + math.asin(corr) / math.pi}
    a_f, b_fix = model.matrices(speed, rho, fixed_c2)
    growth_f, rms_f = _stationary(a_f, b_fix, model.c_displacement[2], FORCE_STD)
    _, flight_s, skip_s = RMS_POINT
    n, skip = int(flight_s * SAMPLE_RATE), int(skip_s * SAMPLE_RATE)
    force = _forces(seeds, n)
    flown = {}
    for name, gains in {**laws, "fixed": None}.items():
        if gains is None:
            f = fly_switched(model, fixed_law(model, fixed_c2), speed, rho, force,
                             time_constant=0.0, initial_damping=fixed_c2, keep_states=True)
        else:
            f = fly_switched(model, gains.law, speed, rho, force,
                             time_constant=gains.time_constant,
                             noise=_noise(seeds, n, noise * sensor_rms), keep_states=True)
        x = f.states[:, skip:]
        damper_force, wanted = k2 * x[..., idx], -(x @ k)
        flown[name] = {
            "leading_edge_rms_m": float(np.mean(np.sqrt(np.mean(
                f.leading_edge[:, skip:] ** 2, axis=1)))),
            "damper_force_rms_n": float(np.sqrt(np.mean(damper_force ** 2))),
            "desired_force_rms_n": float(np.sqrt(np.mean(wanted ** 2))),
            "force_correlation": float(np.corrcoef(damper_force.ravel(), wanted.ravel())[0, 1]),
            "share_at_c_hi": float(np.mean(f.target[:, skip:])) if gains is not None
            else math.nan,
            "damper_power_w": float(np.mean(f.damper_power[:, skip:])),
            "mean_c2": float(np.mean(f.damping[:, skip:])),
        }
    reference = flown["fixed"]["leading_edge_rms_m"]
    for name in laws:
        flown[name]["share_of_ideal_gain"] = (
            (reference - flown[name]["leading_edge_rms_m"]) / (reference - rms))
    return {"airspeed_ratio": ratio, "seeds": len(seeds), "ideal": ideal,
            "fixed": {"c2": fixed_c2, "least_stable_real_part": growth_f,
                      "leading_edge_rms_m": rms_f},
            "flown": flown}
