"""The flight runtime: one scenario flown block by block, what the simulator node steps (no ROS).

:class:`FlightRuntime` ties a scenario, the wing with its tunable Maxwell DVA, the damper model
and the seeded excitation together. The simulator node calls :meth:`FlightRuntime.step` and
publishes what it returns; the batch path and the tests call the same code, so a seed gives the
same data through either route. A scenario with an active ``plant`` section flies the hidden
plant of :mod:`aero_dva.flight.hidden_plant` instead of the nominal model; what is published (and
the damper state) stays the same in kind, so the log does not reveal the plant options.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from aero_dva import data_files
from aero_dva.flight.applied_control import AppliedControl
from aero_dva.flight.damper import (
    DAMPER_RANGE,
    DEFAULT_STALE_TIMEOUT,
    SWITCHING_SOURCE,
    CommandResult,
    DamperConfig,
    DamperMode,
    DamperModel,
    DamperSnapshot,
)
from aero_dva.flight.discrete_model import FLIGHT_QUANTUM
from aero_dva.flight.hidden_plant import PlantSimulator
from aero_dva.flight.samples import FlightSamples
from aero_dva.flight.scenario import (
    Scenario,
    airspeed_at,
    density_at,
    force_scale_at,
    resolve_airspeeds,
    sample_times,
    sweep_damping_at,
)
from aero_dva.flight.scenario_io import load_scenario
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.text_input import loggable
from aero_dva.wing.absorbers import MaxwellAbsorber
from aero_dva.wing.critical_cache import critical_airspeed as kept_critical_airspeed
from aero_dva.wing.model import WingParameters
from aero_dva.wing.wing_io import load_wing

ABSORBER_CHOICES = ("maxwell", "none")
SWEEP_SOURCE = "sweep"  # dva_msgs/DamperCommand.SOURCE_SWEEP


@dataclass(frozen=True)
class RuntimeConfig:
    """Everything a flight needs, validated.

    Attributes
    ----------
    scenario : Scenario
        With airspeeds still possibly relative to the critical airspeed without DVA.
    wing : WingParameters
    aero : aerodynamic model of the wing file (quasi-steady by default)
    absorber : MaxwellAbsorber or None
        None flies the bare wing.
    damper : DamperConfig
    per_sample : mapping
        Command source -> the gains of the per-sample law the damper's own controller runs
        while the commands in force come from that source (``"switching"``,
        ``"clipped_optimal"``; :func:`aero_dva.control.switching_io.with_per_sample` sets
        them), or -> the reason it cannot run (a ``str``: no file, an invalid file, a file for
        another wing). A source with neither is a constant c2 like any other.
    sensor_noise : float
        Noise on the measurements of the per-sample law's observer (the absorber stroke and
        the three accelerations), std as a fraction of each one's stationary RMS at U_cr with
        the law's middle c2 (0: exact measurements). Drawn from a generator of its own, seeded
        from the scenario's seed, so the aileron force stays that of the seed.
    """

    scenario: Scenario
    wing: WingParameters
    aero: object
    absorber: MaxwellAbsorber | None
    damper: DamperConfig
    per_sample: Mapping[str, object] = field(default_factory=dict)
    sensor_noise: float = 0.0


def _nan_or(value: float, default: float) -> float:
    return default if value is None or (isinstance(value, float) and math.isnan(value)) else value


def load_runtime_config(params: dict) -> RuntimeConfig:
    """Build a :class:`RuntimeConfig` from node-style parameters (see simulator_node).

    Empty paths take the package's defaults; NaN absorber and damper values take the wing file's
    Maxwell design. Raises ValueError naming the bad parameter.
    """
    scenario_path = params.get("scenario") or data_files.data_file("scenario_ramp.yaml")
    scenario = load_scenario(scenario_path)
    wing_file = load_wing(params.get("wing") or None)
    choice = params.get("absorber", "maxwell")
    if choice not in ABSORBER_CHOICES:
        raise ValueError(f"parameter 'absorber' must be one of {ABSORBER_CHOICES}, got {choice!r}")
    design = wing_file.maxwell_design
    absorber = None
    if choice == "maxwell":
        absorber = MaxwellAbsorber(
            mass=_nan_or(params.get("absorber_mass"), design.mass),
            stiffness=_nan_or(params.get("absorber_stiffness"), design.stiffness),
            series_stiffness=_nan_or(params.get("absorber_series_stiffness"),
                                     design.series_stiffness),
            damping=design.damping,
            position=_nan_or(params.get("absorber_position"), design.position),
        )
        wing_file.wing.check_on_chord(absorber.position, "absorber_position")
    low = float(params.get("damper_min", DAMPER_RANGE[0]))
    high = float(params.get("damper_max", DAMPER_RANGE[1]))
    fallback = _nan_or(params.get("damper_fallback"), min(max(design.damping, low), high))
    damper = DamperConfig(
        min_damping=low, max_damping=high, fallback_damping=fallback,
        initial_damping=_nan_or(params.get("damper_initial"), fallback),
        stale_timeout=float(params.get("damper_timeout", DEFAULT_STALE_TIMEOUT)),
        time_constant=float(params.get("damper_time_constant", 0.0)),
    )
    problem = sweep_problem(scenario, damper)
    if problem is not None:
        raise ValueError(f"{problem} (parameters damper_min, damper_max)")
    noise = float(params.get("damper_sensor_noise", 0.0))
    if not (math.isfinite(noise) and 0.0 <= noise <= 10.0):
        raise ValueError(f"parameter 'damper_sensor_noise' must be a fraction in [0, 10], got "
                         f"{noise}")
    return RuntimeConfig(scenario=scenario, wing=wing_file.wing, aero=wing_file.aero,
                         absorber=absorber, damper=damper, sensor_noise=noise)


def sweep_problem(scenario: Scenario, damper: DamperConfig) -> str | None:
    """Why a stepped sweep's own c2 values cannot be flown with ``damper``, or None."""
    return damper.range_problem(scenario.sweep_damping,
                                f"scenario {scenario.name!r}: sweep c2 values")


