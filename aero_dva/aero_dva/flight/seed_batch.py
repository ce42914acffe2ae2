"""Flights of one scenario that differ only in their seed, stepped block by block together.

:class:`SeedBatchRuntime` is :class:`~aero_dva.flight.flight_runtime.FlightRuntime` for ``F``
seeds at once: the same airspeed and density profile, each flight its own aileron force (drawn
per block from ``default_rng(seed)``, as the runtime draws it) and its own damper, so a
controller may command a different c2 to every flight. A block of all flights costs one pass
of Python: while the flights hold one condition, each hold period is one product of its
period map (:class:`~aero_dva.flight.discrete_model.DiscreteWing`'s, as the runtime's) with
the states and forces of all flights; once their c2 differ, the new conditions of the block
are discretised together and the flights step on their own one-sample maps.

When the commands do not depend on the response (a c2 from time and flight condition), no
block-by-block flight is needed: :func:`damper_schedule` gives the c2 of every sample and
:func:`fly_held_commands` flies every seed whole with it through the batch simulator.

The same model, parameter hold (the flight quantum), forces, damper rules and divergence (half
the chord) as the one-flight route, so a flight's samples agree with :class:`FlightRuntime`'s
to rounding (products summed in another order). A flight stops after the block in which it
diverged, as a flown one does. Nominal wings only: a hidden plant or a stepped sweep fly one
at a time (:func:`batch_problem`); the switching law is not commanded here. Pure numerics.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from aero_dva.flight.damper import DamperModel
from aero_dva.flight.discrete_model import (
    DEFAULT_HOLD,
    FLIGHT_QUANTUM,
    N_DISPLACEMENTS,
    N_OUTPUTS,
    DiscreteWing,
)
from aero_dva.flight.flight_runtime import resolved_scenario
from aero_dva.flight.samples import FlightSamples
from aero_dva.flight.scenario import (
    airspeed_at,
    density_at,
    force_scale_at,
    resolve_airspeeds,
    sample_times,
)
from aero_dva.wing.model import LEADING_EDGE, AeroelasticModel

__all__ = ["IdealDampers", "SeedBatchRuntime",
           "batch_problem", "damper_schedule", "fly_held_commands"]


def batch_problem(config) -> str | None:
    """Why the flights of ``config`` (a RuntimeConfig) cannot be flown as a seed batch, or
    None when they can."""
    scenario = config.scenario
    if scenario.plant is not None and scenario.plant.active:
        return "the scenario flies a hidden plant"
    if scenario.airspeed.kind == "steps":
        return "the scenario is a stepped sweep (it operates the damper itself)"
    if config.absorber is None:
        return "the wing flies without absorber"
    return None


class IdealDampers:
    """:class:`~aero_dva.flight.damper.DamperModel` without lag (``time_constant`` 0) for many
    flights at once: the same rules on arrays. Before a first accepted command the initial c2
    acts; a command is accepted when it is finite, >= 0 and not absurd, clipped to the range,
    and acts at once; once the last accepted command is older than the stale timeout, the
    fallback acts. NaN means no command (the node publishes none)."""

    def __init__(self, config, flights: int):
        if config.time_constant != 0.0:
            raise ValueError("IdealDampers model a damper without lag (time_constant 0)")
        self.config = config
        self.accepted_time = np.full(flights, math.nan)
        self.accepted = np.full(flights, math.nan)

    def values(self, which: np.ndarray, t: float) -> np.ndarray:
        """[N s/m] c2 acting at sim time ``t`` in the flights ``which``."""
        cfg = self.config
        at = self.accepted_time[which]
        with np.errstate(invalid="ignore"):
            stale = t > at + cfg.stale_timeout
        return np.where(np.isnan(at), cfg.initial_damping,
                        np.where(stale, cfg.fallback_damping, self.accepted[which]))

    def command(self, which: np.ndarray, damping: np.ndarray, t: float) -> None:
        """Commands ``damping`` to the flights ``which`` at sim time ``t``."""
        cfg = self.config
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(damping) & (damping >= 0.0) & (damping <= cfg.absurd_limit)
        self.accepted_time[which[ok]] = t
        self.accepted[which[ok]] = np.minimum(np.maximum(damping[ok], cfg.min_damping),
                                              cfg.max_damping)


class SeedBatchRuntime:
    """Step the flights of ``config`` with ``seeds`` block by block (see module docstring).

    Parameters
    ----------
    config : RuntimeConfig
        Its scenario's seed is replaced by each of ``seeds``.
    seeds : sequence of int
    critical_airspeed : float, optional
        [m/s] the bare wing's U_cr (solved if not given), for relative airspeeds.
    """

    def __init__(self, config, seeds: Sequence[int], critical_airspeed: float | None = None):
        problem = batch_problem(config)
        if problem is not None:
            raise ValueError(f"these flights cannot be flown as a seed batch: {problem}")
        seeds = [int(s) for s in seeds]
        if not seeds:
            raise ValueError("seeds must not be empty")
        self.config = config
        self.seeds = seeds
        self.critical_airspeed, self.scenario = resolved_scenario(config, critical_airspeed)
        self.sample_rate = self.scenario.sample_rate
        self.block_size = self.scenario.block_size
        model = AeroelasticModel(config.wing, config.absorber, config.aero)
        # As the runtime's streaming simulator: the default hold, the flight quantum.
        self.discrete = DiscreteWing(model, self.sample_rate, hold=DEFAULT_HOLD,
                                     quantum=FLIGHT_QUANTUM)
        self.divergence_limit = 0.5 * config.wing.chord
        # One damper per flight: as arrays when it has no lag (the evaluation's).
        self._dampers = IdealDampers(config.damper, len(seeds)) \
            if config.damper.time_constant == 0.0 else \
            [DamperModel(config.damper, start_time=0.0) for _ in seeds]
        self._rngs = [np.random.default_rng(s) for s in seeds]
        self._y = np.zeros((len(seeds), model.n_states))
        self._held_flight = (math.nan, math.nan)  # airspeed, density in force (shared)
        self._held_c = np.full(len(seeds), math.nan)
        self._index = 0
        self._checked = False
        self._steps = _StepMaps(self.discrete)
        self.active = np.arange(len(seeds))  # flights still flying

    @property
    def time(self) -> float:
        """[s] sim time of the next sample."""
        return self._index / self.sample_rate

    @property
    def done(self) -> bool:
        return self._index >= self.scenario.n_samples or self.active.size == 0

    def command(self, damping, source: str) -> None:
        """Hand each active flight its c2 command (``damping`` (F_a,) or one for all, NaN: no
        command) at the current sim time."""
        t = self.time
        which = self.active
        values = np.broadcast_to(np.asarray(damping, dtype=float), which.shape)
        if isinstance(self._dampers, IdealDampers):
            self._dampers.command(which, values, t)
            return
        for f, c2 in zip(which.tolist(), values.tolist()):
            if not math.isnan(c2):
                self._dampers[f].command(c2, t, source)

    def _damper_values(self, t: float) -> np.ndarray:
        which = self.active
        if isinstance(self._dampers, IdealDampers):
            return self._dampers.values(which, t)
        return np.array([self._dampers[f].update(t) for f in which.tolist()])

    def step(self) -> FlightSamples:
        """Simulate the next block of every active flight: their samples with a leading axis
        of flights (``flights``: their indices into the seeds; airspeed and density the same
        for all, each its own c2 held over the block); flights that diverge in it are dropped
        afterwards (its ``diverged``)."""
        scenario = self.scenario
        n = min(self.block_size, scenario.n_samples - self._index)
        if n <= 0 or self.active.size == 0:
            raise ValueError("the flights are over")
        flights = self.active
        t = sample_times(scenario, self._index, n)
        airspeed = airspeed_at(scenario, t)
        density = density_at(scenario, t)
        # The damper is updated once per block: commands arrive between blocks.
        c2 = self._damper_values(float(t[0]))
        force = np.empty((flights.size, n))
        for row, f in enumerate(flights.tolist()):
            force[row] = self._rngs[f].standard_normal(n)
        force *= scenario.force_std
        if scenario.force_levels:
            force *= force_scale_at(scenario, t)
        if not self._checked:
            self.discrete.check_sampling(float(airspeed[0]), float(density[0]), float(c2[0]))
            self._checked = True
        out, y = self._advance(self._y[flights], force, airspeed, density, c2)
        self._y[flights] = y
        disp = out[:, :N_DISPLACEMENTS]
        diverged = ~np.isfinite(y).all(axis=1) | ~np.isfinite(disp).all(axis=(1, 2)) | \
            (np.abs(disp[:, LEADING_EDGE]).max(axis=1) > self.divergence_limit)
        block = FlightSamples(
            first_index=self._index, sample_rate=self.sample_rate, airspeed=airspeed,
            density=density, damping=np.broadcast_to(c2[:, None], (flights.size, n)),
            force=force, displacements=disp, accelerations=out[:, N_DISPLACEMENTS:],
            diverged=diverged, flights=flights)
        self._index += n
        self.active = flights[~diverged]
        # (The runtime also advances its damper to t_end here; a command at t_end does that
        # itself, and the next block's update too, to the same value.)
        return block

    def _advance(self, y, force, airspeed, density, c2):
        """Samples ``index .. index + n - 1`` of the flights ``y`` (F_a, n_states) hold period by
        hold period; returns the outputs (F_a, p, n) and the end states."""
        dw = self.discrete
        total, h = force.shape[1], dw.hold
        q = dw.quantum
        first = min((h - self._index % h) % h, total)  # samples left in the current period
        flights = self.active
        held_c = self._held_c[flights]
        held_u, held_rho = self._held_flight
        segments = [(0, first, held_u, held_rho, held_c)] if first else []
        for a in range(first, total, h):
            # The parameter hold of the flight runtime, per input (next_held).
            u, rho = float(airspeed[a]), float(density[a])
            held_u = held_u if abs(u - held_u) <= q * abs(held_u) else u
            held_rho = held_rho if abs(rho - held_rho) <= q * abs(held_rho) else rho
            held_c = np.where(np.abs(c2 - held_c) <= q * np.abs(held_c), held_c, c2)
            segments.append((a, min(a + h, total), held_u, held_rho, held_c))
        self._held_flight = (held_u, held_rho)
        self._held_c[flights] = held_c
        out = np.empty((flights.size, N_OUTPUTS, total))
        if all(bool((c == c[0]).all()) for *_, c in segments):
            y = self._shared_conditions(y, force, segments, out)
        else:
            y = self._own_conditions(y, force, segments, out)
        return out, y

    def _shared_conditions(self, y, force, segments, out):
        """Every flight holds one condition per segment: a full hold period is one product of
        its period map (as the streaming simulator's) with all flights' states and forces."""
        dw = self.discrete
        h, ns = dw.hold, dw.n_states
        maps = dw.conditions([(u, rho, float(c[0])) for _, _, u, rho, c in segments])
        for (a, b, *_), cond in zip(segments, maps):
            if b - a == h:
                r = cond.period @ np.concatenate((y, force[:, a:b]), axis=1).T
                y = r[:ns].T
                out[:, :, a:b] = r[ns:].reshape(N_OUTPUTS, h, -1).transpose(2, 0, 1)
                continue
            for j in range(a, b):  # a partial period: sample by sample
                r = cond.step @ np.concatenate((y, force[:, j:j + 1]), axis=1).T
                y = r[:ns].T
                out[:, :, j] = r[ns:].T
        return y

    def _own_conditions(self, y, force, segments, out):
        """Each flight its own condition: the one-sample maps of all of them, stepped
        together (a period map per flight would cost more to build than it saves)."""
        ns = self.discrete.n_states
        keys = [(u, rho, v) for _, _, u, rho, c in segments for v in c.tolist()]
        index = self._steps.lookup(keys).reshape(len(segments), -1)
        steps = self._steps.maps
        x = np.empty((y.shape[0], ns + 1, 1))
        r = np.empty((y.shape[0], ns + N_OUTPUTS, 1))
        x[:, :ns, 0] = y
        for (a, b, *_), k in zip(segments, index):
            m = steps[k]  # (F_a, n + p, n + 1)
            for j in range(a, b):
                x[:, ns, 0] = force[:, j]
                np.matmul(m, x, out=r)
                x[:, :ns] = r[:, :ns]
                out[:, :, j] = r[:, ns:, 0]
        return x[:, :ns, 0].copy()


class _StepMaps:
    """One-sample maps ``[[Ad, Bd], [C, D]]`` of held conditions kept by exact key in one
    array (gathered per flight); discretised in batches, dropped when ``max_size`` is reached."""

    def __init__(self, discrete: DiscreteWing, max_size: int = 8192):
        self.discrete, self.max_size = discrete, max_size
        n = discrete.n_states
        self.maps = np.empty((256, n + N_OUTPUTS, n + 1))
        self.index: dict[tuple, int] = {}

    def lookup(self, keys: list[tuple]) -> np.ndarray:
        """Rows of :attr:`maps` of the conditions ``keys`` ((U, rho, c2) tuples)."""
        index = self.index
        missing = [k for k in dict.fromkeys(keys) if k not in index]
        if missing:
            if len(index) + len(missing) > self.max_size:
                index.clear()
                missing = list(dict.fromkeys(keys))
            start = len(index)
            if start + len(missing) > len(self.maps):
                grown = np.empty((max(2 * len(self.maps), start + len(missing)),)
                                 + self.maps.shape[1:])
                grown[:start] = self.maps[:start]
                self.maps = grown
            m = self.discrete.discretise(np.array(missing, dtype=float))
            n = self.discrete.n_states
            block = self.maps[start:start + len(missing)]
            block[:, :n, :n], block[:, :n, n] = m.ad, m.bd
            block[:, n:, :n], block[:, n:, n] = m.c, m.d
            for i, key in enumerate(missing, start):
                index[key] = i
        return np.fromiter((index[k] for k in keys), dtype=np.intp, count=len(keys))


def damper_schedule(config, critical_airspeed: float, command, source: str) -> np.ndarray:
    """c2 [N s/m] of every sample when the commands do not depend on the response.

    ``command(block)`` is asked after each block (its FlightSamples with the block's time and
    flight condition; its response arrays are NaN) and returns a c2 or None, which the damper
    (the runtime's DamperModel, updated once per block) takes at the block's end, as
    :class:`FlightRuntime` takes a controller's command.
    """
    scenario = resolve_airspeeds(config.scenario, critical_airspeed)
    total, size = scenario.n_samples, scenario.block_size
    damper = DamperModel(config.damper, start_time=0.0)
    damping = np.empty(total)
    for a in range(0, total, size):
        n = min(size, total - a)
        t = sample_times(scenario, a, n)
        damping[a:a + n] = damper.update(float(t[0]))
        nan = np.full(n, math.nan)
        block = FlightSamples(first_index=a, sample_rate=scenario.sample_rate,
                              airspeed=airspeed_at(scenario, t),
                              density=density_at(scenario, t), damping=damping[a:a + n],
                              force=nan, displacements=np.full((N_DISPLACEMENTS, n), math.nan),
                              accelerations=np.full((N_OUTPUTS - N_DISPLACEMENTS, n),
                                                    math.nan))
        c2 = command(block)
        if c2 is not None:
            damper.command(c2, block.t_end, source)
    return damping


def fly_held_commands(config, seeds: Sequence[int], damping: np.ndarray,
                      critical_airspeed: float) -> FlightSamples:
    """The flights of ``seeds`` with the c2 of every sample given (:func:`damper_schedule`),
    whole, by the batch simulator (:func:`~aero_dva.flight.batch_simulator.simulate_flights`,
    vectorised across hold periods: no Python per block); each then ends with the block in
    which it diverged, as :class:`SeedBatchRuntime` and the runtime end it. The same hold (the
    default hold, the flight quantum) and forces (each seed's per-block draws, which are one
    draw of the whole flight), so the same flights up to rounding. The samples of the flights
    (a leading axis of flights; airspeed, density and c2 the same for all), each flown up to
    its ``samples`` (past them: not flown, undefined)."""
    from aero_dva.flight.batch_simulator import simulate_flights

    problem = batch_problem(config)
    if problem is not None:
        raise ValueError(f"these flights cannot be flown as a seed batch: {problem}")
    scenario = resolve_airspeeds(config.scenario, critical_airspeed)
    total, size = scenario.n_samples, scenario.block_size
    t = sample_times(scenario)
    force = np.stack([np.random.default_rng(int(s)).standard_normal(total) for s in seeds])
    force *= scenario.force_std
    if scenario.force_levels:
        force *= force_scale_at(scenario, t)
    airspeed, density = airspeed_at(scenario, t), density_at(scenario, t)
    with np.errstate(over="ignore", invalid="ignore"):  # diverged flights run on, cut below
        traces = simulate_flights(config.wing, config.absorber, force=force, airspeed=airspeed,
                                  density=density, damping=damping,
                                  sample_rate=scenario.sample_rate, aero=config.aero,
                                  hold=DEFAULT_HOLD, quantum=FLIGHT_QUANTUM)
        disp = traces.displacements
        bad = ~np.isfinite(disp).all(axis=1) | \
            (np.abs(disp[:, LEADING_EDGE]) > 0.5 * config.wing.chord)
    diverged = bad.any(axis=1)
    first_bad = np.where(diverged, bad.argmax(axis=1), total)
    samples = np.minimum((first_bad // size + 1) * size, total)
    return FlightSamples(first_index=0, sample_rate=scenario.sample_rate, airspeed=airspeed,
                         density=density, damping=damping, force=force, displacements=disp,
                         accelerations=traces.accelerations, diverged=diverged,
                         samples=samples)
