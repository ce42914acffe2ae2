"""The stepped (U, c2) sweep simulated parallel in time: the flight runtime's flight, at once.

:class:`~aero_dva.flight.flight_runtime.FlightRuntime` steps a flight in 50-sample blocks, one
hold period (10 samples) after the other. A sweep is piecewise constant: its held airspeed,
density and c2 (the parameter hold of :class:`~aero_dva.flight.discrete_model.DiscreteWing`,
with the runtime's 0.1 % hysteresis) change only at dwell boundaries, so each dwell is one
linear time-invariant system and the whole flight can be computed exactly with large array
operations:

1. every distinct held condition is discretised in one batched call
   (:meth:`~aero_dva.flight.discrete_model.DiscreteWing.discretise`, exact ZOH);

then, chunk by chunk of dwells (about 65 dwells each, so a consumer gets the first chunk at
once and the flight streams out):

2. the chunk's force, the runtime's: ``force_std * default_rng(seed).standard_normal`` (the
   generator yields the same numbers in one call as in pieces);
3. the forced state at the end of each of the chunk's dwells from rest, all at once
   (sub-blocks of ``L`` samples, grouped ``R`` at a time, so the sequential part is short);
4. a scan over the chunk's dwells gives their initial states,
   ``x0[k+1] = Phi_k^M x0[k] + xf_k``, carried on to the next chunk;
5. the states at every sub-block start follow (two short recurrences, vectorised over the
   dwells), and the outputs come from one batched product per output channel asked for (a
   consumer that records no displacement skips those channels) with the sub-block map
   ``y = [C Phi^j | Toeplitz(C Phi^i Gamma, D)] [x; u]``, written straight into time order.

Same seed -> same data as stepping the runtime, to round-off (a test compares them sample by
sample). Supported: ``steps`` scenarios with constant density and the nominal plant
(:func:`unsupported_reason` names what is not); anything else is flown by FlightRuntime.
Pure numerics (no ROS, no files).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from aero_dva.flight.discrete_model import (
    DEFAULT_HOLD,
    FLIGHT_QUANTUM,
    N_DISPLACEMENTS,
    N_OUTPUTS,
    OUTPUT_NAMES,
    DiscreteWing,
    next_held,
)
from aero_dva.flight.flight_runtime import RuntimeConfig
from aero_dva.flight.scenario import Scenario, airspeed_at, density_at, sweep_damping_at
from aero_dva.wing.model import AeroelasticModel

__all__ = ["SweepChunk", "SweepMaps", "SweepPlan", "plan_sweep", "simulate_sweep",
           "split_sweep", "sweep_maps", "unsupported_reason"]

SUBBLOCK = 10  # [samples] L: outputs cost p (n + L) multiply-adds per sample and channel
CHUNK_SAMPLES = 1 << 18  # samples per output chunk (about 15 MB of outputs): cache-friendly
# (a stepped sweep sets c2 itself: it never arms a per-sample law)
_KNOWN_CONFIG = {"scenario", "wing", "aero", "absorber", "damper", "per_sample",
                 "sensor_noise"}


@dataclass(frozen=True)
class SweepPlan:
    """The sweep as segments of constant held parameters, with their discretisations.

    Attributes
    ----------
    scenario : Scenario
        Resolved (airspeeds in m/s).
    n_samples : int
    sample_rate : float
        [Hz]
    starts, lengths : (S,) int
        First sample and length of each segment (a run of hold periods with one condition).
    condition : (S,) int
        Index of each segment's condition into ``params``.
    params : (K, 3)
        Distinct held (airspeed [m/s], density [kg/m^3], c2 [N s/m]) conditions.
    subblock : int
        L, samples per sub-block (divides every segment length).
    """

    scenario: Scenario
    n_samples: int
    sample_rate: float
    starts: np.ndarray
    lengths: np.ndarray
    condition: np.ndarray
    params: np.ndarray
    subblock: int


@dataclass(frozen=True)
class SweepChunk:
    """Consecutive samples of the flight (time on the last axis).

    Attributes
    ----------
    first_index : int
        Index of the chunk's first sample since the start of the flight.
    force : (T,) [N]
    outputs : (m, T)
        The computed output channels, in the order of ``channels``.
    channels : tuple of int
        Indices into :data:`.OUTPUT_NAMES` of the rows of ``outputs``.
    """

    first_index: int
    force: np.ndarray
    outputs: np.ndarray
    channels: tuple[int, ...] = tuple(range(N_OUTPUTS))

    def rows(self, names) -> np.ndarray:
        """(len(names), T) the named channels of :data:`.OUTPUT_NAMES` (a view when they lie in
        order); ValueError naming a channel that was not computed."""
        try:
            rows = [self.channels.index(OUTPUT_NAMES.index(name)) for name in names]
        except ValueError:
            raise ValueError(f"channels {list(names)} asked for; this chunk has "
                             f"{[OUTPUT_NAMES[c] for c in self.channels]}") from None
        if rows and rows == list(range(rows[0], rows[0] + len(rows))):
            return self.outputs[rows[0]:rows[0] + len(rows)]
        return self.outputs[rows]

    @property
    def displacements(self) -> np.ndarray:
        """(4, T) plunge [m], pitch [rad], leading edge [m], DVA stroke [m]."""
        return self.rows(OUTPUT_NAMES[:N_DISPLACEMENTS])

    @property
    def accelerations(self) -> np.ndarray:
        """(3, T) plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2]."""
        return self.rows(OUTPUT_NAMES[N_DISPLACEMENTS:])


def unsupported_reason(config: RuntimeConfig, scenario: Scenario) -> str | None:
    """Why this flight cannot take the parallel-in-time path (None: it can).

    ``scenario`` is the runtime's resolved scenario.
    """
    extra = {f.name for f in dataclasses.fields(config)} - _KNOWN_CONFIG
    if extra:
        return f"runtime options {sorted(extra)} are not modelled here"
    if scenario.airspeed.kind != "steps":
        return f"airspeed kind {scenario.airspeed.kind!r} is not a stepped sweep"
    if scenario.density_variation != 0.0:
        return "the density varies within the dwells"
    plant = getattr(scenario, "plant", None)
    if plant is not None and getattr(plant, "active", True):
        return "the scenario flies a hidden plant"
    # Options added to Scenario later are flown by FlightRuntime only, unless left at default.
    changed = [f.name for f in dataclasses.fields(scenario)
               if f.name not in _SCENARIO_FIELDS and getattr(scenario, f.name) != _default(f)]
    if changed:
        return f"scenario options {changed} are not modelled here"
    return None


_SCENARIO_FIELDS = {"name", "duration", "sample_rate", "block_size", "airspeed", "density",
                    "density_variation", "density_frequency", "force_std", "seed", "dwell",
                    "sweep_damping", "plant"}


def _default(f: dataclasses.Field):
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return f.default


def _held_runs(raw: tuple[np.ndarray, ...], quantum: float) -> tuple[np.ndarray, np.ndarray]:
    """Held parameters of the hold periods, as runs: (first period of each run, values).

    ``raw`` = (airspeed, density, c2), each (P,), the inputs at the periods' first samples.
    The rule is the discrete wing's (:func:`~aero_dva.flight.discrete_model.next_held`, NaN
    before the first period). Inputs that are constant over a run of periods give one decision
    per run, so the loop runs over the input's changes.
    """
    change = np.zeros(len(raw[0]), dtype=bool)
    change[0] = True
    for column in raw:
        change[1:] |= column[1:] != column[:-1]
    first = np.flatnonzero(change)
    held = []
    cur = (math.nan, math.nan, math.nan)
    quanta = (quantum,) * 3
    for row in np.column_stack([column[first] for column in raw]).tolist():
        cur = next_held(row, cur, quanta)
        held.append(cur)
    held = np.array(held, dtype=float).reshape(-1, 3)
    keep = np.ones(len(first), dtype=bool)  # runs whose held values did not change merge
    keep[1:] = np.any(held[1:] != held[:-1], axis=1)
    return first[keep], held[keep]


def plan_sweep(config: RuntimeConfig, scenario: Scenario, *, hold: int = DEFAULT_HOLD,
               quantum: float = FLIGHT_QUANTUM, subblock: int = SUBBLOCK) -> SweepPlan:
    """Cut the runtime's flight into segments of constant held parameters.

    Parameters
    ----------
    config : RuntimeConfig
    scenario : Scenario
        The runtime's resolved scenario (``FlightRuntime.scenario``).
    hold, quantum : the parameter hold (defaults: the flight runtime's values).
    subblock : int
        Largest sub-block length L; the one used divides every segment length.

    Raises
    ------
    ValueError
        The flight is not supported (:func:`unsupported_reason`), or the sample rate is below
        the Nyquist rate of a mode at the first condition (as the streaming simulator).
    """
    reason = unsupported_reason(config, scenario)
    if reason is not None:
        raise ValueError(f"the parallel-in-time sweep cannot fly this: {reason}")
    n = scenario.n_samples
    rate = scenario.sample_rate
    grid = np.arange(0, n, hold)
    t = grid / rate  # == sample_times(scenario)[grid], bit for bit
    c2 = sweep_damping_at(scenario, t) if config.absorber is not None else np.zeros(t.size)
    raw = (airspeed_at(scenario, t), density_at(scenario, t), c2)
    first, held = _held_runs(raw, quantum)
    starts = first * hold
    lengths = np.diff(np.append(starts, n))
    params, condition = np.unique(held, axis=0, return_inverse=True)
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    DiscreteWing(model, rate, hold=hold, quantum=quantum).check_sampling(
        raw[0][0], raw[1][0], c2[0])
    g = int(np.gcd.reduce(lengths))
    sub = max(d for d in range(1, min(subblock, g) + 1) if g % d == 0)
    return SweepPlan(scenario=scenario, n_samples=n, sample_rate=rate, starts=starts,
                     lengths=lengths, condition=condition.reshape(-1), params=params,
                     subblock=sub)


class SweepMaps:
    """Per-condition discrete maps over one sample, a sub-block and groups of sub-blocks.

    Built by :func:`sweep_maps` (the first step of the module docstring); processes that
    share a flight build them once, before they fork.
    """

    def __init__(self, wing: DiscreteWing, params: np.ndarray, sub: int):
        self.n = n = wing.n_states
        sampled = wing.discretise(params)
        phi, gam, c, d = sampled.ad, sampled.bd, sampled.c, sampled.d
        k, p = len(params), wing.n_outputs
        # powers[j] = Phi^j, j = 0..L; obs[j] = C Phi^j; markov[j] = C Phi^j Gamma.
        powers = np.empty((sub + 1, k, n, n))
        powers[0] = np.eye(n)
        for j in range(sub):
            powers[j + 1] = phi @ powers[j]
        obs = c[None] @ powers[:sub]  # (L, K, p, n)
        markov = (obs @ gam[None, :, :, None])[..., 0]  # (L, K, p)
        # Sub-block map per output o, transposed: [x; u_0..u_{L-1}] (n + L) -> y_o (L).
        qt = np.zeros((k, p, n + sub, sub))
        qt[:, :, :n] = obs.transpose(1, 2, 3, 0)
        for j in range(sub):
            qt[:, :, n + j, j] = d
            for i in range(j):
                qt[:, :, n + i, j] = markov[j - 1 - i]
        self.qt = qt
        self.phi_l = powers[sub]  # (K, n, n)
        # ctrb_l[:, :, i] = Phi^(L-1-i) Gamma: the end state of a sub-block from its forces.
        self.ctrb_l = (powers[sub - 1::-1] @ gam[None, :, :, None])[..., 0].transpose(1, 2, 0)
        self.sub = sub
        self._groups: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._segments: dict[int, tuple[int, int, np.ndarray]] = {}

    def group(self, r: int) -> tuple[np.ndarray, np.ndarray]:
        """(Phi^(L r), ctrb over L r samples (K, n, L r)) for groups of ``r`` sub-blocks."""
        if r not in self._groups:
            parts = [self.ctrb_l]
            power = self.phi_l
            for _ in range(r - 1):
                parts.append(power @ self.ctrb_l)
                power = self.phi_l @ power
            self._groups[r] = (power, np.concatenate(parts[::-1], axis=2))
        return self._groups[r]

    def segment(self, m: int) -> tuple[int, int, np.ndarray]:
        """(R, groups, Phi^m (K, n, n)) for segments of ``m`` samples."""
        if m not in self._segments:
            r = _split(m // self.sub)
            groups = m // (self.sub * r)
            self._segments[m] = (r, groups, _power(self.group(r)[0], groups))
        return self._segments[m]


def sweep_maps(config: RuntimeConfig, plan: SweepPlan) -> SweepMaps:
    """The discrete maps of every condition and segment length of ``plan``."""
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    maps = SweepMaps(DiscreteWing(model, plan.sample_rate), plan.params, plan.subblock)
    for m in np.unique(plan.lengths).tolist():
        maps.segment(m)
    return maps


def _power(m: np.ndarray, e: int) -> np.ndarray:
    """m^e for a stack of matrices (binary powering)."""
    out = np.broadcast_to(np.eye(m.shape[-1]), m.shape).copy()
    while e:
        if e & 1:
            out = m @ out
        e >>= 1
        if e:
            m = m @ m
    return out


def _split(b: int) -> int:
    """R: the divisor of ``b`` closest to sqrt(b) (sub-blocks per group)."""
    root = math.isqrt(b)
    return max(d for d in range(1, root + 1) if b % d == 0) if b > 1 else 1


def _segment_forces(force: np.ndarray, starts: np.ndarray, m: int) -> np.ndarray:
    """(S, m) forces of segments of length ``m`` (a view when they are back to back)."""
    if len(starts) > 1 and np.all(np.diff(starts) == m):
        return force[starts[0]:starts[0] + m * len(starts)].reshape(len(starts), m)
    return force[starts[:, None] + np.arange(m)]


def _matvec(m: np.ndarray, x: np.ndarray) -> np.ndarray:
    return (m @ x[..., None])[..., 0]


def simulate_sweep(config: RuntimeConfig, plan: SweepPlan, *,
                   chunk_samples: int = CHUNK_SAMPLES,
                   outputs=OUTPUT_NAMES, span: tuple[int, int] | None = None,
                   maps: SweepMaps | None = None) -> Iterator[SweepChunk]:
    """Yield the flight in chunks of whole segments, in time order.

    Chunk by chunk (so a consumer, e.g. a writer thread, gets the first one at once, and one
    that stops early (divergence) saves the rest): the chunk's force (from the scenario's random
    seed, drawn in pieces), its segments' end states from rest, the scan that carries the
    state from segment to segment (steps 3-4 of the module docstring), then the outputs.
    ``outputs`` names the channels of :data:`.OUTPUT_NAMES` to compute (each costs the same; a
    channel left out is not computed at all); a channel's values do not depend on which
    others are computed.

    ``span = (first, end)`` yields only samples ``first .. end - 1``, both segment starts
    (:func:`split_sweep`; ``end`` may be ``n_samples``), so that processes can share a
    flight. The segments before ``first`` are still scanned (force and end states, no
    outputs: about a third of the cost of simulating them) because their state and the force
    stream carry on; the yielded samples are the same bits as those of the whole flight.
    ``maps``: the plan's :func:`sweep_maps`, if already built.
    """
    channels = _channels(outputs)
    first_sample, end_sample = _span(plan, span)
    s = plan.scenario
    rng = np.random.default_rng(s.seed)
    if maps is None:
        maps = sweep_maps(config, plan)
    nst, sub = maps.n, plan.subblock

    x = np.zeros(nst)  # state at the start of the next chunk
    drawn = 0
    k = 0
    last = int(np.searchsorted(plan.starts, end_sample))  # segments k < last are flown
    while k < last:
        # A chunk lies before the span or inside it, never across its start.
        bound = last if plan.starts[k] >= first_sample else \
            int(np.searchsorted(plan.starts, first_sample))
        stop = k + 1
        total = int(plan.lengths[k])
        while stop < bound and total + plan.lengths[stop] <= chunk_samples:
            total += int(plan.lengths[stop])
            stop += 1
        first = int(plan.starts[k])
        if first != drawn:
            raise ValueError(f"the sweep plan's segments are not back to back at sample {first}")
        force = s.force_std * rng.standard_normal(total)  # the stream of one call, in pieces
        drawn += total
        n = stop - k
        x_free_end = np.empty((n, nst))  # end state from rest (forced part)
        phi_seg = np.empty((n, nst, nst))  # Phi^M: carries the initial state
        x0 = np.empty((n, nst))
        out = np.empty((len(channels), total))
        with np.errstate(over="ignore", invalid="ignore"):  # a diverging flight may overflow
            groups_of = {m: np.flatnonzero(plan.lengths[k:stop] == m)
                         for m in np.unique(plan.lengths[k:stop]).tolist()}
            for m, local in groups_of.items():
                r, groups, phi_m = maps.segment(m)
                phi_g, ctrb_g = maps.group(r)
                cond = plan.condition[k + local]
                u = _segment_forces(force, plan.starts[k + local] - first, m)
                g = ctrb_g[cond] @ u.reshape(len(local), groups, sub * r).transpose(0, 2, 1)
                xe = np.zeros((len(local), nst))
                p = phi_g[cond]
                for j in range(groups):  # forced end of each group, in turn
                    xe = _matvec(p, xe) + g[:, :, j]
                x_free_end[local] = xe
                phi_seg[local] = phi_m[cond]
            # The sequential scan over the chunk's segments (a few microseconds each).
            for i in range(n):
                x0[i] = x
                x = phi_seg[i] @ x + x_free_end[i]
            if first < first_sample:  # before the span: only the state carries on
                k = stop
                continue
            for m, local in groups_of.items():
                r, groups, _ = maps.segment(m)
                _outputs(maps, (r, groups), plan.condition[k + local], x0[local],
                         _segment_forces(force, plan.starts[k + local] - first, m),
                         plan.starts[k + local] - first, out, channels)
        yield SweepChunk(first_index=first, force=force, outputs=out, channels=channels)
        k = stop


def split_sweep(plan: SweepPlan, parts: int, *, align: int = 1,
                weights=None) -> list[tuple[int, int]]:
    """Cut the flight into at most ``parts`` consecutive spans for :func:`simulate_sweep`.

    Every cut is a segment start that is a multiple of ``align`` (e.g. the message block
    size, so that no block straddles two spans), placed nearest to where the ``weights``
    (relative sizes, default equal) put it. Fewer spans come back when there are fewer
    usable cuts; empty spans are dropped.
    """
    if isinstance(parts, bool) or not isinstance(parts, (int, np.integer)) or parts < 1:
        raise ValueError(f"parts must be a positive integer, got {parts!r}")
    w = np.ones(parts) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (parts,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(f"weights must be {parts} finite values > 0, got {weights!r}")
    cuts = plan.starts[(plan.starts > 0) & (plan.starts % align == 0)]
    bounds = [0]
    if cuts.size:
        for target in (np.cumsum(w)[:-1] / w.sum() * plan.n_samples).tolist():
            cut = int(cuts[np.argmin(np.abs(cuts - target))])
            if cut > bounds[-1]:
                bounds.append(cut)
    bounds.append(plan.n_samples)
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _span(plan: SweepPlan, span) -> tuple[int, int]:
    if span is None:
        return 0, plan.n_samples
    first, end = (int(v) for v in span)
    valid = set(plan.starts.tolist()) | {plan.n_samples}
    if first not in valid or end not in valid or not first < end:
        raise ValueError(f"span {tuple(span)} must be two segment starts (or n_samples = "
                         f"{plan.n_samples}) with first < end")
    return first, end


def _channels(outputs) -> tuple[int, ...]:
    if isinstance(outputs, str):
        outputs = (outputs,)
    outputs = tuple(outputs)
    unknown = [o for o in outputs if o not in OUTPUT_NAMES]
    if unknown or not outputs or len(set(outputs)) != len(outputs):
        raise ValueError(f"outputs must be distinct names among {OUTPUT_NAMES}, got {outputs}")
    return tuple(OUTPUT_NAMES.index(o) for o in outputs)


def _outputs(maps: SweepMaps, layout: tuple[int, int], cond: np.ndarray, x0: np.ndarray,
             u: np.ndarray, offsets: np.ndarray, out: np.ndarray,
             channels: tuple[int, ...]) -> None:
    """Output ``channels`` of segments of one length into ``out`` (m, T) at ``offsets``.

    ``x0`` (S, n) initial states, ``u`` (S, M) forces. States at group starts (G steps), then
    at sub-block starts (R steps, vectorised over groups), then one batched product.
    """
    r, groups = layout
    nseg, m = u.shape
    nst, sub = maps.n, maps.sub
    phi_g, ctrb_g = maps.group(r)
    blocks = u.reshape(nseg, groups * r, sub)
    g = ctrb_g[cond] @ u.reshape(nseg, groups, sub * r).transpose(0, 2, 1)  # (S, n, G)
    starts_g = np.empty((nseg, nst, groups))
    x = x0
    p = phi_g[cond]
    for j in range(groups):
        starts_g[:, :, j] = x
        x = _matvec(p, x) + g[:, :, j]
    # Within groups: y[r'] for all groups at once.
    gl = (maps.ctrb_l[cond] @ blocks.transpose(0, 2, 1)).reshape(nseg, nst, groups, r)
    xs = np.empty((nseg, groups, r, nst + sub))  # [state; forces] of every sub-block
    xs[..., nst:] = blocks.reshape(nseg, groups, r, sub)
    p = maps.phi_l[cond]
    y = starts_g
    for j in range(r):
        xs[:, :, j, :nst] = y.transpose(0, 2, 1)
        y = p @ y + gl[:, :, :, j]
    xs = xs.reshape(nseg, groups * r, nst + sub)
    # One product per output channel writes time-ordered samples straight into ``out``.
    back_to_back = nseg == 1 or bool(np.all(np.diff(offsets) == m))
    for row_index, o in enumerate(channels):
        q = maps.qt[cond, o]  # (S, n + L, L)
        if back_to_back:
            row = out[row_index, offsets[0]:offsets[0] + nseg * m].reshape(nseg, groups * r, sub)
            np.matmul(xs, q, out=row)
        else:
            for i, off in enumerate(offsets.tolist()):
                out[row_index, off:off + m] = (xs[i] @ q[i]).reshape(m)
