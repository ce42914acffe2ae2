"""Closed-loop flights of many seeds at once: :func:`.closed_loop.fly` for a seed batch.

The flights of one controller in one case differ only in their aileron force, so they are
flown together and the controller's arithmetic runs once for all of them:

- a law whose commands depend on the block's time and flight condition alone (its table entry's
  ``shared_commands``: the fixed controller, the schedule, the oracle), the same for every
  flight: the law in its :class:`.closed_loop.LawControl` and the damper give the c2 of every
  block first (:func:`~aero_dva.flight.seed_batch.damper_schedule`), then every seed's whole
  flight is simulated at once (:func:`~aero_dva.flight.seed_batch.fly_held_commands`) and cut
  after the block in which it diverged;
- the RBF network (:class:`~aero_dva.control.command_laws.RBFLaw` on spectra): the flights step
  block by block together (:class:`~aero_dva.flight.seed_batch.SeedBatchRuntime`, each its own
  c2) and :class:`BatchSpectrumRBF`, the ``spectrum`` + ``rbf_controller`` arithmetic (eq. 7.3
  windows of 2 s every 0.1 s, the network's clamped c2 from each completed window, the last one
  acting) on every flight's window at once.

:func:`fly_batch` returns one :class:`~.closed_loop.FlightOutcome` per seed, equal to what
:func:`.closed_loop.fly` gives for that seed up to rounding (products over several flights may
sum in another order). Other laws and flights the batch cannot fly
(:func:`~aero_dva.flight.seed_batch.batch_problem`) fly one at a time.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from aero_dva.control.command_laws import RBFLaw
from aero_dva.flight.scenario import resolve_airspeeds
from aero_dva.flight.seed_batch import (
    SeedBatchRuntime,
    batch_problem,
    damper_schedule,
    fly_held_commands,
)
from aero_dva.wing.flutter import bare_critical_airspeed
from aero_dva.wing.model import LEADING_EDGE
from dva_offline.evaluation.closed_loop import FlightOutcome, LawControl, fly

__all__ = ["BatchSpectrumRBF", "batchable", "fly_batch"]


def _spectrum_rbf(controller) -> bool:
    return controller.sliding is not None and isinstance(controller.law, RBFLaw)


def batchable(controller) -> bool:
    """``controller`` (a :class:`.closed_loop.LawControl`) can fly a seed batch."""
    return isinstance(controller, LawControl) and (controller.entry.shared_commands
                                                   or _spectrum_rbf(controller))


class BatchSpectrumRBF:
    """The RBF network's :class:`~.closed_loop.LawControl` for the flights of a batch.

    Each flight's accelerations (plunge, pitch) and applied c2 are kept whole; every completed
    window (all flights' at once) gives eq. 7.3 spectra, the network's input (spectra, mean
    c2 over the window), its largest hidden activation and its c2, clamped to the damper range
    (NaN: no command, as the node publishes none).

    The windows (2 s) overlap by all but a hop (0.1 s), so each hop of samples is transformed
    once: with the rectangular window, the DFT of a window is the sum of its hops' DFTs, the
    k-th turned by ``exp(-2 pi j f k hop / fs)``. The same spectra up to rounding.
    """

    def __init__(self, control: LawControl, flights: int, samples: int):
        sliding = control.sliding
        if sliding.window_function != "rectangular" or \
                sliding.window_length % sliding.hop_length or control._rows != [0, 1]:
            raise ValueError("the batch spectrum needs the plunge and pitch in a rectangular "
                             "window of whole hops")
        self.network = control.law.network
        self.low, self.high = control.law.damping_range
        self.window = sliding.window_length
        self.hop = sliding.hop_length
        # The node's rectangular-window DFT kernel (eq. 7.3 scaling 2 / n), one hop's rows.
        kernel = np.exp(-2j * np.pi * np.outer(np.arange(self.hop), sliding.frequencies)
                        / sliding.sample_rate) * (2.0 / self.window)
        self.kernel = np.concatenate([kernel.real, kernel.imag], axis=1)
        self.bins = kernel.shape[1]
        hops = np.arange(self.window // self.hop)[:, None]
        self.turn = np.exp(-2j * np.pi * sliding.frequencies * hops * self.hop
                           / sliding.sample_rate)  # (hops per window, n_freq)
        self.acc = np.empty((flights, 2, samples))
        self.damping = np.empty((flights, samples))
        self.hop_dft = np.empty((flights, 2, samples // self.hop, self.bins), dtype=complex)
        self.hops_done = 0
        self.next_start = 0
        self.peak_activation: list[list[float]] = [[] for _ in range(flights)]

    def command(self, block) -> np.ndarray | None:
        """c2 per flight of ``block`` (a seed batch's samples without its diverged flights),
        or None when no window completed."""
        a, n = block.first_index, block.force.shape[1]
        flights = block.flights
        self.acc[flights, :, a:a + n] = block.accelerations[:, :2]
        self.damping[flights, a:a + n] = block.damping
        stop, start = a + n, None
        complete = stop // self.hop
        if complete > self.hops_done:  # transform the hops this block completed
            h0, h = self.hops_done, self.hop
            x = self.acc[flights, :, h0 * h:complete * h].reshape(len(flights), 2, -1, h)
            parts = x @ self.kernel
            self.hop_dft[flights, :, h0:complete] = \
                parts[..., :self.bins] + 1j * parts[..., self.bins:]
            self.hops_done = complete
        while self.next_start + self.window <= stop:
            start = self.next_start  # of the windows this block completes, the last acts
            self.next_start += self.hop
        if start is None:
            return None
        return self._answer(flights, start)

    def _answer(self, flights, start: int) -> np.ndarray:
        first = start // self.hop
        spectra = self.hop_dft[flights, :, first:first + len(self.turn)]
        amplitudes = np.abs(np.einsum("fckb,kb->fcb", spectra, self.turn))  # (F, 2, n_freq)
        band = amplitudes.sum(axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            magnitudes = np.where(band[..., None] > 0.0, amplitudes / band[..., None], np.nan)
        mean_c2 = np.mean(self.damping[flights, start:start + self.window], axis=1)
        inputs = np.concatenate([magnitudes.reshape(len(flights), -1), mean_c2[:, None]],
                                axis=1)
        net = self.network
        hidden = net.hidden(inputs)  # once for the activation and the output (as predict)
        activation = hidden.max(axis=1) if net.n_neurons else np.ones(len(flights))
        for f, value in zip(flights.tolist(), activation.tolist()):
            self.peak_activation[f].append(value)
        c2 = hidden @ net.output_weights + net.output_bias
        return np.where(np.isfinite(c2), np.clip(c2, self.low, self.high), np.nan)


def fly_batch(config, make_controller: Callable[[], object], seeds: Sequence[int],
              critical_airspeed: float | None = None) -> list[FlightOutcome]:
    """Fly ``config`` (a RuntimeConfig; its seed replaced by each of ``seeds``) with the
    controller ``make_controller()`` gives, every seed in one batch where the controller and
    the scenario allow it, else one :func:`.closed_loop.fly` per seed. One outcome per seed."""
    controller = make_controller()
    if not batchable(controller) or batch_problem(config) is not None:
        return [fly(replace(config, scenario=replace(config.scenario, seed=int(s))),
                    controller if i == 0 else make_controller(), critical_airspeed)
                for i, s in enumerate(seeds)]
    if critical_airspeed is None:
        critical_airspeed = bare_critical_airspeed(config.wing, config.scenario.density,
                                                   config.aero)
    if controller.entry.shared_commands:
        return _fly_shared(config, controller, seeds, critical_airspeed)
    runtime = SeedBatchRuntime(config, seeds, critical_airspeed)
    f, total = len(seeds), runtime.scenario.n_samples
    trace_u, trace_rho = np.empty(total), np.empty(total)
    damping, leading_edge = np.empty((f, total)), np.empty((f, total))
    samples = np.zeros(f, dtype=int)
    diverged = np.zeros(f, dtype=bool)
    spectra = BatchSpectrumRBF(controller, f, total)
    while not runtime.done:
        block = runtime.step()
        a, n = block.first_index, block.force.shape[1]
        trace_u[a:a + n], trace_rho[a:a + n] = block.airspeed, block.density
        damping[block.flights, a:a + n] = block.damping
        leading_edge[block.flights, a:a + n] = block.displacements[:, LEADING_EDGE]
        samples[block.flights] = a + n
        diverged[block.flights[block.diverged]] = True
        if runtime.active.size == 0:
            break
        c2 = spectra.command(_without_diverged(block))
        if c2 is not None:
            runtime.command(c2, controller.entry.source)
    outcomes = []
    for i in range(f):
        k = int(samples[i])
        outcomes.append(FlightOutcome(
            diverged=bool(diverged[i]), samples=k, sample_rate=runtime.sample_rate,
            airspeed=trace_u[:k].copy(), density=trace_rho[:k].copy(),
            damping=damping[i, :k].copy(), leading_edge=leading_edge[i, :k].copy(),
            peak_activation=np.asarray(spectra.peak_activation[i], dtype=float)))
    return outcomes


def _fly_shared(config, controller, seeds, critical_airspeed) -> list[FlightOutcome]:
    """A controller that commands from time and flight condition alone: its c2 of every
    sample first (the damper and the controller over the blocks, no flight needed), then
    every seed's whole flight with that c2 at once."""
    view = SimpleNamespace(scenario=resolve_airspeeds(config.scenario, critical_airspeed))
    damping = damper_schedule(config, critical_airspeed,
                              lambda block: controller.command(block, view),
                              controller.entry.source)
    flights = fly_held_commands(config, seeds, damping, critical_airspeed)
    rate = config.scenario.sample_rate
    return [FlightOutcome(diverged=bool(flights.diverged[i]), samples=int(k), sample_rate=rate,
                          airspeed=flights.airspeed[:k].copy(),
                          density=flights.density[:k].copy(), damping=damping[:k].copy(),
                          leading_edge=flights.displacements[i, LEADING_EDGE, :k].copy(),
                          peak_activation=np.empty(0))
            for i, k in enumerate(flights.samples.tolist())]


def _without_diverged(block):
    keep = ~block.diverged
    if keep.all():
        return block
    return replace(block, flights=block.flights[keep], damping=block.damping[keep],
                   force=block.force[keep], displacements=block.displacements[keep],
                   accelerations=block.accelerations[keep], diverged=block.diverged[keep])
