"""Training the spectrum-based RBF controller from a recorded sweep (seed sec. 7.2.1, fig. 7.11).

The seed's experiment: at each airspeed of 0.8 .. 1.14 U_cr (step 0.002 U_cr) 20 values of the
damper c2 are applied in turn; each (U, c2) pair gives a 2 s window at 1 kHz of both responses
(translational and rotational), whose eq. 7.3 scaled spectra at 5..20 Hz plus the current c2 are
the network's 33 inputs. The output (label) of every window of an airspeed is the c2 that gave
the lowest *measured* RMS at that airspeed: model-free, read from the log alone.

Steps (all pure numerics on arrays of a :class:`~aero_dva.bag.flight_log_io.FlightLog`):

1. :func:`find_dwells` cuts the log where the recorded applied c2 or the airspeed changes;
2. :func:`build_dataset` takes the last ``window`` seconds of each dwell (the wing carries its
   state from one dwell into the next, so the start of a dwell is a transient) and computes the
   scaled spectra of the plunge and pitch accelerations (what the ``spectrum`` node publishes
   to the ``rbf_controller``) and the leading-edge displacement RMS (the seed's objective);
3. :func:`label_min_rms` labels each airspeed with the c2 of its lowest measured RMS;
4. :func:`split_by_airspeed` holds out whole airspeeds (every k-th), so validation windows
   never share an airspeed, hence a label and a flight state, with training windows;
5. :func:`train_network` trains by orthogonal least squares for each candidate spread and keeps
   the spread with the lowest RMS error on the held-out airspeeds.

:func:`adapt_sweep` makes a sweep scenario safe to fly continuously: an unstable (U, c2) pair
grows and ruins every later dwell, so only airspeeds at which every c2 of the list decays at
least at a given rate are kept, and each dwell gets a settling time before its window.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from aero_dva.control.rbf_network import (
    SPECTRUM_INPUT_DIM,
    OLSTrainingResult,
    fit_input_scaling,
    select_spread,
    spectrum_input_names,
    spectrum_input_vector,
)
from aero_dva.control.spectrum import DEFAULT_FREQUENCIES, scaled_spectrum
from aero_dva.flight.scenario import AirspeedProfile, Scenario, sweep_duration
from aero_dva.wing.model import ACCELERATION_NAMES

__all__ = [
    "ACCELERATION_CHANNELS",
    "CHANNELS",
    "DEFAULT_SPREADS",
    "Dwells",
    "OptimalC2",
    "SweepAdaptation",
    "TrainingData",
    "TrainingDataError",
    "TrainingOutcome",
    "adapt_sweep",
    "build_dataset",
    "find_dwells",
    "label_min_rms",
    "split_by_airspeed",
    "train_network",
]

#: Acceleration channels of a FlightLog, in its row order (the wing model's outputs).
ACCELERATION_CHANNELS = ACCELERATION_NAMES
#: Spectrum channels of the seed's network (translational, rotational), as the spectrum node.
CHANNELS = ("plunge", "pitch")
LEADING_EDGE = 2  # row of the leading-edge displacement in FlightLog.displacements
#: Candidate spreads in min-max scaled input space (33 inputs: distances of order 0.1 .. 1).
DEFAULT_SPREADS = (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0)


class TrainingDataError(ValueError):
    """A log cannot give a training set (too few windows, gaps, ...); the message says why."""


# -- the sweep --------------------------------------------------------------------------------

@dataclass(frozen=True)
class SweepAdaptation:
    """What :func:`adapt_sweep` changed.

    Attributes
    ----------
    scenario : Scenario
        The sweep to fly (airspeeds still relative to U_cr if they were).
    ratios : ndarray, shape (n_kept,)
        Kept airspeeds [U/U_cr].
    dropped_ratios : ndarray
        Airspeeds [U/U_cr] left out because some c2 of the list decays too slowly or grows.
    max_growth : ndarray, shape (n_airspeeds,)
        [1/s] largest growth rate over the c2 list at each airspeed of the original sweep.
    min_decay : float
        [1/s] the decay rate every kept (U, c2) pair has at least.
    settle, window : float
        [s] settling time and analysis window of each dwell (dwell = settle + window).
    """

    scenario: Scenario
    ratios: np.ndarray
    dropped_ratios: np.ndarray
    max_growth: np.ndarray
    min_decay: float
    settle: float
    window: float


def adapt_sweep(scenario: Scenario, critical_airspeed: float,
                growth_rate: Callable[[np.ndarray, float], np.ndarray], *, damping=None,
                min_decay: float = 0.5, settle: float = 2.0, window: float = 2.0
                ) -> SweepAdaptation:
    """Keep the sweep's airspeeds at which every c2 decays at ``min_decay`` or faster.

    Parameters
    ----------
    scenario : Scenario
        A ``steps`` sweep; airspeeds in m/s or relative to ``critical_airspeed``.
    critical_airspeed : float
        [m/s] U_cr of the wing without DVA.
    growth_rate : callable
        ``growth_rate(airspeeds_m_s, c2) -> ndarray`` [1/s], the largest real part of the
        wing's eigenvalues at each airspeed for one c2 (e.g.
        :func:`aero_dva.wing.flutter.growth_rate` of the model).
    damping : sequence of float, optional
        [N s/m] c2 values to apply at each airspeed; default the scenario's.
    min_decay : float
        [1/s] required decay rate (> 0): the transient from the previous dwell falls by
        ``exp(-min_decay * settle)`` before the window starts.
    settle, window : float
        [s] settling time (>= 0) and window (> 0); the dwell becomes ``settle + window``.

    Returns
    -------
    SweepAdaptation
        The kept airspeeds are the leading run of the sweep's airspeeds that qualify (the sweep
        flies upwards and stops at the first airspeed that does not).
    """
    if scenario.airspeed.kind != "steps":
        raise ValueError(f"scenario must be a 'steps' sweep, got {scenario.airspeed.kind!r}")
    if not (np.isfinite(critical_airspeed) and critical_airspeed > 0):
        raise ValueError(f"critical_airspeed must be > 0 m/s, got {critical_airspeed}")
    if not min_decay > 0:
        raise ValueError(f"min_decay must be > 0 1/s, got {min_decay}")
    if not settle >= 0:
        raise ValueError(f"settle must be >= 0 s, got {settle}")
    if not window > 0:
        raise ValueError(f"window must be > 0 s, got {window}")
    c2 = tuple(float(c) for c in (scenario.sweep_damping if damping is None else damping))
    if not c2 or not all(np.isfinite(c) and c >= 0 for c in c2):
        raise ValueError(f"damping must be a non-empty list of c2 >= 0 N s/m, got {c2}")
    values = np.asarray(scenario.airspeed.values, dtype=float)
    ratios = values if scenario.airspeed.relative else values / critical_airspeed
    speeds = ratios * critical_airspeed
    growth = np.max([np.asarray(growth_rate(speeds, c), dtype=float).reshape(speeds.shape)
                     for c in c2], axis=0)
    bad = np.flatnonzero(growth > -min_decay)
    n_keep = int(bad[0]) if bad.size else ratios.size
    if n_keep == 0:
        raise ValueError(
            f"no airspeed of the sweep decays at {min_decay} 1/s for every c2 in {c2} "
            f"(largest growth at the first airspeed: {growth[0]:.3g} 1/s)")
    kept = values[:n_keep]
    dwell = settle + window
    adapted = replace(
        scenario,
        airspeed=AirspeedProfile("steps", tuple(float(v) for v in kept),
                                 scenario.airspeed.relative),
        sweep_damping=c2, dwell=dwell, duration=sweep_duration(n_keep, len(c2), dwell))
    return SweepAdaptation(scenario=adapted, ratios=ratios[:n_keep],
                           dropped_ratios=ratios[n_keep:], max_growth=growth,
                           min_decay=float(min_decay), settle=float(settle),
                           window=float(window))


# -- dwells and windows -------------------------------------------------------------------------

@dataclass(frozen=True)
class Dwells:
    """Runs of samples with constant recorded airspeed and applied c2.

    Attributes
    ----------
    start, stop : ndarray of int, shape (n,)
        Sample index range ``[start, stop)`` of each dwell.
    airspeed : ndarray, shape (n,) [m/s]
    damping : ndarray, shape (n,) [N s/m] applied c2
    """

    start: np.ndarray
    stop: np.ndarray
    airspeed: np.ndarray
    damping: np.ndarray


def find_dwells(airspeed, applied_damping) -> Dwells:
    """Cut a sweep where the recorded airspeed or applied c2 changes.

    Parameters
    ----------
    airspeed, applied_damping : array_like, shape (n,)
        Per-sample airspeed [m/s] and applied c2 [N s/m] (FlightLog fields).

    Raises
    ------
    TrainingDataError
        No damper state recorded (all c2 NaN) or no samples.
    """
    u = np.asarray(airspeed, dtype=float)
    c = np.asarray(applied_damping, dtype=float)
    if u.ndim != 1 or c.shape != u.shape:
        raise ValueError(f"airspeed and applied_damping must be 1-D of equal length, got "
                         f"{u.shape} and {c.shape}")
    if u.size == 0:
        raise TrainingDataError("the log holds no samples")
    if np.all(np.isnan(c)):
        raise TrainingDataError("the log has no applied c2 (topic /dva/damper_state missing or "
                                "empty): dwells cannot be found")
    # NaN != NaN would cut at every sample; compare with NaN mapped to a sentinel.
    uk = np.where(np.isnan(u), -1.0, u)
    ck = np.where(np.isnan(c), -1.0, c)
    cuts = np.flatnonzero((np.diff(uk) != 0) | (np.diff(ck) != 0)) + 1
    start = np.concatenate([[0], cuts]).astype(int)
    stop = np.concatenate([cuts, [u.size]]).astype(int)
    return Dwells(start=start, stop=stop, airspeed=u[start], damping=c[start])


@dataclass(frozen=True)
class TrainingData:
    """One window per usable dwell.

    Attributes
    ----------
    inputs : ndarray, shape (n, 33)
        Scaled spectra of the plunge and pitch accelerations (channel-major, 5..20 Hz), then c2.
    airspeed : ndarray, shape (n,) [m/s]
    damping : ndarray, shape (n,) [N s/m] c2 applied during the window
    rms : ndarray, shape (n,) [m] measured leading-edge displacement RMS over the window
    window_start : ndarray of int, shape (n,)
        Sample index of each window's first sample.
    window : float
        [s] window length.
    skipped : dict
        Dwells not used, by reason ("short", "gap", "no_airspeed").
    input_names, input_units : tuple of str
        As :func:`aero_dva.control.rbf_network.spectrum_input_names`.
    """

    inputs: np.ndarray
    airspeed: np.ndarray
    damping: np.ndarray
    rms: np.ndarray
    window_start: np.ndarray
    window: float
    skipped: dict
    input_names: tuple[str, ...]
    input_units: tuple[str, ...]

    @property
    def n_windows(self) -> int:
        return int(self.airspeed.size)


def build_dataset(log, window: float = 2.0, channels: Sequence[str] = CHANNELS,
                  frequencies=DEFAULT_FREQUENCIES) -> TrainingData:
    """Windows of a recorded sweep -> network inputs and measured RMS.

    Parameters
    ----------
    log : FlightLog
        :func:`aero_dva.bag.flight_log_io.load_flight_log` of the sweep's bag.
    window : float
        [s] window length; the last ``window`` seconds of each dwell are used.
    channels : sequence of str
        Acceleration channels of the spectra (default plunge, pitch).
    frequencies : array_like
        [Hz] spectrum frequencies (default 5..20 Hz).

    Raises
    ------
    TrainingDataError
        No dwell long enough with complete samples.
    """
    unknown = [ch for ch in channels if ch not in ACCELERATION_CHANNELS]
    if unknown or not channels:
        raise ValueError(f"channels must be among {ACCELERATION_CHANNELS}, got {list(channels)}")
    rows = [ACCELERATION_CHANNELS.index(ch) for ch in channels]
    rate = float(log.sample_rate)
    n_win = int(round(window * rate))
    if not window > 0 or abs(n_win - window * rate) > 1e-6 * max(1.0, window * rate):
        raise ValueError(f"window * sample_rate must be a whole number of samples, got "
                         f"{window} s * {rate} Hz")
    dwells = find_dwells(log.airspeed, log.applied_damping)
    names, units = spectrum_input_names(channels, frequencies)
    skipped = {"short": 0, "gap": 0, "no_airspeed": 0}
    inputs, speeds, c2s, rms, starts = [], [], [], [], []
    for a, b, u, c in zip(dwells.start, dwells.stop, dwells.airspeed, dwells.damping):
        if np.isnan(u) or np.isnan(c):
            skipped["no_airspeed"] += 1
            continue
        if b - a < n_win:
            skipped["short"] += 1
            continue
        lo = b - n_win
        acc = log.accelerations[rows, lo:b]
        disp = log.displacements[LEADING_EDGE, lo:b]
        if not (np.all(np.isfinite(acc)) and np.all(np.isfinite(disp))):
            skipped["gap"] += 1
            continue
        spectrum = scaled_spectrum(acc, rate, frequencies)
        if not np.all(np.isfinite(spectrum.magnitudes)):
            skipped["gap"] += 1
            continue
        inputs.append(spectrum_input_vector(spectrum.magnitudes, c))
        speeds.append(u)
        c2s.append(c)
        rms.append(float(np.sqrt(np.mean(disp ** 2))))
        starts.append(lo)
    if not inputs:
        raise TrainingDataError(
            f"no usable {window:g} s window in the log: {dwells.start.size} dwell(s) found "
            f"(by changes of airspeed or applied c2), skipped {skipped}")
    return TrainingData(
        inputs=np.array(inputs), airspeed=np.array(speeds), damping=np.array(c2s),
        rms=np.array(rms), window_start=np.array(starts, dtype=int), window=float(window),
        skipped=skipped, input_names=names, input_units=units)


# -- labels, split, training --------------------------------------------------------------------

@dataclass(frozen=True)
class OptimalC2:
    """Per airspeed: the c2 with the lowest measured RMS (the experiment's optimum).

    Attributes
    ----------
    airspeed : ndarray, shape (n_airspeeds,) [m/s], ascending
    damping : ndarray, shape (n_airspeeds,) [N s/m] c2 of the lowest RMS
    rms : ndarray, shape (n_airspeeds,) [m] that lowest RMS
    n_damping : ndarray of int, shape (n_airspeeds,) windows (c2 values) seen at each airspeed
    targets : ndarray, shape (n_windows,) [N s/m] label of every window of the data set
    airspeed_index : ndarray of int, shape (n_windows,) index of each window's airspeed
    """

    airspeed: np.ndarray
    damping: np.ndarray
    rms: np.ndarray
    n_damping: np.ndarray
    targets: np.ndarray
    airspeed_index: np.ndarray


def label_min_rms(data: TrainingData, min_damping_values: int = 2) -> OptimalC2:
    """Label each window with the c2 that minimised the measured RMS at its airspeed.

    Raises
    ------
    TrainingDataError
        An airspeed with fewer than ``min_damping_values`` distinct c2 windows (no choice).
    """
    speeds, index = np.unique(data.airspeed, return_inverse=True)
    best_c2 = np.empty(speeds.size)
    best_rms = np.empty(speeds.size)
    counts = np.zeros(speeds.size, dtype=int)
    for k in range(speeds.size):
        members = np.flatnonzero(index == k)
        counts[k] = np.unique(data.damping[members]).size
        if counts[k] < min_damping_values:
            raise TrainingDataError(
                f"airspeed {speeds[k]:.3f} m/s has windows for {counts[k]} c2 value(s); "
                f"labelling needs at least {min_damping_values}")
        j = members[int(np.argmin(data.rms[members]))]
        best_c2[k], best_rms[k] = data.damping[j], data.rms[j]
    return OptimalC2(airspeed=speeds, damping=best_c2, rms=best_rms, n_damping=counts,
                     targets=best_c2[index], airspeed_index=index)


def split_by_airspeed(n_airspeeds: int, validation_every: int = 5, offset: int = 2
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Interleaved split of airspeed indices: every ``validation_every``-th is held out.

    Returns
    -------
    train, validation : ndarray of int
        Airspeed indices (ascending). Needs at least 2 training and 1 validation airspeed.
    """
    if isinstance(validation_every, bool) or not isinstance(validation_every, int) \
            or validation_every < 2:
        raise ValueError(f"validation_every must be an integer >= 2, got {validation_every!r}")
    idx = np.arange(n_airspeeds)
    held = (idx % validation_every) == (offset % validation_every)
    if not held.any() and n_airspeeds >= 3:
        held[n_airspeeds // 2] = True
    train, val = idx[~held], idx[held]
    if train.size < 2 or val.size < 1:
        raise TrainingDataError(
            f"{n_airspeeds} airspeed(s) in the log: too few to hold out whole airspeeds for "
            f"validation (need at least 3)")
    return train, val


@dataclass(frozen=True)
class TrainingOutcome:
    """A trained network and its errors.

    Attributes
    ----------
    result : OLSTrainingResult
        Training on the training airspeeds with the chosen spread (``result.network``).
    spreads, training_rmse, validation_rmse : ndarray, shape (n_spreads,)
        The candidates and their RMS errors [N s/m] on the training / held-out airspeeds.
    spread : float
        The chosen spread (lowest validation RMS error).
    train_airspeeds, validation_airspeeds : ndarray [m/s]
    training_error, validation_error : float
        [N s/m] RMS error of the chosen network on the training / validation windows.
    train_mask : ndarray of bool, shape (n_windows,)
        Which windows were used for training.
    """

    result: OLSTrainingResult
    spreads: np.ndarray
    training_rmse: np.ndarray
    validation_rmse: np.ndarray
    spread: float
    train_airspeeds: np.ndarray
    validation_airspeeds: np.ndarray
    training_error: float
    validation_error: float
    train_mask: np.ndarray

    @property
    def network(self):
        return self.result.network


def train_network(data: TrainingData, labels: OptimalC2, *, spreads=DEFAULT_SPREADS,
                  validation_every: int = 5, tolerance: float = 1e-3,
                  max_neurons: int = 100) -> TrainingOutcome:
    """OLS-train the RBF network; choose the spread on held-out airspeeds.

    The input scaling is fitted on all windows (min-max of inputs, not of labels), so the
    held-out windows lie in the scaled range the network was built for.
    """
    if data.inputs.shape[1] != SPECTRUM_INPUT_DIM:
        raise ValueError(f"data has {data.inputs.shape[1]} inputs, the seed's network "
                         f"{SPECTRUM_INPUT_DIM}")
    train_idx, val_idx = split_by_airspeed(labels.airspeed.size, validation_every)
    train_mask = np.isin(labels.airspeed_index, train_idx)
    x, y = data.inputs, labels.targets
    selection = select_spread(
        x[train_mask], y[train_mask], x[~train_mask], y[~train_mask], spreads,
        tolerance=tolerance, max_neurons=max_neurons, scaling=fit_input_scaling(x),
        input_names=data.input_names, input_units=data.input_units)
    best = selection.best_index
    return TrainingOutcome(
        result=selection.best, spreads=selection.spreads,
        training_rmse=selection.training_rmse, validation_rmse=selection.validation_rmse,
        spread=float(selection.best_spread), train_airspeeds=labels.airspeed[train_idx],
        validation_airspeeds=labels.airspeed[val_idx],
        training_error=float(selection.training_rmse[best]),
        validation_error=float(selection.validation_rmse[best]), train_mask=train_mask)


def network_c2_per_airspeed(network, data: TrainingData, labels: OptimalC2) -> np.ndarray:
    """Mean network output over each airspeed's windows [N s/m], shape (n_airspeeds,)."""
    pred = network.predict(data.inputs)
    out = np.zeros(labels.airspeed.size)
    np.add.at(out, labels.airspeed_index, pred)
    return out / np.bincount(labels.airspeed_index, minlength=labels.airspeed.size)
