"""Plant effects a flight log does not reveal ("hidden plant"), to test model-discrepancy tools.

The simulator normally flies exactly the model the analysis tools assume. With
:class:`PlantOptions` it flies a plant that differs from that model in ways nothing in the
recorded topics names:

- ``actuator_lag`` T [s]: the c2 acting on the wing follows the c2 the damper reports
  (``dva/damper_state``) through a first-order lag, c2_true' = (c2_reported - c2_true) / T.
- ``sensor_delay`` tau [s]: the accelerometer channels are delayed by tau (whole samples).
- ``cubic_stiffness`` kappa [1/rad^2]: hardening pitch spring, moment k_alpha (alpha +
  kappa alpha^3) (nonlinear; the cubic part is applied as a pitch moment sampled each step).
- ``unsteady_aero`` s [-]: Wagner's indicial lift in R. T. Jones' two-lag form
  (:class:`~aero_dva.wing.aerodynamics.WagnerAero`) with the lag amplitudes A1, A2 scaled by s
  (s = 1: Jones), instead of the wing file's aerodynamics.
- ``drift_parameter`` / ``drift_rate`` r [1/s]: a structural stiffness (wing pitch or plunge,
  or the DVA spring k1, e.g. a rubber element softening as it warms) changes linearly over the
  flight, p(t) = p0 (1 + r t) (for the wing the stiffness-proportional damping C = beta K
  follows it).
- ``sensor_noise`` (plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2]): white Gaussian
  accelerometer noise with these standard deviations.
- ``sensor_gain`` (three factors): accelerometer calibration errors (an effect outside the
  discrepancy loop's library, for testing that it does not misattribute).

:class:`PlantSimulator` has the streaming interface of
:class:`~aero_dva.flight.streaming_simulator.StreamingSimulator` (``advance(force, airspeed,
density, damping)``) and flies the same :class:`~aero_dva.flight.discrete_model.DiscreteWing`
(one per drift step, with a pitch-moment input): exact ZOH steps with the condition held over
the default hold and only renewed when it moved by more than the flight quantum (0.1 %, as the
flight runtime; 2 % for the lagged c2, which moves continuously; 0.5 % for a drifting
stiffness), one matrix per hold period for a linear plant and sample by sample with a cubic
stiffness. So :class:`~aero_dva.flight.flight_runtime.FlightRuntime` swaps it in when a
scenario has a ``plant`` section. Pure numerics (no ROS).
"""
from __future__ import annotations

import dataclasses
import math
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
from aero_dva.flight.samples import FlightSamples
from aero_dva.wing.aerodynamics import QuasiSteadyAero, WagnerAero
from aero_dva.wing.model import ACCELERATION_NAMES, AeroelasticModel

DRIFT_PARAMETERS = ("pitch_stiffness", "plunge_stiffness", "absorber_stiffness")
CHANNELS = ACCELERATION_NAMES  # the accelerometers the sensor options act on
# The held airspeed, density and c2 change with FLIGHT_QUANTUM, the flight runtime's, so the
# plant flies every condition step the log shows (with 0.5 % a 0.3 % airspeed step between two
# dwells was not flown: the log then lied).
QUANTUM_DRIFT = 5e-3  # the drifting stiffness factor is applied in steps of 0.5 %
QUANTUM_LAGGED = 0.02  # the same for the lagged c2 (it moves continuously after each step)
DRIFT_UPDATE = 0.05  # [s] the drifting stiffness is updated at this interval
MAX_CUBIC_PITCH = 0.5  # [rad] beyond this the pitch "spring" is no longer a spring: diverged
PITCH = OUTPUT_NAMES.index("pitch")
LEADING_EDGE = OUTPUT_NAMES.index("leading_edge")


def _finite(name: str, value, low: float, high: float, low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"plant.{name} must be a number, got {value!r}")
    v = float(value)
    ok = math.isfinite(v) and (v > low if low_open else v >= low) and v <= high
    if not ok:
        side = "(" if low_open else "["
        raise ValueError(f"plant.{name} must be in {side}{low:g}, {high:g}], got {value!r}")
    return v


