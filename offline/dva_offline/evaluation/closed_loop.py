"""Closed-loop flights in one process: the simulator node's runtime with a controller in the loop.

:class:`~aero_dva.flight.flight_runtime.FlightRuntime` (the simulator node's runtime) flies the
scenario block by block (50 samples); after every block the controller sees what the graph's
controller would receive for that block and may command a c2, which the damper applies from
the next block on: the graph with its command lag bound at one block (``run_flight
--max-command-lag 0.05``), without DDS and processes, so a flight takes a fraction of a second.
The same the study gives the same aileron force whatever the controller (the force is drawn per
block from the scenario's generator), so flights of different controllers are paired.

Controllers: the laws of the controller table (:mod:`aero_dva.control.controllers`), each in a
:class:`LawControl`, which hands the law after every block what its node would have received for
that block:

- a law on its node's timer (the ``fixed_controller``): one tick;
- a law of flight conditions (the ``airspeed_controller``'s schedule): the block's
  ``flight/condition`` (its first airspeed and density);
- a law of spectra (``spectrum`` + ``rbf_controller``): eq. 7.3 spectra of the plunge and pitch
  accelerations over 2 s windows every 0.1 s (the spectrum node's defaults), each with the
  window's mean applied c2; the last command acts;
- a reference that reads the truth (the oracle, :mod:`aero_dva.control.oracle`): the true
  airspeed and density of the block it commands (the middle of the next block);
- a per-sample law (the switching law, the clipped-optimal law): :class:`PerSampleControl`,
  its supervisor's command after every block, which arms the law in the runtime's damper path
  (the simulator's, sample by sample, with the law's damper lag and sensor noise).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from aero_dva.control import controllers as table
from aero_dva.control.controllers import (
    CONDITION,
    SPECTRUM,
    TICK,
    TRUTH,
    Condition,
    Controller,
    SpectrumInput,
)
from aero_dva.control.spectrum import SlidingSpectrum
from aero_dva.flight.flight_runtime import FlightRuntime
from aero_dva.flight.scenario import airspeed_at, density_at
from aero_dva.wing.model import ACCELERATION_NAMES, LEADING_EDGE

__all__ = ["FlightOutcome", "LawControl", "PerSampleControl", "fly", "law_control"]

SPECTRUM_HOP = 0.1  # [s] the spectrum node's default hop


def _shape_default(name: str):
    return next(p.default for p in table.SPECTRUM_SHAPE if p.name == name)


class LawControl:
    """A law of the controller table in the loop (module docstring): ``command(block,
    runtime)`` after each block, the c2 that acts from the next block on (None: none).

    Parameters
    ----------
    entry : Controller
        The law's entry (what it reads).
    law
        The law (``entry.make_law(values)``); its state is this flight's.
    sample_rate : float
        [Hz]
    """

    def __init__(self, entry: Controller, law, sample_rate: float):
        self.entry, self.law, self.name = entry, law, entry.name
        self.peak_activation: list[float] = []  # the largest hidden activation per command
        self.sliding = None
        if SPECTRUM in entry.inputs:
            channels = tuple(getattr(law, "channels", _shape_default("channels")))
            self._rows = [ACCELERATION_NAMES.index(c) for c in channels]
            self._channels = channels
            self.sliding = SlidingSpectrum(
                len(channels), sample_rate,
                float(getattr(law, "window_duration", _shape_default("window_duration"))),
                SPECTRUM_HOP,
                getattr(law, "frequencies", np.asarray(_shape_default("frequencies"))),
                getattr(law, "window", _shape_default("window")))

    def command(self, block, runtime) -> float | None:
        c2 = None
        for kind in self.entry.inputs:
            for stamp_ns, value in self._inputs(kind, block, runtime):
                step = self.law.answer(kind, stamp_ns, value)
                if step.kind == "command":
                    c2 = step.damping
                    if "activation" in step.values:
                        self.peak_activation.append(float(step.values["activation"]))
        return c2

    def _inputs(self, kind: str, block, runtime):
        if kind == TICK:
            return [(round(block.t_end * 1e9), None)]
        if kind == CONDITION:
            return [(round(block.t0 * 1e9),
                     Condition(float(block.airspeed[0]), float(block.density[0])))]
        if kind == TRUTH:
            t = np.array([block.t_end + 0.5 * (block.t_end - block.t0)])
            scenario = runtime.scenario
            return [(round(t[0] * 1e9), Condition(float(airspeed_at(scenario, t)[0]),
                                                  float(density_at(scenario, t)[0])))]
        if kind == SPECTRUM:
            result = self.sliding.push(block.first_index, block.accelerations[self._rows],
                                       damping=block.damping)
            rate = self.sliding.sample_rate
            out = []
            for w in result.spectra:
                stamp = round((w.stop_sample_index - 1) / rate * 1e9)  # its last sample
                out.append((stamp, SpectrumInput(
                    stamp, self._channels, w.spectrum.frequencies, w.spectrum.magnitudes,
                    w.spectrum.window_duration, w.spectrum.window_function, "band_sum",
                    w.mean_damping)))
            return out
        return []  # what a node of this law reads but the loop does not give


def law_control(name: str, values=None, sample_rate: float = 1000.0) -> LawControl:
    """The law ``name`` of the table, made from ``values`` (over its defaults), in a
    :class:`LawControl`."""
    entry = table.controller(name)
    return LawControl(entry, entry.make_law(values), sample_rate)


class PerSampleControl:
    """A per-sample law of the controller table in the loop: after every block its supervisor's
    command, which arms the law in the damper path for the next block, with the safe constant
    c2 the damper holds if the law cannot run. The supervisor's burst detector is not flown: it
    would disarm the law at its first burst (the practical boundary) and leave the wing on the
    safe c2 beyond that c2's own flutter, so the law's bounded boundary could not be measured.

    :meth:`configure` gives a flight the law's gains for the commands of its source, and its
    damper lag and sensor noise as designed (the table entry's).

    Parameters
    ----------
    entry : Controller
    gains : SwitchingGains
        The law (``entry.make_law(values)``).
    safe_damping : float
        [N s/m] the constant c2 of its commands.
    """

    def __init__(self, entry: Controller, gains, safe_damping: float):
        self.entry, self.gains, self.name = entry, gains, entry.name
        self.safe_damping = float(safe_damping)
        self.peak_activation: list[float] = []

    def configure(self, config):
        """``config`` (a RuntimeConfig) flown with this law in the damper path."""
        entry = self.entry
        return replace(config, per_sample={**config.per_sample, entry.source: self.gains},
                       damper=replace(config.damper, time_constant=float(entry.damper_lag)),
                       sensor_noise=entry.sensor_noise)

    def command(self, block, runtime) -> float | None:
        return self.safe_damping


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
    target : ndarray, shape (samples,)
        [N s/m] the c2 the damper was asked for at each sample: a block law's command in
        force, a per-sample law's choice of its two levels (its lag then follows).
    damper_power : ndarray, shape (samples,)
        [W] the power the damper dissipated over each sample, F^2 / c2 from the damper force
        F = k2 delta the flight reports (a per-sample law's); NaN where it reports none.
    """

    diverged: bool
    samples: int
    sample_rate: float
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    leading_edge: np.ndarray
    peak_activation: np.ndarray
    target: np.ndarray | None = None
    damper_power: np.ndarray | None = None


def fly(config, controller=None, critical_airspeed: float | None = None) -> FlightOutcome:
    """Fly ``config`` (a :class:`~aero_dva.flight.flight_runtime.RuntimeConfig`) with
    ``controller`` (None: nothing commands c2; the damper holds its initial value).
    ``critical_airspeed``: the bare wing's U_cr [m/s] if the caller has it (else solved)."""
    if hasattr(controller, "configure"):
        config = controller.configure(config)
    runtime = FlightRuntime(config, critical_airspeed)
    n = runtime.scenario.n_samples
    keys = ("airspeed", "density", "damping", "leading_edge", "target", "damper_power")
    out = {k: np.empty(n) for k in keys}
    done = 0
    diverged = False
    source = table.NONE if controller is None else controller.entry.source
    law = getattr(controller, "gains", None)
    while not runtime.done:
        block = runtime.step()
        k = block.force.size
        out["airspeed"][done:done + k] = block.airspeed
        out["density"][done:done + k] = block.density
        out["damping"][done:done + k] = block.damping
        out["leading_edge"][done:done + k] = block.displacements[LEADING_EDGE]
        target = getattr(block, "target", None)
        out["target"][done:done + k] = block.damping if target is None or law is None else \
            np.where(target, law.law.c_hi, law.law.c_lo)
        force = getattr(block, "damper_force", None)
        out["damper_power"][done:done + k] = math.nan if force is None else \
            force ** 2 / block.damping
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
