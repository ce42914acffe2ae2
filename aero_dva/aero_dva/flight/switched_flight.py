"""A flight with the Maxwell DVA's c2 switched every sample by state feedback (no ROS).

The law runs where a real semi-active damper runs it, in the damper's own controller, once per
sample: from an estimate ``x`` of the state it sets the target

    c2 = c_hi  when  F(x) h(x) > 0,  else c_lo,      F = k2 delta (the damper force),

with ``h = gain @ x`` linear in the state (:mod:`aero_dva.control.switching_design` designs the
gain). The damper follows its target through a first-order lag ``tau`` (exact for a target held
over a sample); the command acts from the sample after the one it was computed on.

Stepping exactly with a c2 that changes every sample. ``c2`` enters the model only through the
Maxwell relaxation rate ``k2 / c2``, so each sample is an exact zero-order-hold step of the
model at the c2 acting over it. Without lag c2 takes two values: both steps are precomputed.
With a lag c2 is continuous; the choice here is a table of ``levels`` c2 values spaced evenly in
log c2 between c_lo and c_hi, every step precomputed, and each sample flown with the level
nearest (in log c2) to the lag's mean over the sample: with the default 65 levels between 100
and 2500 N s/m the c2 acting is within 2.5 % of the lagged c2, far inside the accuracy of the
damper's model, and the flight stays a table look-up and one matrix-vector product per sample.

The estimate comes from a fixed-gain Kalman filter of the measured signals (the absorber stroke
and the three accelerations, with sensor noise), run on an observer model that may differ from
the flown plant (model mismatch). Plant, filter and law are one linear map per c2 level applied
to ``[x; x_pred; force; noise]``; airspeed and density are held every ``hold`` samples as the
other simulators hold them (:func:`~aero_dva.flight.discrete_model.next_held`). Pure numerics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.flight.discrete_model import DEFAULT_HOLD, next_held
from aero_dva.flight.discretize import zoh
from aero_dva.wing.absorbers import MaxwellAbsorber
from aero_dva.wing.checks import positive
from aero_dva.wing.model import AeroelasticModel

__all__ = [
    "MEASURED_OUTPUTS",
    "SwitchedFlight",
    "SwitchingLaw",
    "c2_levels",
    "fly_switched",
    "maxwell_index",
    "measurement_matrices",
]

#: Rows of the discrete model's outputs the damper's controller measures: the absorber stroke
#: [m] and the plunge [m/s^2], pitch [rad/s^2] and leading-edge [m/s^2] accelerations.
MEASURED_OUTPUTS = ("absorber_stroke", "plunge_acceleration", "pitch_acceleration",
                    "leading_edge_acceleration")
DEFAULT_LEVELS = 65
#: Relative airspeed and density change below which a held value is kept, the batch
#: simulator's (0.2 m/s at 100 m/s): each held condition costs a c2 table of discretisations.
BATCH_QUANTUM = 2e-3


@dataclass(frozen=True)
class SwitchingLaw:
    """The per-sample law and its observer, as the damper's controller holds them.

    Attributes
    ----------
    gain : (n,)
        ``h = gain @ x`` on the observer model's state.
    c_lo, c_hi : float
        [N s/m] the two targets, ``0 < c_lo < c_hi``.
    observer : (n, 4) or None
        Filter gain on :data:`MEASURED_OUTPUTS` (``x = x_pred + observer (y - C x_pred)``);
        None: the law sees the plant's true state (the plant and observer models must then be
        the same).
    force_gain : (n,) or None
        ``F = force_gain @ x``; None: the damper force k2 delta. A design that leads the
        damper's lag evaluates F and h on the state predicted ahead (both rows times the
        model's transition matrix over the lead).
    """

    gain: np.ndarray
    c_lo: float
    c_hi: float
    observer: np.ndarray | None = None
    force_gain: np.ndarray | None = None

    def __post_init__(self):
        gain = np.asarray(self.gain, dtype=float)
        if gain.ndim != 1 or not np.all(np.isfinite(gain)):
            raise ValueError("gain must be a finite vector")
        lo, hi = float(self.c_lo), float(self.c_hi)
        if not (math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"need 0 < c_lo < c_hi (finite), got ({lo}, {hi}) N s/m")
        object.__setattr__(self, "gain", gain)
        object.__setattr__(self, "c_lo", lo)
        object.__setattr__(self, "c_hi", hi)
        if self.observer is not None:
            obs = np.asarray(self.observer, dtype=float)
            if obs.shape != (gain.size, len(MEASURED_OUTPUTS)) or not np.all(np.isfinite(obs)):
                raise ValueError(f"observer must be a finite ({gain.size}, "
                                 f"{len(MEASURED_OUTPUTS)}) matrix")
            object.__setattr__(self, "observer", obs)
        if self.force_gain is not None:
            fg = np.asarray(self.force_gain, dtype=float)
            if fg.shape != gain.shape or not np.all(np.isfinite(fg)):
                raise ValueError(f"force_gain must be a finite vector of {gain.size} entries")
            object.__setattr__(self, "force_gain", fg)


def maxwell_index(model: AeroelasticModel) -> int:
    """State index of the Maxwell spring deflection ``delta`` (F = k2 delta)."""
    if not isinstance(model.absorber, MaxwellAbsorber):
        raise ValueError("the switching law needs a Maxwell absorber")
    return model.state_names.index("maxwell_deflection")


def c2_levels(c_lo: float, c_hi: float, time_constant: float,
              levels: int = DEFAULT_LEVELS) -> np.ndarray:
    """The c2 values flown: the two targets without lag, else ``levels`` values evenly spaced
    in log c2 (module docstring)."""
    if time_constant == 0.0:
        return np.array([c_lo, c_hi])
    if int(levels) < 2:
        raise ValueError(f"levels must be >= 2, got {levels}")
    return np.geomspace(c_lo, c_hi, int(levels))


def measurement_matrices(model: AeroelasticModel, airspeed, density, damping):
    """``C`` (..., 4, n) and ``D`` (..., 4) of :data:`MEASURED_OUTPUTS` (force input)."""
    a, b = model.matrices(airspeed, density, damping)
    c_acc, d_acc = model.acceleration_output(a, b)
    stroke = np.broadcast_to(model.c_displacement[3], a.shape[:-2] + (1, a.shape[-1]))
    c = np.concatenate([stroke, c_acc], axis=-2)
    d = np.concatenate([np.zeros(a.shape[:-2] + (1,)), d_acc], axis=-1)
    return c, d


@dataclass(frozen=True)
class SwitchedFlight:
    """What a switched flight did, per sample.

    Attributes
    ----------
    leading_edge : (N,) [m]
    stroke : (N,) [m] absorber stroke
    damping : (N,) [N s/m] c2 flown over each sample (a table level)
    target : (N,) bool, True where the target was c_hi
    damper_power : (N,) [W] power the damper dissipates, F^2 / c2
    """

    leading_edge: np.ndarray
    stroke: np.ndarray
    damping: np.ndarray
    target: np.ndarray
    damper_power: np.ndarray
    sample_rate: float

    @property
    def switches_per_second(self) -> float:
        """Target changes per second of flight."""
        changes = np.count_nonzero(self.target[1:] != self.target[:-1])
        return changes * self.sample_rate / max(1, self.target.size - 1)

    def dissipated(self, stop: int | None = None) -> float:
        """[J] energy the damper dissipated over the first ``stop`` samples (all: None)."""
        return float(np.sum(self.damper_power[:stop]) / self.sample_rate)


def _steps(model: AeroelasticModel, conditions: np.ndarray, levels: np.ndarray, dt: float):
    """``Ad`` (K, L, n, n), ``Bd`` (K, L, n) at the held conditions ``conditions`` (K, 2) and
    each c2 level, and the measurement ``C`` (K, 4, n), ``D`` (K, 4), in one batch."""
    k, nl = conditions.shape[0], levels.size
    speeds = np.repeat(conditions[:, 0], nl)
    rhos = np.repeat(conditions[:, 1], nl)
    a, b = model.matrices_unchecked(speeds, rhos, np.tile(levels, k))
    ad, bd = zoh(a, b, dt)
    n = a.shape[-1]
    a, b = a.reshape(k, nl, n, n)[:, 0], b.reshape(k, nl, n)[:, 0]
    c_acc, d_acc = model.acceleration_output(a, b)
    c = np.concatenate([np.broadcast_to(model.c_displacement[3], (k, 1, n)), c_acc], axis=1)
    d = np.concatenate([np.zeros((k, 1)), d_acc], axis=1)
    return ad.reshape(k, nl, n, n), bd.reshape(k, nl, n), c, d


def _condition_maps(plant, observer_model, law, conditions, levels, dt):
    """Per held condition and level, ``T`` with ``[x; p; F~; h~] = T [x; p; F~; h~; f; noise]``
    (the last two rows the state part of the next sample's (F, h)), and ``G`` (K, 2, 5) the
    input part of (F, h): the law's F and h at sample i+1 are ``T``'s last rows plus
    ``G @ [f; noise]`` of sample i+1."""
    ap, bp, cp, dp = _steps(plant, conditions, levels, dt)
    kc, nl, n = ap.shape[0], levels.size, plant.n_states
    nv = 1 + len(MEASURED_OUTPUTS)
    if law.observer is None:
        m = 0
        est = np.zeros((kc, n, n + nv))
        est[:, :, :n] = np.eye(n)
        fh_model, fh_state = plant, est
        ao = None
    else:
        same = observer_model is plant
        ao, _, co, _ = (ap, bp, cp, dp) if same else _steps(observer_model, conditions,
                                                             levels, dt)
        m = observer_model.n_states
        obs = law.observer
        # Filtered estimate e = p + M (y - C_o p), y = C_p x + D_p f + noise, as a map of v.
        est = np.zeros((kc, m, n + m + nv))
        est[:, :, :n] = obs @ cp
        est[:, :, n:n + m] = np.eye(m) - obs @ co
        est[:, :, n + m] = dp @ obs.T
        est[:, :, n + m + 1:] = obs
        fh_model, fh_state = observer_model, est
    width = n + m
    fh = np.zeros((kc, 2, width + nv))
    if law.force_gain is None:
        fh[:, 0] = fh_model.absorber.series_stiffness * fh_state[:, maxwell_index(fh_model)]
    else:
        fh[:, 0] = law.force_gain @ fh_state
    fh[:, 1] = law.gain @ fh_state
    # The (F, h) of the next sample from the next state: their state part rides along.
    step = np.zeros((kc, nl, width, width + 2 + nv))
    step[:, :, :n, :n] = ap
    step[:, :, :n, width + 2] = bp
    if ao is not None:
        step[:, :, n:, :width] = ao @ est[:, None, :, :width]
        step[:, :, n:, width + 2:] = ao @ est[:, None, :, width:]
    t = np.zeros((kc, nl, width + 2, width + 2 + nv))
    t[..., :width, :] = step
    t[..., width:, :] = fh[:, None, :, :width] @ step
    return t, fh[:, :, width:], fh[:, :, :width]


def fly_switched(plant: AeroelasticModel, law: SwitchingLaw, airspeed, density, force, *,
                 observer_model: AeroelasticModel | None = None, sample_rate: float = 1000.0,
                 time_constant: float = 0.01, noise=None, levels: int = DEFAULT_LEVELS,
                 hold: int = DEFAULT_HOLD, quantum: float = BATCH_QUANTUM,
                 initial_damping: float | None = None,
                 force_limit: float = math.inf, update_every: int = 1) -> SwitchedFlight:
    """Fly ``plant`` with the switching law armed (module docstring).

    Parameters
    ----------
    plant : AeroelasticModel
        The flown wing, with a Maxwell absorber.
    law : SwitchingLaw
    airspeed, density : float or array_like (N,)
        [m/s], [kg/m^3], held every ``hold`` samples with relative ``quantum``; the same for
        every flight of a batch.
    force : array_like (N,) or (F, N)
        [N] aileron force per sample (F flights at once: one vectorised loop).
    observer_model : AeroelasticModel, optional
        The controller's model (default ``plant``).
    time_constant : float
        [s] damper lag, >= 0.
    noise : array_like (N, 4) or (F, N, 4), optional
        [SI] sensor noise added to :data:`MEASURED_OUTPUTS`.
    initial_damping : float, optional
        [N s/m] c2 at the start (default c_hi); the first sample's target is the nearer
        of c_lo and c_hi (in log c2).
    force_limit : float
        [N] a relief valve: on a sample whose true damper force |k2 delta| exceeds it, c2 is
        the table's lowest level whatever the law asks (the force is then no longer c2 times
        the velocity the law assumes). inf: no valve.
    update_every : int
        [samples] between the law's decisions (1: every sample); a slower loop holds each
        decision, made on the last sample of a block, over the next block.

    Returns
    -------
    SwitchedFlight
        Arrays (N,) for one flight, (F, N) for a batch.
    """
    observer_model = plant if observer_model is None else observer_model
    maxwell_index(plant)
    maxwell_index(observer_model)
    if law.gain.size != observer_model.n_states:
        raise ValueError(f"gain has {law.gain.size} entries, the observer model "
                         f"{observer_model.n_states} states")
    if law.observer is None and observer_model is not plant:
        raise ValueError("a law without observer sees the plant's state: no observer_model")
    force = np.asarray(force, dtype=float)
    single = force.ndim == 1
    force = np.atleast_2d(force)
    if force.ndim != 2 or not np.all(np.isfinite(force)):
        raise ValueError(f"force must be finite with shape (N,) or (F, N), got {force.shape}")
    nf, nsamp = force.shape
    speeds = np.broadcast_to(np.asarray(airspeed, dtype=float), (nsamp,))
    rhos = np.broadcast_to(np.asarray(density, dtype=float), (nsamp,))
    if not (np.all(np.isfinite(speeds)) and np.all(speeds >= 0)):
        raise ValueError("airspeed must be finite and >= 0")
    if not (np.all(np.isfinite(rhos)) and np.all(rhos >= 0)):
        raise ValueError("density must be finite and >= 0")
    dt = 1.0 / positive(sample_rate, "sample_rate")
    tau = float(time_constant)
    if not (math.isfinite(tau) and tau >= 0.0):
        raise ValueError(f"time_constant must be finite and >= 0 s, got {tau}")
    if isinstance(hold, bool) or int(hold) != hold or hold < 1:
        raise ValueError(f"hold must be an integer >= 1, got {hold}")
    table = c2_levels(law.c_lo, law.c_hi, tau, levels)
    n = plant.n_states
    width = n + (0 if law.observer is None else observer_model.n_states)
    nv = 1 + len(MEASURED_OUTPUTS)
    inputs = np.zeros((nf, nsamp, nv))
    inputs[:, :, 0] = force
    if noise is not None:
        noise = np.asarray(noise, dtype=float)
        if noise.shape not in ((nsamp, nv - 1), (nf, nsamp, nv - 1)):
            raise ValueError(f"noise must have shape ({nsamp}, {nv - 1}) or "
                             f"({nf}, {nsamp}, {nv - 1}), got {noise.shape}")
        inputs[:, :, 1:] = noise
    # The held condition of each hold period, then every map they need in one batch.
    periods = range(0, nsamp, hold)
    held = [(math.nan, math.nan)]
    for start in periods:
        held.append(next_held((float(speeds[start]), float(rhos[start])), held[-1],
                              (quantum, quantum)))
    keys = list(dict.fromkeys(held[1:]))
    index = {key: j for j, key in enumerate(keys)}
    maps = _condition_maps(plant, observer_model, law, np.array(keys), table, dt)
    period_map = np.array([index[h] for h in held[1:]])
    # The (F, h) of each sample from its inputs (force, noise), all samples at once.
    of_sample = np.repeat(period_map, hold)[:nsamp]
    fh_in = np.einsum("sij,fsj->fsi", maps[1][of_sample], inputs)
    c_start = law.c_hi if initial_damping is None else min(
        max(float(initial_damping), law.c_lo), law.c_hi)
    if not float(force_limit) > 0:
        raise ValueError(f"force_limit must be > 0 N, got {force_limit}")
    if isinstance(update_every, bool) or int(update_every) != update_every or update_every < 1:
        raise ValueError(f"update_every must be an integer >= 1, got {update_every}")
    lag = _Damper(tau, dt, law.c_lo, law.c_hi, table.size, c_start, float(force_limit),
                  plant.absorber.series_stiffness, maxwell_index(plant), int(update_every))
    run = _loop_one if nf == 1 else _loop_batch
    states, level, targets = run(maps, period_map, periods, hold, inputs, fh_in, width, lag)
    states = states[..., :n]
    le = states @ plant.c_displacement[2]
    stroke = states @ plant.c_displacement[3]
    damping = table[level]
    spring_force = plant.absorber.series_stiffness * states[..., maxwell_index(plant)]
    out = SwitchedFlight(leading_edge=le, stroke=stroke, damping=damping, target=targets,
                         damper_power=spring_force**2 / damping, sample_rate=1.0 / dt)
    if single:
        return SwitchedFlight(*(getattr(out, f)[0] for f in (
            "leading_edge", "stroke", "damping", "target", "damper_power")), 1.0 / dt)
    return out


@dataclass(frozen=True)
class _Damper:
    """The damper's first-order lag over one sample with the target held, the table, and its
    relief valve (c2 at the table's lowest level while |k2 delta| > force_limit)."""

    tau: float
    dt: float
    c_lo: float
    c_hi: float
    n_levels: int
    c_start: float
    force_limit: float = math.inf
    k2: float = 0.0
    deflection: int = 0  # column of the plant's delta
    every: int = 1  # samples between decisions

    @property
    def decay(self) -> float:
        return math.exp(-self.dt / self.tau) if self.tau > 0 else 0.0

    @property
    def mean_factor(self) -> float:
        """(mean of c - target over the sample) / (c - target at its start)."""
        return self.tau / self.dt * (1.0 - self.decay) if self.tau > 0 else 0.0

    @property
    def per_level(self) -> float:
        return (math.log(self.c_hi) - math.log(self.c_lo)) / (self.n_levels - 1)


def _loop_one(maps, period_map, periods, hold, inputs, fh_in, width, lag):
    """One flight: Python floats for the law, one matrix-vector product per sample into
    preallocated row views (a memoryview reads the (F, h) parts without numpy scalars)."""
    t_all, _, g_state = maps
    nsamp = inputs.shape[1]
    z = np.zeros((nsamp + 1, width + 2 + inputs.shape[2]))
    z[:nsamp, width + 2:] = inputs[0]
    z[0, width:width + 2] = g_state[period_map[0]] @ z[0, :width]
    level = np.empty(nsamp, dtype=np.int64)
    targets = np.empty(nsamp, dtype=bool)
    fh_list = fh_in[0].tolist()
    rows = list(z)
    heads = list(z[:, :width + 2])
    view = memoryview(z)
    f_col, h_col = width, width + 1
    dot, log = np.dot, math.log
    tau, decay, mean_factor = lag.tau, lag.decay, lag.mean_factor
    c_hi, c_lo, c = lag.c_hi, lag.c_lo, lag.c_start
    log_lo, per_level = math.log(lag.c_lo), lag.per_level
    relief, force_limit = math.isfinite(lag.force_limit), lag.force_limit
    k2, d_col, every = lag.k2, lag.deflection, lag.every
    target_hi = c >= math.sqrt(c_lo * c_hi)
    prev_fh = 0.0
    for p, start in enumerate(periods):
        steps = list(t_all[period_map[p]])
        if p and period_map[p] != period_map[p - 1]:  # (F, h) with the new condition's maps
            z[start, width:width + 2] = g_state[period_map[p]] @ z[start, :width]
        for i in range(start, min(start + hold, nsamp)):
            if i and i % every == 0:
                target_hi = prev_fh > 0.0  # the decision of sample i-1 acts from i on
            f_in, h_in = fh_list[i]
            prev_fh = (view[i, f_col] + f_in) * (view[i, h_col] + h_in)
            if tau > 0:
                target = c_hi if target_hi else c_lo
                mean = target + (c - target) * mean_factor
                c = target + (c - target) * decay
                k = int((log(mean) - log_lo) / per_level + 0.5)
            else:
                k = 1 if target_hi else 0
            if relief and abs(view[i, d_col]) * k2 > force_limit:
                k = 0
            level[i] = k
            targets[i] = target_hi
            dot(steps[k], rows[i], heads[i + 1])
    return z[None, :nsamp, :width], level[None], targets[None]


def _loop_batch(maps, period_map, periods, hold, inputs, fh_in, width, lag):
    """Many flights: the same loop vectorised across flights."""
    t_all, _, g_state = maps
    nf, nsamp, nv = inputs.shape
    state = np.zeros((nf, width + 2 + nv))
    state[:, width:width + 2] = state[:, :width] @ g_state[period_map[0]].T
    record = np.empty((nsamp, nf, width))
    level = np.empty((nsamp, nf), dtype=np.int64)
    targets = np.empty((nsamp, nf), dtype=bool)
    decay, mean_factor = lag.decay, lag.mean_factor
    log_lo, per_level = math.log(lag.c_lo), lag.per_level
    c = np.full(nf, lag.c_start)
    relief = math.isfinite(lag.force_limit)
    target_hi = np.full(nf, lag.c_start >= math.sqrt(lag.c_lo * lag.c_hi))
    prev_fh = np.zeros(nf)
    inputs_t = np.ascontiguousarray(inputs.transpose(1, 0, 2))
    fh_t = np.ascontiguousarray(fh_in.transpose(1, 0, 2))
    for p, start in enumerate(periods):
        steps = t_all[period_map[p]]
        if p and period_map[p] != period_map[p - 1]:
            state[:, width:width + 2] = state[:, :width] @ g_state[period_map[p]].T
        for i in range(start, min(start + hold, nsamp)):
            if i and i % lag.every == 0:
                target_hi = prev_fh > 0.0
            state[:, width + 2:] = inputs_t[i]
            fh = state[:, width:width + 2] + fh_t[i]
            prev_fh = fh[:, 0] * fh[:, 1]
            if lag.tau > 0:
                target = np.where(target_hi, lag.c_hi, lag.c_lo)
                mean = target + (c - target) * mean_factor
                c = target + (c - target) * decay
                k = ((np.log(mean) - log_lo) / per_level + 0.5).astype(np.int64)
            else:
                k = target_hi.astype(np.int64)
            if relief:
                k = np.where(np.abs(state[:, lag.deflection]) * lag.k2 > lag.force_limit, 0, k)
            level[i] = k
            targets[i] = target_hi
            record[i] = state[:, :width]
            state[:, :width + 2] = np.matmul(steps[k], state[:, :, None])[:, :, 0]
    return record.transpose(1, 0, 2), level.T, targets.T