@dataclass(frozen=True)
class PlantOptions:
    """Hidden plant effects (module docstring); the defaults are the nominal plant.

    Attributes
    ----------
    actuator_lag : float
        Time constant [s] of the damper actuator, in [0, 60].
    sensor_delay : float
        Delay of the accelerometers [s], in [0, 1] (rounded to whole samples).
    cubic_stiffness : float
        kappa [1/rad^2] of the hardening pitch spring, in [0, 1e8].
    unsteady_aero : float
        Scale of Jones' lag amplitudes, in [0, 1.9]; 0 keeps the wing file's aerodynamics.
    drift_parameter : {"pitch_stiffness", "plunge_stiffness", "absorber_stiffness"}
    drift_rate : float
        [1/s] relative change of ``drift_parameter`` per second, |r| <= 0.05.
    sensor_noise : tuple of 3 float
        Accelerometer noise standard deviations (plunge [m/s^2], pitch [rad/s^2],
        leading edge [m/s^2]), >= 0.
    sensor_gain : tuple of 3 float
        Accelerometer gain factors, in (0, 10].
    """

    actuator_lag: float = 0.0
    sensor_delay: float = 0.0
    cubic_stiffness: float = 0.0
    unsteady_aero: float = 0.0
    drift_parameter: str = "pitch_stiffness"
    drift_rate: float = 0.0
    sensor_noise: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_gain: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        _finite("actuator_lag", self.actuator_lag, 0.0, 60.0)
        _finite("sensor_delay", self.sensor_delay, 0.0, 1.0)
        _finite("cubic_stiffness", self.cubic_stiffness, 0.0, 1e8)
        _finite("unsteady_aero", self.unsteady_aero, 0.0, 1.9)
        _finite("drift_rate", self.drift_rate, -0.05, 0.05)
        if self.drift_parameter not in DRIFT_PARAMETERS:
            raise ValueError(f"plant.drift.parameter must be one of {DRIFT_PARAMETERS}, "
                             f"got {self.drift_parameter!r}")
        for name, values, low, low_open in (("sensor_noise", self.sensor_noise, 0.0, False),
                                            ("sensor_gain", self.sensor_gain, 0.0, True)):
            if len(values) != 3:
                raise ValueError(f"plant.{name} needs 3 values ({', '.join(CHANNELS)}), "
                                 f"got {values!r}")
            object.__setattr__(self, name, tuple(
                _finite(f"{name}.{ch}", v, low, 1e6 if name == "sensor_noise" else 10.0,
                        low_open) for ch, v in zip(CHANNELS, values)))

    @property
    def active(self) -> bool:
        """True unless every option is nominal."""
        return self != PlantOptions(drift_parameter=self.drift_parameter)

    def check_duration(self, duration: float) -> None:
        """Raise ValueError if the drift would make the stiffness (nearly) vanish."""
        if abs(self.drift_rate) * duration > 0.5:
            raise ValueError(
                f"plant.drift.rate {self.drift_rate:g} 1/s changes {self.drift_parameter} by "
                f"{100 * self.drift_rate * duration:.0f} % over the {duration:g} s flight "
                "(at most 50 % allowed)")