def resolved_scenario(config: RuntimeConfig, critical_airspeed: float | None = None):
    """(U_cr, the scenario with absolute airspeeds): relative airspeeds (U/U_cr, as the study
    states them) refer to the wing without DVA; a caller that flies many flights of one wing
    passes the U_cr it already has."""
    u_cr = (kept_critical_airspeed(config.wing, config.scenario.density, config.aero)
            if critical_airspeed is None else float(critical_airspeed))
    return u_cr, resolve_airspeeds(config.scenario, u_cr)


class FlightRuntime:
    """Step a flight block by block (see module docstring).

    ``compiled``: the nominal wing's blocks are stepped by the compiled loop
    (:class:`~aero_dva.flight.streaming_simulator.StreamingSimulator`, ``compiled``; the
    simulator node's default), loaded by :meth:`prepare`; else in NumPy.
    """

    def __init__(self, config: RuntimeConfig, critical_airspeed: float | None = None,
                 compiled: bool = False):
        problem = sweep_problem(config.scenario, config.damper)
        if problem is not None:
            raise ValueError(problem)
        self.config = config
        self.critical_airspeed, self.scenario = resolved_scenario(config, critical_airspeed)
        self.sample_rate = self.scenario.sample_rate
        self.block_size = self.scenario.block_size
        self.block_duration = self.block_size / self.sample_rate
        # Held airspeed/density/c2 change only by more than FLIGHT_QUANTUM (0.1 %) so a ramp
        # reuses cached discretisations (eigenvalue shifts ~1e-3 relative, far below the
        # model's accuracy).
        plant = self.scenario.plant
        if plant is not None and plant.active:
            # Hidden plant: the wing flown differs from the model the log implies.
            self._sim = PlantSimulator(config.wing, config.absorber, self.sample_rate,
                                       config.aero, plant, seed=self.scenario.seed)
        else:
            self._sim = StreamingSimulator(config.wing, config.absorber,
                                           sample_rate=self.sample_rate, aero=config.aero,
                                           quantum=FLIGHT_QUANTUM, compiled=compiled)
        self._check_sampling()
        self._damper = DamperModel(config.damper, start_time=0.0)
        self._rng = np.random.default_rng(self.scenario.seed)
        self._index = 0
        self._inputs: tuple | None = None  # (first sample, t, airspeed, density) of a block
        self._sweep = self.scenario.airspeed.kind == "steps"
        self._laws: dict = {}  # source -> its per-sample law's damper path, built when armed
        self._flown_law = (-1, None)  # (first sample, law) of the last block a law flew
        self._noise_rng = np.random.default_rng([self.scenario.seed, 1])  # the sensors'
        self._noise_scale: dict = {}  # source -> sensor noise std (4,)
        self.applied = AppliedControl()  # blocks by the source of the c2 they were flown with
        self._flown: DamperSnapshot | None = None  # the damper over the last block

    def _check_sampling(self) -> None:
        """Refuse, before the first block, a flight whose wing has a mode at or above the
        Nyquist frequency somewhere in its flight (an absorber of a gram, a spring of 1e12
        N/m): checked at the ends of its airspeed and density ranges and of the damper's."""
        from aero_dva.flight.discretize import check_sampling
        from aero_dva.wing.model import AeroelasticModel

        s, absorber = self.scenario, self.config.absorber
        model = AeroelasticModel(self.config.wing, absorber, self.config.aero)
        speeds = np.asarray(s.airspeed.values, dtype=float)
        densities = s.density * (1.0 + s.density_variation * np.array([-1.0, 1.0]))
        dampers = (None,) if absorber is None else self.config.damper.damping_range
        for u in (speeds.min(), speeds.max()):
            for rho in densities:
                for c2 in dampers:
                    a, _ = model.matrices(u, rho, c2)
                    try:
                        check_sampling(a, 1.0 / s.sample_rate)
                    except ValueError as exc:
                        raise ValueError(f"scenario {loggable(s.name)!r}: {exc} (at "
                                         f"{u:g} m/s)") from None

    @property
    def sweeps_damping(self) -> bool:
        """The scenario is a stepped sweep that operates the damper itself (commands ignored)."""
        return self._sweep

    @property
    def time(self) -> float:
        """[s] sim time of the next sample."""
        return self._index / self.sample_rate

    @property
    def done(self) -> bool:
        return self._index >= self.scenario.n_samples

    def command(self, damping: float, source: str) -> CommandResult | None:
        """Hand a c2 command to the damper at the current sim time (None: a sweep ignores it)."""
        if self._sweep:
            return None
        return self._damper.command(damping, self.time, source)

    def damper_snapshot(self) -> DamperSnapshot:
        """The damper now (after the last block: a command may still come before the next)."""
        return self._damper.snapshot()

    @property
    def flown_damper(self) -> DamperSnapshot | None:
        """The damper the last block was flown with: its state at the block's start (time,
        applied c2, status, source), with the block's mode and switching rate. This is what
        ``dva/damper_state`` records, so a bag's c2 at a sample is the c2 that sample had (the
        state at the block's end is the next block's only if no command comes between)."""
        return self._flown

    def next_condition(self) -> tuple[float, float, float]:
        """(t0 [s], airspeed [m/s], density [kg/m^3]) of the next block's first sample, known
        from the scenario before the block is flown: the values :meth:`step` flies it with
        (the same arrays, kept for it), so a flight condition published ahead of its block
        equals the block's."""
        if self.done:
            raise ValueError("the flight is over")
        t, airspeed, density = self._block_inputs()
        return float(t[0]), float(airspeed[0]), float(density[0])

    def _block_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The next block's sample times, airspeeds and densities (computed once per block)."""
        if self._inputs is None or self._inputs[0] != self._index:
            n = min(self.block_size, self.scenario.n_samples - self._index)
            t = sample_times(self.scenario, self._index, n)
            self._inputs = (self._index, t, airspeed_at(self.scenario, t),
                            density_at(self.scenario, t))
        return self._inputs[1:]

    def step(self) -> FlightSamples:
        """Simulate the next block (shorter at the end of the flight): its samples, with the c2
        the damper applied; with a per-sample law armed, also the law's targets and the damper
        force at each sample (``damper_force``)."""
        if self.done:
            raise ValueError("the flight is over")
        t, airspeed, density = self._block_inputs()
        n = t.size
        if self._sweep:
            # The sweep operates the damper itself: command it every block so the damper's
            # state (and dva/damper_state) reports the c2 the wing really has.
            damping = sweep_damping_at(self.scenario, t)
            self._damper.command(float(damping[0]), float(t[0]), SWEEP_SOURCE)
            self._damper.update(float(t[0]))
        else:
            # The damper is updated once per block: commands arrive between blocks.
            damping = np.full(n, self._damper.update(float(t[0])))
        start = self._damper.snapshot()
        self.applied.count(start.source)
        force = self.scenario.force_std * self._rng.standard_normal(n)
        if self.scenario.force_levels:
            force *= force_scale_at(self.scenario, t)
        source = None if self._sweep else self._damper.source_in_force
        asked = source is not None and source in self.config.per_sample
        mode, rate, law_c2, law_out = DamperMode.CONSTANT, 0.0, None, None
        for other, path in self._laws.items():  # one law runs at a time
            if other != source and path.armed:
                path.disarm()
        if asked and self.law_problem(source) is None:
            law = self._per_sample_path(source)
            if not law.armed:
                law.arm(self._sim.state, float(damping[0]))
            out = law.advance(self._index, force, airspeed, density,
                              self._sensor_noise(source, n))
            diverged = bool(self._sim.diverged or not np.all(np.isfinite(out.state))
                            or np.max(np.abs(out.displacements[2]))
                            > self._sim.divergence_limit)
            self._sim.continue_from(out.state, n, diverged)
            damping, displacements, accelerations = out.damping, out.displacements, \
                out.accelerations
            mode, rate, law_c2 = DamperMode.SWITCHING, law.switches * self.sample_rate / n, \
                law.damping
            law_out = out
            self._flown_law = (self._index, law.law)
        else:
            if source in self._laws:
                self._laws[source].disarm()
            if asked:
                mode = DamperMode.SWITCHING_REFUSED
            sim_out = self._sim.advance(force, airspeed, density,
                                        damping if self.config.absorber is not None else None)
            displacements, accelerations = sim_out.displacements, sim_out.accelerations
            diverged = sim_out.diverged
        block = FlightSamples(
            first_index=self._index, sample_rate=self.sample_rate, airspeed=airspeed,
            density=density, damping=damping, force=force, displacements=displacements,
            accelerations=accelerations, diverged=diverged,
            target=None if law_out is None else law_out.target,
            damper_force=None if law_out is None else law_out.damper_force)
        self._index += n
        if not self._sweep:
            self._damper.update(block.t_end)
        self._damper.record_mode(mode, rate, law_c2)
        self._flown = replace(start, mode=DamperMode(mode), switching_rate=float(rate))
        return block

    def commanded_damping(self, block: FlightSamples) -> np.ndarray | None:
        """[N s/m] (n,) the c2 the per-sample law commanded for each sample of ``block`` (the
        last block :meth:`step` returned): its target, the law's c_hi or c_lo, before the
        damper's lag; None for a block no law flew."""
        if block.target is None:
            return None
        first, law = self._flown_law
        if first != block.first_index:
            raise ValueError("commanded_damping needs the last block step returned")
        return np.where(block.target, law.c_hi, law.c_lo)

    def law_problem(self, source: str = SWITCHING_SOURCE) -> str | None:
        """Why the per-sample law of commands from ``source`` cannot run in this flight, or
        None."""
        gains = self.config.per_sample.get(source)
        if gains is None:
            return f"no per-sample law for commands from {source!r}"
        if isinstance(gains, str):
            return gains
        if self.config.absorber is None:
            return "the wing flies without absorber"
        if not isinstance(self._sim, StreamingSimulator):
            return "the law runs on the nominal wing only (the scenario has a hidden plant)"
        law = gains.law
        problem = self.config.damper.range_problem((law.c_lo, law.c_hi),
                                                   f"the {source} gains' c_lo and c_hi")
        if problem is not None:
            return problem
        if abs(gains.sample_rate - self.sample_rate) > 1e-9:
            return (f"the {source} gains are for {gains.sample_rate:g} Hz, the flight samples "
                    f"at {self.sample_rate:g} Hz")
        return None

    def prepare(self) -> None:
        """Load ahead of the flight what it may need in mid-flight: for each per-sample law that
        can run, its compiled loop (numba's import and its cached code, about a second of CPU
        that would otherwise fall between two blocks when a law is first armed) and its sensor
        noise's scale (scipy's Lyapunov solver). A throwaway copy of the law flies one sample;
        the flight's own starts afresh. A flight no per-sample law can run in loads neither
        (numba and scipy are imported only for a law that can run)."""
        if isinstance(self._sim, StreamingSimulator) and self._sim.compiled:
            t = sample_times(self.scenario, 0, 1)
            self._sim.prepare(float(airspeed_at(self.scenario, t)[0]),
                              float(density_at(self.scenario, t)[0]),
                              self._damper.snapshot().applied_damping
                              if self.config.absorber is not None else None)
        for source in self.config.per_sample:
            if self._sweep or self.law_problem(source) is not None:
                continue
            from aero_dva.flight.per_sample.stream import SwitchedStream

            law = SwitchedStream(self._sim.model, self.config.per_sample[source].law,
                                 self.sample_rate, self.config.damper.time_constant,
                                 quantum=FLIGHT_QUANTUM)
            t = sample_times(self.scenario, 0, 1)
            law.arm(np.zeros(self._sim.n_states), self._damper.snapshot().applied_damping)
            law.advance(0, np.zeros(1), airspeed_at(self.scenario, t),
                        density_at(self.scenario, t))
            self._noise_std(source)

    def _per_sample_path(self, source: str):
        if source not in self._laws:
            from aero_dva.flight.per_sample.stream import SwitchedStream

            self._laws[source] = SwitchedStream(
                self._sim.model, self.config.per_sample[source].law, self.sample_rate,
                self.config.damper.time_constant, quantum=FLIGHT_QUANTUM)
        return self._laws[source]

    def _sensor_noise(self, source: str, n: int) -> np.ndarray | None:
        """The noise on the law's measurements over the next ``n`` samples (None: none)."""
        if not self.config.sensor_noise:
            return None
        return self._noise_rng.standard_normal((n, 4)) * self._noise_std(source)

    def _noise_std(self, source: str) -> np.ndarray:
        """[SI] (4,) the sensor noise's std of the law of ``source`` (module docstring)."""
        if source not in self._noise_scale:
            from aero_dva.flight.per_sample.switching_law import measured_rms

            law = self.config.per_sample[source].law
            self._noise_scale[source] = self.config.sensor_noise * measured_rms(
                self._sim.model, self.critical_airspeed, self.scenario.density,
                math.sqrt(law.c_lo * law.c_hi), self.sample_rate, self.scenario.force_std)
        return self._noise_scale[source]

    def describe(self) -> dict:
        """A short summary for logs."""
        u = np.asarray(self.scenario.airspeed.values)
        absorber = self.config.absorber
        return {
            "scenario": loggable(self.scenario.name), "duration_s": self.scenario.duration,
            "sample_rate_hz": self.sample_rate, "airspeed_min": float(u.min()),
            "airspeed_max": float(u.max()), "critical_airspeed": self.critical_airspeed,
            "absorber": "none" if absorber is None else (
                f"maxwell m1={absorber.mass:g} kg k1={absorber.stiffness:g} N/m "
                f"k2={absorber.series_stiffness:g} N/m at {absorber.position:g} m"),
        }


