"""A whole flight with the Maxwell DVA's c2 switched every sample by state feedback (no ROS).

The law (:mod:`.switching_law`) runs where a real semi-active damper runs it, in the damper's
own controller, once per sample. The damper follows its target through a first-order lag
``tau`` (exact for a target held over a sample); the command acts from the sample after the one
it was computed on.

Stepping exactly with a c2 that changes every sample. ``c2`` enters the model only through the
Maxwell relaxation rate ``k2 / c2``, so each sample is an exact zero-order-hold step of the
model at the c2 acting over it. Without lag c2 takes two values: both steps are precomputed.
With a lag c2 is continuous; the choice here is a table of ``levels`` c2 values spaced evenly in
log c2 between c_lo and c_hi, every step precomputed, and each sample flown with the level
nearest (in log c2) to the lag's mean over the sample: with the default 65 levels between 100
and 2500 N s/m the c2 acting is within 2.5 % of the lagged c2, far inside the accuracy of the
damper's model. The steps of a ramp's many held airspeeds and the table's levels are
interpolated from a few Chebyshev nodes, to rounding accuracy
(:mod:`aero_dva.flight.per_sample.smooth_tables`).

The estimate comes from a fixed-gain Kalman filter of the measured signals (the absorber stroke
and the three accelerations, with sensor noise), run on an observer model that may differ from
the flown plant (model mismatch). The loop over samples is compiled
(:mod:`aero_dva.flight.per_sample.kernel`); airspeed and density are held every ``hold`` samples
as the other simulators hold them (:func:`~aero_dva.flight.discrete_model.next_held`). Pure
numerics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aero_dva.flight.discrete_model import DEFAULT_HOLD, N_DISPLACEMENTS
from aero_dva.flight.discretize import zoh
from aero_dva.flight.kept import KeptByKey
from aero_dva.flight.per_sample.smooth_tables import interpolated_maps
from aero_dva.flight.per_sample.switching_law import (
    MEASURED_OUTPUTS,
    SwitchingLaw,
    maxwell_index,
)
from aero_dva.flight.samples import FlightSamples
from aero_dva.wing.checks import positive
from aero_dva.wing.model import AeroelasticModel

__all__ = ["c2_levels", "fly_switched"]

DEFAULT_LEVELS = 65
#: Relative airspeed and density change below which a held value is kept, the batch
#: simulator's (0.2 m/s at 100 m/s): each held condition costs a c2 table of discretisations.
BATCH_QUANTUM = 2e-3


def c2_levels(c_lo: float, c_hi: float, time_constant: float,
              levels: int = DEFAULT_LEVELS) -> np.ndarray:
    """The c2 values flown: the two targets without lag, else ``levels`` values evenly spaced
    in log c2 (module docstring)."""
    if time_constant == 0.0:
        return np.array([c_lo, c_hi])
    if int(levels) < 2:
        raise ValueError(f"levels must be >= 2, got {levels}")
    return np.geomspace(c_lo, c_hi, int(levels))


def _measurement(model: AeroelasticModel, conditions: np.ndarray):
    """``C`` (K, 4, n) and ``D`` (K, 4) of :data:`MEASURED_OUTPUTS` at ``conditions`` (K, 2);
    c2 does not enter them (it acts only on the Maxwell deflection's own rate)."""
    k, n = conditions.shape[0], model.n_states
    a, b = model.matrices_unchecked(conditions[:, 0], conditions[:, 1],
                                    np.full(k, model.absorber.damping))
    c_acc, d_acc = model.acceleration_output(a, b)
    c = np.concatenate([np.broadcast_to(model.c_displacement[3], (k, 1, n)), c_acc], axis=1)
    d = np.concatenate([np.zeros((k, 1)), d_acc], axis=1)
    return c, d


def _steps(plant, observer_model, conditions: np.ndarray, levels: np.ndarray, dt: float,
           expm=None):
    """(K, L, S): per held condition and c2 level, the plant's ``[Ad | Bd]``, (when the
    observer's model is another) the observer's ``Ad``, and the plant's input column of a
    unit rate on the Maxwell deflection (a yield force's offset), flattened (``expm``: the
    matrix exponential of a stack, as for :func:`~aero_dva.flight.discretize.zoh`)."""
    k, nl = conditions.shape[0], levels.size
    speeds = np.repeat(conditions[:, 0], nl)
    rhos = np.repeat(conditions[:, 1], nl)
    n = plant.n_states
    a, b = plant.matrices_unchecked(speeds, rhos, np.tile(levels, k))
    inputs = np.zeros(b.shape + (2,))
    inputs[..., 0] = b
    inputs[..., maxwell_index(plant), 1] = 1.0
    ad, gamma = zoh(a, inputs, dt, expm)
    # [Ad | Bd] row by row, then Ao, then the deflection-rate column: the compiled loop's
    # layout.
    parts = [np.concatenate([ad, gamma[..., :1]], axis=-1).reshape(k, nl, -1)]
    if observer_model is not plant:
        a, b = observer_model.matrices_unchecked(speeds, rhos, np.tile(levels, k))
        parts.append(zoh(a, b, dt, expm)[0].reshape(k, nl, -1))
    parts.append(gamma[..., 1].reshape(k, nl, n))
    return np.concatenate(parts, axis=-1)


def _condition_maps(plant, observer_model, law, conditions):
    """Per held condition (K, 2), the filtered estimate ``e = est @ [x; p; f; noise]`` (K, m,
    n+m+5; None without observer) and the law's ``(F, h) = g_state @ [x; p] + g_in @ [f;
    noise]``: g_state (K, 2, n+m), g_in (K, 2, 5)."""
    kc, n = conditions.shape[0], plant.n_states
    nv = 1 + len(MEASURED_OUTPUTS)
    if law.observer is None:
        fh_model, m, est = plant, 0, None
        fh_state = np.zeros((kc, n, n + nv))
        fh_state[:, :, :n] = np.eye(n)
    else:
        cp, dp = _measurement(plant, conditions)
        co = cp if observer_model is plant else _measurement(observer_model, conditions)[0]
        m = observer_model.n_states
        obs = law.observer
        # Filtered estimate e = p + M (y - C_o p), y = C_p x + D_p f + noise, as a map of v.
        est = np.zeros((kc, m, n + m + nv))
        est[:, :, :n] = obs @ cp
        est[:, :, n:n + m] = np.eye(m) - obs @ co
        est[:, :, n + m] = dp @ obs.T
        est[:, :, n + m + 1:] = obs
        fh_model, fh_state = observer_model, est
    fh = np.zeros((kc, 2, n + m + nv))
    if law.scheduled:  # the rows at each condition's airspeed
        gain, force_gain = law.rows_at(conditions[:, 0])
    else:
        gain, force_gain = law.gain, law.force_gain
    if force_gain is None:
        fh[:, 0] = fh_model.absorber.series_stiffness * fh_state[:, maxwell_index(fh_model)]
    elif law.scheduled:
        fh[:, 0] = np.einsum("kj,kjc->kc", force_gain, fh_state)
    else:
        fh[:, 0] = force_gain @ fh_state
    fh[:, 1] = np.einsum("kj,kjc->kc", gain, fh_state) if law.scheduled else gain @ fh_state
    if est is None:
        est = np.zeros((kc, 0, n + nv))
    return est, fh[:, :, n + m:], fh[:, :, :n + m]


def fly_switched(plant: AeroelasticModel, law: SwitchingLaw, airspeed, density, force, *,
                 observer_model: AeroelasticModel | None = None, sample_rate: float = 1000.0,
                 time_constant: float = 0.01, noise=None, levels: int = DEFAULT_LEVELS,
                 hold: int = DEFAULT_HOLD, quantum: float = BATCH_QUANTUM,
                 initial_damping: float | None = None,
                 force_limit: float = math.inf, update_every: int = 1,
                 yield_force: float = 0.0, keep_states: bool = False) -> FlightSamples:
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
    yield_force : float
        [N] a Bingham damper's yield force (0: none, the damper force is c2 times its
        velocity): locked while the spring force is at most it, else the force is c2 times
        the velocity plus the yield force (:func:`~aero_dva.flight.per_sample.kernel.fly_maps`;
        the lock and the sign are held over each sample). The law and its observer still
        assume the linear damper.
    keep_states : bool
        Return the plant's state at each sample's start too (``states``).

    Returns
    -------
    FlightSamples
        Arrays (N,) for one flight, (F, N) for a batch.
    """
    observer_model = plant if observer_model is None else observer_model
    maxwell_index(plant)
    maxwell_index(observer_model)
    if law.states != observer_model.n_states:
        raise ValueError(f"gain has {law.states} entries, the observer model "
                         f"{observer_model.n_states} states")
    if law.observer is None and observer_model is not plant:
        raise ValueError("a law without observer sees the plant's state: no observer_model")
    force = np.asarray(force, dtype=float)
    single = force.ndim == 1
    force = np.atleast_2d(force)
    if force.ndim != 2 or force.size == 0 or not np.all(np.isfinite(force)):
        raise ValueError(f"force must be finite with shape (N,) or (F, N), N and F >= 1, "
                         f"got {force.shape}")
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
    starts = np.arange(0, nsamp, hold)
    # imported here: numba takes 0.4 s to import, and every simulator process imports this
    # module (switching_io) whether or not a switching law flies
    from aero_dva.flight.held_kernel import compiled_expm as expm
    from aero_dva.flight.held_kernel import hold_rule
    from aero_dva.flight.per_sample.kernel import fly_fixed, fly_maps

    raw = np.stack([speeds[starts], rhos[starts]], axis=-1)
    held = hold_rule(raw, np.full(2, np.nan), quantum, np.empty_like(raw))
    # held values come in runs: the distinct conditions of the runs' first periods
    new_run = np.ones(len(held), dtype=bool)
    new_run[1:] = np.any(held[1:] != held[:-1], axis=1)
    keys, run_key = np.unique(held[new_run], axis=0, return_inverse=True)
    period_map = run_key.ravel()[np.cumsum(new_run) - 1]
    steps, index, weight, est, g_in, g_state, fixed = _flight_maps(
        plant, observer_model, law, keys, table, dt, expm)
    c_start = law.c_hi if initial_damping is None else min(
        max(float(initial_damping), law.c_lo), law.c_hi)
    if not float(force_limit) > 0:
        raise ValueError(f"force_limit must be > 0 N, got {force_limit}")
    if isinstance(update_every, bool) or int(update_every) != update_every or update_every < 1:
        raise ValueError(f"update_every must be an integer >= 1, got {update_every}")
    lag = _Damper(tau, dt, law.c_lo, law.c_hi, table.size, c_start, float(force_limit),
                  plant.absorber.series_stiffness, maxwell_index(plant), int(update_every))
    yield_force = float(yield_force)
    if not (math.isfinite(yield_force) and yield_force >= 0.0):
        raise ValueError(f"yield_force must be finite and >= 0 N, got {yield_force}")
    locked = (_steps(plant, plant, keys, np.array([np.inf]), dt, expm)[:, 0, :n * (n + 1)]
              if yield_force > 0 else np.zeros((1, n * (n + 1))))
    sample_map = np.repeat(period_map.astype(np.int64).ravel(), hold)[:nsamp]
    loop = (lag.tau, lag.decay, lag.mean_factor, lag.c_lo, lag.c_hi, lag.per_level,
            lag.force_limit, lag.k2, lag.deflection, lag.every, 0,
            np.zeros((nf, n + est.shape[1])), np.full(nf, c_start),
            np.full(nf, c_start >= math.sqrt(law.c_lo * law.c_hi)), np.zeros(nf), yield_force,
            np.ascontiguousarray(locked), table)
    if fixed is not None:  # the wing's sizes: every level of every condition formed
        states, level, targets = fly_fixed(fixed, sample_map, inputs, *loop)
    else:
        states, level, targets = fly_maps(steps, index, weight, est, g_in, g_state,
                                          sample_map, inputs, n, *loop)
    # each displacement row as its own product (the leading edge and the stroke as before)
    disp = np.stack([states @ plant.c_displacement[k] for k in range(N_DISPLACEMENTS)],
                    axis=-2)
    damping = table[level]
    damper_force = states[..., maxwell_index(plant)] * plant.absorber.series_stiffness
    spring_force = np.abs(damper_force)
    # F v_damper: F^2 / c2 for the linear damper; F (|F| - yield) / c2 while a Bingham
    # damper flows, 0 while it is locked
    flowing = np.maximum(spring_force - yield_force, 0.0) if yield_force > 0 else spring_force
    power = spring_force * flowing
    power /= damping
    k = 0 if single else slice(None)
    return FlightSamples(first_index=0, sample_rate=1.0 / dt, airspeed=speeds, density=rhos,
                         damping=damping[k], force=force[k], displacements=disp[k],
                         states=states[k] if keep_states else None, target=targets[k],
                         damper_force=damper_force[k], damper_power=power[k])


_KEPT_MAPS = 2
"""Flights whose maps :func:`_flight_maps` keeps (the last ones flown)."""
_kept = KeptByKey(_KEPT_MAPS)


def _models_key(model: AeroelasticModel) -> tuple:
    return (model.wing, model.absorber, model.aero)


def _flight_maps(plant, observer_model, law, keys, table, dt, expm):
    """The interpolated steps (:func:`.smooth_tables.interpolated_maps`) and the condition
    maps (:func:`_condition_maps`) of a flight, kept for the next flights with the same
    models, law, held conditions, c2 table and sample interval (the seeds of a case and the
    repeats of a benchmark); last, the maps of the fixed-size loop with every level formed
    (:func:`.kernel.fixed_maps`; None for other sizes). The arrays are shared: nothing writes
    into them."""
    def raw(a):
        return None if a is None else (a.shape, a.tobytes())

    key = (_models_key(plant), _models_key(observer_model), observer_model is plant,
           raw(law.gain), law.c_lo, law.c_hi, raw(law.observer), raw(law.force_gain),
           raw(law.airspeeds), raw(keys), raw(table), dt)
    kept = _kept.get(key)
    if kept is not None:
        return kept
    steps, index, weight = interpolated_maps(
        lambda cond, lev: _steps(plant, observer_model, cond, lev, dt, expm), keys, table,
        plant.absorber.series_stiffness)
    maps = (steps, index, weight) + _condition_maps(plant, observer_model, law, keys)
    from aero_dva.flight.per_sample.kernel import fixed_maps  # numba: as in fly_switched

    maps += (fixed_maps(*maps, plant.n_states, 1 + len(MEASURED_OUTPUTS)),)
    return _kept.keep(key, maps)


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