class PlantSimulator:
    """Streaming simulator of the hidden plant (``StreamingSimulator``'s ``advance`` contract).

    Parameters
    ----------
    wing : WingParameters
    absorber : MaxwellAbsorber or PassiveAbsorber or None
    sample_rate : float
        [Hz]
    aero : aerodynamic model of the wing file (replaced by Wagner's when ``unsteady_aero``)
    plant : PlantOptions
    seed : int
        Seed of the sensor noise (independent of the excitation's random stream).
    divergence_limit : float, optional
        [m] leading-edge displacement that counts as divergence (default half the chord).
    """

    def __init__(self, wing, absorber, sample_rate: float, aero, plant: PlantOptions,
                 seed: int = 0, divergence_limit: float | None = None):
        if not isinstance(plant, PlantOptions):
            raise TypeError(f"plant must be PlantOptions, got {type(plant).__name__}")
        self.plant = plant
        self.wing0, self.absorber = wing, absorber
        if plant.unsteady_aero > 0:
            jones = WagnerAero()
            aero = WagnerAero(a1=jones.a1 * plant.unsteady_aero, b1=jones.b1,
                              a2=jones.a2 * plant.unsteady_aero, b2=jones.b2)
        self.aero = QuasiSteadyAero() if aero is None else aero
        self.sample_rate = float(sample_rate)
        self.dt = 1.0 / self.sample_rate
        self.divergence_limit = 0.5 * wing.chord if divergence_limit is None else float(
            divergence_limit)
        self._rng = np.random.default_rng([int(seed), 0x5E75])  # not the excitation's stream
        self._delay = int(round(plant.sensor_delay * self.sample_rate))
        self.hold = DEFAULT_HOLD
        self._wings: dict[float, DiscreteWing] = {}
        self._index = 0
        self._y = None
        self._held = None
        self._c_true = None
        self._lag_decay = (math.exp(-self.dt / plant.actuator_lag)
                           if plant.actuator_lag > 0 else 0.0)
        self._pending = np.zeros((3, self._delay))  # delayed acceleration samples
        self._diverged = False
        self._checked = False

    @property
    def diverged(self) -> bool:
        return self._diverged

    def _wing(self, factor: float) -> DiscreteWing:
        """The plant's sampled wing at a drift factor, with the pitch-moment input."""
        wing_d = self._wings.get(factor)
        if wing_d is None:
            name = self.plant.drift_parameter
            wing, absorber = self.wing0, self.absorber
            if factor != 1.0 and name == "absorber_stiffness":
                if absorber is None:
                    raise ValueError("plant.drift.parameter absorber_stiffness needs an absorber")
                absorber = dataclasses.replace(absorber, stiffness=absorber.stiffness * factor)
            elif factor != 1.0:
                wing = wing.replace(**{name: getattr(wing, name) * factor})
            wing_d = DiscreteWing(AeroelasticModel(wing, absorber, self.aero), self.sample_rate,
                                  hold=self.hold, inputs=("force", "pitch_moment"),
                                  max_conditions=4096)
            if len(self._wings) > 64:
                self._wings.clear()
            self._wings[factor] = wing_d
        return wing_d

    def _true_damping(self, reported: np.ndarray) -> np.ndarray:
        """c2 acting on the wing: the reported c2 through the actuator's first-order lag."""
        if self.plant.actuator_lag <= 0:
            return reported
        out = np.empty_like(reported)
        c = reported[0] if self._c_true is None else self._c_true
        g = self._lag_decay
        for i, target in enumerate(reported):
            out[i] = c
            c = target + (c - target) * g  # exact for a target held over the sample
        self._c_true = c
        return out

    def _hold(self, raw: tuple) -> tuple:
        if self._held is None:
            return raw
        quanta = (QUANTUM_DRIFT, FLIGHT_QUANTUM, FLIGHT_QUANTUM,
                  QUANTUM_LAGGED if self.plant.actuator_lag > 0 else FLIGHT_QUANTUM)
        return next_held(raw, self._held, quanta)

    def advance(self, force, airspeed, density, damping=None) -> FlightSamples:
        """Simulate ``len(force)`` samples (as
        :class:`~aero_dva.flight.streaming_simulator.StreamingSimulator` does).
        """
        f = np.asarray(force, dtype=float)
        n = f.size
        shape = (n,)
        u = np.broadcast_to(np.asarray(airspeed, dtype=float), shape)
        rho = np.broadcast_to(np.asarray(density, dtype=float), shape)
        if damping is None:
            damping = 0.0 if self.absorber is None else self.absorber.damping
        c = self._true_damping(np.broadcast_to(np.asarray(damping, dtype=float), shape).copy())
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(u)) and np.all(np.isfinite(rho))
                and np.all(np.isfinite(c))):
            raise ValueError("force, airspeed, density and damping must be finite")
        plant = self.plant
        kappa_moment = self.wing0.pitch_stiffness * plant.cubic_stiffness
        out = np.empty((N_OUTPUTS, n))
        h = self.hold
        y = self._y
        j = 0
        while j < n:
            i = self._index + j
            t = i * self.dt
            factor = 1.0
            if plant.drift_rate:
                t_q = math.floor(t / DRIFT_UPDATE) * DRIFT_UPDATE
                factor = round(1.0 + plant.drift_rate * t_q, 9)
            self._held = self._hold((factor, float(u[j]), float(rho[j]), float(c[j])))
            wing_d = self._wing(self._held[0])
            if not self._checked:
                wing_d.check_sampling(*self._held[1:])
                self._checked = True
            condition = wing_d.at(*self._held[1:])
            ns = wing_d.n_states
            if y is None:
                y = np.zeros(ns)
            elif y.size != ns:
                raise ValueError("the plant's state size changed during the flight")
            end = min(j + h - i % h, n)
            if not kappa_moment and end - j == h:
                # linear plant, whole hold period: one matrix-vector product
                r = condition.period @ np.concatenate((y, f[j:end]))
                y = r[:ns]
                out[:, j:end] = r[ns:].reshape(N_OUTPUTS, h)
                j = end
                continue
            step = condition.step
            pitch = wing_d.state_names.index("pitch")
            for k in range(j, end):
                moment = -kappa_moment * y[pitch] ** 3 if kappa_moment else 0.0
                r = step @ np.concatenate((y, (f[k], moment)))
                y = r[:ns]
                out[:, k] = r[ns:]
            j = end
        self._y = y
        self._index += n
        disp = out[:N_DISPLACEMENTS]
        acc = self._sensors(out[N_DISPLACEMENTS:])
        if not self._diverged:
            self._diverged = bool(
                not np.all(np.isfinite(y)) or not np.all(np.isfinite(disp))
                or (n and np.max(np.abs(disp[LEADING_EDGE])) > self.divergence_limit)
                or (kappa_moment and n and np.max(np.abs(disp[PITCH])) > MAX_CUBIC_PITCH))
        return FlightSamples(first_index=self._index - n, sample_rate=self.sample_rate,
                             airspeed=u, density=rho, damping=c, force=f, displacements=disp,
                             accelerations=acc, diverged=self._diverged)

    def _sensors(self, acc: np.ndarray) -> np.ndarray:
        """Accelerometer readings: delay, gain, noise."""
        plant = self.plant
        if self._delay:
            joined = np.concatenate([self._pending, acc], axis=1)
            acc, self._pending = joined[:, :acc.shape[1]], joined[:, acc.shape[1]:]
        acc = acc * np.asarray(plant.sensor_gain)[:, None]
        noise = np.asarray(plant.sensor_noise)
        if np.any(noise > 0):
            acc = acc + noise[:, None] * self._rng.standard_normal(acc.shape)
        return acc
