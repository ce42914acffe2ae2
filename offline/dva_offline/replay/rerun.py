"""Open-loop re-runs of a recorded flight's controller without ROS, and their comparison.

The inputs a controller saw in a recorded flight (acceleration blocks and damper states for the
spectrum node and a law of spectra, flight conditions for a law of them) are fed, in the bag's
order, through the very code the nodes run (:class:`~aero_dva.control.spectrum_stream.
SpectrumStream`, the law of the controller's table entry, :mod:`aero_dva.control.controllers`).
With the network or schedule that flew, the spectra and commands equal the recorded ones; with
another, they are that controller's commands on the same data. ``dva replay`` runs this
(``--offline``) or the same through the node graph, and compares either with the recording
(:func:`compare`).

The re-run is open loop: the wing does not respond to the new commands (the recorded
accelerations and applied c2 are replayed as they were).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from aero_dva.control.controllers import (
    CONDITION,
    SPECTRUM,
    Condition,
    Controller,
    SpectrumInput,
)
from aero_dva.control.spectrum_stream import SpectrumStream
from aero_dva.wing.model import ACCELERATION_NAMES

__all__ = ["Comparison", "CommandRecord", "SpectrumRecord", "compare", "law_commands",
           "spectra_from_inputs"]

#: Channels of an acceleration block, in the order read from a bag (dva_msgs/AccelerationBlock).
ACCELERATION_CHANNELS = ACCELERATION_NAMES


@dataclass(frozen=True)
class SpectrumRecord:
    """One ``dva/spectrum`` message's numbers: stamp [ns], magnitudes (channels, n_freq),
    band sums, the c2 of the window [N s/m]."""

    stamp_ns: int
    magnitudes: np.ndarray
    band_sums: np.ndarray
    damping: float


@dataclass(frozen=True)
class CommandRecord:
    """One ``dva/damper_command``: stamp [ns] (its input's time), c2 [N s/m], source."""

    stamp_ns: int
    damping: float
    source: str


@dataclass(frozen=True)
class BlockInput:
    """An acceleration block as recorded: stamp [ns], index, rate [Hz], samples (3, n)."""

    stamp_ns: int
    first_index: int
    sample_rate: float
    samples: np.ndarray


@dataclass(frozen=True)
class StateInput:
    """A damper state as recorded: stamp [ns], applied c2 [N s/m]."""

    stamp_ns: int
    applied: float


def spectra_from_inputs(inputs: Iterable[BlockInput | StateInput], channels: Sequence[str],
                        window_duration: float, hop: float, frequencies,
                        window: str) -> list[SpectrumRecord]:
    """The spectrum node's output for blocks and damper states in their recorded order (a
    recording with damper states: as the node told that states are required, which the replay
    through the graph does)."""
    rows = [ACCELERATION_CHANNELS.index(c) for c in channels]
    inputs = list(inputs)
    stream = SpectrumStream(channels, window_duration, hop, frequencies, window,
                            states_required=any(isinstance(i, StateInput) for i in inputs))
    spectra = []
    for item in inputs:
        if isinstance(item, StateInput):
            stream.damper_state(item.stamp_ns, item.applied)
            spectra += stream.release()[0]
        else:
            spectra += stream.block(item.stamp_ns, item.first_index, item.sample_rate,
                                    item.samples[rows])[0]
    spectra += stream.release(force=True)[0]  # blocks after the last state
    return [SpectrumRecord(s.stamp_ns, s.spectrum.magnitudes, s.spectrum.band_sums, s.damping)
            for s in spectra]


def law_commands(entry: Controller, law, conditions, spectra: Iterable[SpectrumRecord],
                 shape: tuple) -> list[CommandRecord]:
    """The commands of ``entry``'s ``law`` on a recording, input by input as its node would
    give them: for each spectrum (a law of spectra; ``shape`` = channels, frequencies,
    window duration, window function of the spectra), for each flight condition (stamp [ns],
    airspeed [m/s], density [kg/m^3]) (a law of them), and a law on its own timer at each
    flight condition's stamp (one per block, the recording's clock). An input the law rejects
    gives none, as in the node."""
    kind = entry.inputs[0]
    if kind == SPECTRUM:
        channels, frequencies, duration, window = shape
        items = [(s.stamp_ns, SpectrumInput(s.stamp_ns, tuple(channels),
                                            np.asarray(frequencies, dtype=float), s.magnitudes,
                                            float(duration), window, "band_sum", s.damping))
                 for s in spectra]
    elif kind == CONDITION:
        items = [(stamp, Condition(u, rho)) for stamp, u, rho in conditions]
    else:
        items = [(stamp, None) for stamp, *_ in conditions]
    out = []
    for stamp_ns, value in items:
        step = law.answer(kind, stamp_ns, value)
        if step.kind == "command":
            out.append(CommandRecord(stamp_ns, step.damping, entry.source))
    return out


@dataclass(frozen=True)
class Comparison:
    """Two series of stamped values side by side (matched by stamp).

    Attributes
    ----------
    reference, other : int
        Messages in each series.
    matched : int
        Stamps in both.
    max_abs_difference : float
        Largest |difference| of the compared values over the matched stamps (0 if none).
    rms_difference : float
        RMS of those differences.
    identical : bool
        Same stamps, and every value equal bit for bit.
    held : dict or None
        Commands only: each command of ``other`` against the reference c2 in force at its
        stamp (the latest reference command at or before it), for controllers whose commands
        come at other times: ``compared`` (commands with a reference before them),
        ``mean_difference`` (other - reference), ``max_abs_difference``, ``rms_difference``
        [N s/m].
    """

    reference: int
    other: int
    matched: int
    max_abs_difference: float
    rms_difference: float
    identical: bool
    held: dict | None = None

    def to_dict(self) -> dict:
        return dict(reference=self.reference, other=self.other, matched=self.matched,
                    max_abs_difference=self.max_abs_difference,
                    rms_difference=self.rms_difference, identical=self.identical,
                    held=self.held)


def _values(record) -> np.ndarray:
    if isinstance(record, SpectrumRecord):
        return np.concatenate([np.ravel(record.magnitudes), np.ravel(record.band_sums),
                               [record.damping]])
    return np.array([record.damping])


def compare(reference: Sequence, other: Sequence) -> Comparison:
    """Compare two series of :class:`SpectrumRecord` or :class:`CommandRecord` by stamp
    (spectra: magnitudes, band sums and c2; commands: c2). A stamp repeated in a series is
    matched in order."""
    def keyed(series):
        seen: dict[int, int] = {}
        out = {}
        for record in series:
            n = seen.get(record.stamp_ns, 0)
            seen[record.stamp_ns] = n + 1
            out[(record.stamp_ns, n)] = _values(record)
        return out

    ref, oth = keyed(reference), keyed(other)
    common = [k for k in ref if k in oth]
    diffs = []
    for k in common:
        a, b = ref[k], oth[k]
        d = np.abs(a - b) if a.shape == b.shape else np.array([np.inf])
        if a.shape == b.shape:
            d = np.where(np.isnan(a) & np.isnan(b), 0.0, np.where(np.isnan(d), np.inf, d))
        diffs.append(d)
    flat = np.concatenate(diffs) if diffs else np.zeros(0)
    identical = len(common) == len(ref) == len(oth) and all(
        ref[k].shape == oth[k].shape and np.array_equal(ref[k], oth[k], equal_nan=True)
        for k in common)
    finite = flat[np.isfinite(flat)]
    max_diff = float(flat.max()) if flat.size else 0.0
    rms = float(np.sqrt(np.mean(finite ** 2))) if finite.size else 0.0
    held = None
    if all(isinstance(r, CommandRecord) for r in (*reference, *other)):
        held = _held_difference(reference, other)
    return Comparison(len(ref), len(oth), len(common), max_diff, rms, identical, held)


def _held_difference(reference: Sequence[CommandRecord],
                     other: Sequence[CommandRecord]) -> dict:
    """``other``'s commands against the reference c2 in force at their stamps."""
    ref = sorted(reference, key=lambda r: r.stamp_ns)
    stamps = np.array([r.stamp_ns for r in ref], dtype=np.int64)
    values = np.array([r.damping for r in ref])
    at = np.array([r.stamp_ns for r in other], dtype=np.int64)
    index = np.searchsorted(stamps, at, side="right") - 1
    keep = index >= 0
    diff = np.array([r.damping for r in other])[keep] - values[index[keep]]
    diff = diff[np.isfinite(diff)]
    if diff.size == 0:
        return {"compared": 0, "mean_difference": None, "max_abs_difference": None,
                "rms_difference": None}
    return {"compared": int(diff.size), "mean_difference": float(diff.mean()),
            "max_abs_difference": float(np.abs(diff).max()),
            "rms_difference": float(np.sqrt(np.mean(diff ** 2)))}
