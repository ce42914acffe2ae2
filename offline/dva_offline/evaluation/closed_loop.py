"""Closed-loop flights in one process: the simulator node's runtime with a controller in the loop.

:class:`~aero_dva.flight.flight_runtime.FlightRuntime` (the simulator node's runtime) flies the
scenario block by block (50 samples); after every block the controller sees what the graph's
controller would receive for that block and may command a c2, which the damper applies from
the next block on: the graph with its command lag bound at one block (``run_flight
--max-command-lag 0.05``), without DDS and processes, so a flight takes a fraction of a second.
The same the study gives the same aileron force whatever the controller (the force is drawn per
block from the scenario's generator), so flights of different controllers are paired.

Controllers (the nodes' command laws, :mod:`aero_dva.control.command_laws`, on the nodes'
inputs):

- :class:`FixedControl` (``fixed_controller``): a constant c2;
- :class:`ScheduleControl` (``airspeed_controller``): its ScheduleLaw (eq. 7.1, clamped to
  the damper, invalid airspeeds rejected) on the block's ``flight/condition`` airspeed;
- :class:`SpectrumRBFControl` (``spectrum`` + ``rbf_controller``): eq. 7.3 spectra of the plunge
  and pitch accelerations over 2 s windows every 0.1 s, the network's c2 from each (input: the
  spectra and the window's mean applied c2) by its RBFLaw, clamped to the damper range;
- :class:`OracleControl`: c2*(U, rho) of the true airspeed and density of the block it commands
  (:class:`OptimalDampingTable`), the upper bound no measurement-based controller can beat.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from aero_dva.control.command_laws import RBFLaw, ScheduleLaw
from aero_dva.control.optimal_damping import optimal_damping
from aero_dva.control.rbf_network import spectrum_input_names
from aero_dva.control.spectrum import SlidingSpectrum
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.flight.damper import DAMPER_RANGE
from aero_dva.flight.flight_runtime import FlightRuntime
from aero_dva.flight.scenario import airspeed_at, density_at
from aero_dva.wing.model import LEADING_EDGE

__all__ = ["FixedControl", "FlightOutcome", "OptimalDampingTable", "OracleControl",
           "ScheduleControl", "SpectrumRBFControl", "fly"]

#: [m/s] the airspeed_controller's default max_airspeed: larger airspeeds are rejected.
MAX_AIRSPEED = 400.0


class FixedControl:
    """A constant c2 [N s/m], commanded every block (``fixed_controller``)."""

    name = "fixed"

    def __init__(self, damping: float):
        if not (math.isfinite(damping) and damping >= 0):
            raise ValueError(f"damping must be a finite c2 >= 0 N s/m, got {damping}")
        self.damping = float(damping)

    def command(self, block, runtime) -> float | None:
        return self.damping


class ScheduleControl:
    """The ``airspeed_controller``'s law (eq. 7.1, the node's default parameters: the line
    extrapolated, one command per condition) on the block's first airspeed (its
    ``flight/condition`` message); a rejected airspeed commands nothing."""

    name = "schedule"

    def __init__(self, schedule, damping_range=DAMPER_RANGE,
                 max_airspeed: float = MAX_AIRSPEED):
        self.law = ScheduleLaw(schedule, tuple(float(v) for v in damping_range),
                               extrapolate=True, max_airspeed=max_airspeed)

    def command(self, block, runtime) -> float | None:
        step = self.law.step(round(block.t0 * 1e9), float(block.airspeed[0]))
        return step.damping if step.kind == "command" else None


class SpectrumRBFControl:
    """The ``spectrum`` and ``rbf_controller`` nodes in one: a c2 from every completed window.

    Parameters
    ----------
    network : RBFNetwork
        33 inputs: plunge and pitch scaled spectra at 5..20 Hz, then c2.
    sample_rate : float
        [Hz]
    damping_range : (float, float)
        [N s/m] commands are clamped to it (the node's damping_min/max).
    window, hop : float
        [s] the spectrum node's window and hop.
    """

    name = "rbf"

    def __init__(self, network, sample_rate: float, damping_range=DAMPER_RANGE,
                 window: float = 2.0, hop: float = 0.1):
        inputs = len(spectrum_input_names()[0])
        if network.input_dim != inputs:
            raise ValueError(f"the network has {network.input_dim} inputs, the spectrum "
                             f"controller gives {inputs}")
        self.network = network
        self.law = RBFLaw(network, tuple(float(v) for v in damping_range))
        self.sliding = SlidingSpectrum(2, sample_rate, window, hop)
        self.peak_activation: list[float] = []

    def command(self, block, runtime) -> float | None:
        result = self.sliding.push(block.first_index, block.accelerations[:2],
                                   damping=block.damping)
        if not result.spectra:
            return None
        window = result.spectra[-1]  # the node answers each; the last one acts
        c2, activation = self.law.command(window.spectrum.magnitudes, window.mean_damping)
        self.peak_activation.append(activation)
        return c2 if math.isfinite(c2) else None  # the node publishes no NaN command


@dataclass(frozen=True)
class OptimalDampingTable:
    """c2*(U, rho) on a grid, interpolated bilinearly (the oracle's knowledge).

    Where no c2 keeps the wing stable (no RMS optimum), the table holds the c2 of the lowest
    growth rate instead, so the oracle still does the best a constant-condition analysis can.

    Attributes
    ----------
    airspeed, density : ndarray
        [m/s], [kg/m^3] grid axes (increasing).
    damping : ndarray, shape (n_u, n_rho)
        [N s/m]
    stable : ndarray of bool, shape (n_u, n_rho)
        An RMS optimum exists there.
    """

    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    stable: np.ndarray

    @classmethod
    def build(cls, model, airspeed, density, *, grid=None, sample_rate: float = 1000.0):
        """Tabulate c2* (the exact stationary leading-edge RMS optimum) on the grid."""
        u = np.asarray(airspeed, dtype=float)
        rho = np.asarray(density, dtype=float)
        c = np.linspace(*DAMPER_RANGE, 126) if grid is None else np.asarray(grid, dtype=float)
        table = np.empty((u.size, rho.size))
        stable = np.empty((u.size, rho.size), dtype=bool)
        for k, r in enumerate(rho):
            res = optimal_damping(model, u, c, float(r), sample_rate=sample_rate)
            stable[:, k] = np.isfinite(res.optimal_damping)
            table[:, k] = res.optimal_damping
            bad = ~stable[:, k]
            if bad.any():
                growth = stationary_rms(model, u[bad, None], float(r), c[None, :]).growth_rate
                table[bad, k] = c[np.argmin(growth, axis=1)]
        return cls(airspeed=u, density=rho, damping=table, stable=stable)

    def __call__(self, airspeed, density) -> np.ndarray:
        interp = RegularGridInterpolator((self.airspeed, self.density), self.damping,
                                         bounds_error=False, fill_value=None)
        u = np.clip(np.asarray(airspeed, float), self.airspeed[0], self.airspeed[-1])
        r = np.clip(np.asarray(density, float), self.density[0], self.density[-1])
        u, r = np.broadcast_arrays(u, r)
        return interp(np.stack([u.ravel(), r.ravel()], axis=-1)).reshape(u.shape)


class OracleControl:
    """c2*(U, rho) at the true airspeed and density of the block the command will act on (the
    middle of the next block), from an :class:`OptimalDampingTable`."""

    name = "oracle"

    def __init__(self, table: OptimalDampingTable):
        self.table = table

    def command(self, block, runtime) -> float | None:
        t = block.t_end + 0.5 * (block.t_end - block.t0)
        scenario = runtime.scenario
        u = airspeed_at(scenario, np.array([t]))
        rho = density_at(scenario, np.array([t]))
        return float(self.table(u, rho)[0])


@dataclass(frozen=True)
class FlightOutcome:
    """One closed-loop flight.

    Attributes
    ----------
    diverged : bool
        The simulator stopped it (|leading edge| above half the chord, or not finite).
    samples : int
        Samples flown.
    sample_rate : float
    airspeed, density, damping, leading_edge : ndarray, shape (samples,)
        [m/s], [kg/m^3], applied c2 [N s/m], leading-edge displacement [m].
    peak_activation : ndarray
        The RBF network's largest hidden activation per spectrum (empty for other
        controllers).
    """

    diverged: bool
    samples: int
    sample_rate: float
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    leading_edge: np.ndarray
    peak_activation: np.ndarray


def fly(config, controller=None, critical_airspeed: float | None = None) -> FlightOutcome:
    """Fly ``config`` (a :class:`~aero_dva.flight.flight_runtime.RuntimeConfig`) with
    ``controller`` (None: nothing commands c2; the damper holds its initial value).
    ``critical_airspeed``: the bare wing's U_cr [m/s] if the caller has it (else solved)."""
    runtime = FlightRuntime(config, critical_airspeed)
    n = runtime.scenario.n_samples
    out = {k: np.empty(n) for k in ("airspeed", "density", "damping", "leading_edge")}
    done = 0
    diverged = False
    source = getattr(controller, "name", "none")
    while not runtime.done:
        block = runtime.step()
        k = block.force.size
        out["airspeed"][done:done + k] = block.airspeed
        out["density"][done:done + k] = block.density
        out["damping"][done:done + k] = block.damping
        out["leading_edge"][done:done + k] = block.displacements[LEADING_EDGE]
        done += k
        if block.diverged:
            diverged = True
            break
        if controller is not None:
            c2 = controller.command(block, runtime)
            if c2 is not None:
                runtime.command(c2, source)
    activation = np.asarray(getattr(controller, "peak_activation", []), dtype=float)
    return FlightOutcome(diverged=diverged, samples=done, sample_rate=runtime.sample_rate,
                         peak_activation=activation,
                         **{k: v[:done] for k, v in out.items()})
