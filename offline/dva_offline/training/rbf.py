"""Training the spectrum-based RBF controller from a recorded sweep (Zhang (2006) sec. 7.2.1).

The study's experiment: at each airspeed of 0.8 .. 1.14 U_cr (step 0.002 U_cr) 20 values of the
damper c2 are applied in turn; each (U, c2) pair gives a 2 s window at 1 kHz of both responses
(translational and rotational), whose eq. 7.3 scaled spectra at 5..20 Hz plus the current c2 are
the network's 33 inputs, and the optimal c2 of the condition is the output. Here the recorded
sweep is a training plan (:mod:`dva_offline.training.plan`: several densities, c2 around the
optimum, each dwell started from its stationary state) or a scenario sweep.

Steps (all pure numerics on arrays of a :class:`~aero_dva.bag.flight_log_io.FlightLog`):

1. :func:`find_dwells` cuts the log where the recorded airspeed, density or applied c2
   changes;
2. :func:`build_dataset` takes the last ``window`` seconds of each dwell and computes the
   scaled spectra of the plunge and pitch accelerations (what the ``spectrum`` node publishes
   to the ``rbf_controller``) and the leading-edge displacement RMS (the study's objective);
3. :mod:`dva_offline.training.labels` labels each window: the exact c2*(U, rho) of its
   condition (default) or the measured-RMS argmin (the study's procedure, which fails);
4. :func:`split_by_airspeed` holds out whole airspeeds (every k-th, at every density), so
   validation windows never share an airspeed with training windows;
5. :func:`train_network` trains by orthogonal least squares for each candidate spread and keeps
   the spread with the lowest RMS error on the held-out airspeeds among those whose neurons
   respond to the held-out inputs (median peak activation >= :data:`MIN_ACTIVATION`).

:func:`adapt_sweep` makes a *scenario* sweep safe to fly continuously (``dva train sweep
--scenario``): an unstable (U, c2) pair grows and ruins every later dwell, so only airspeeds
at which every c2 of the list decays at least at a given rate are kept, and each dwell gets a
settling time before its window.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from aero_dva.control.rbf_network import (
    SPECTRUM_INPUT_DIM,
    OLSTrainingResult,
    fit_input_scaling,
    spectrum_input_names,
    spectrum_input_vector,
    train_rbf_ols,
)
from aero_dva.control.spectrum import DEFAULT_FREQUENCIES, scaled_spectrum
from aero_dva.flight.scenario import AirspeedProfile, Scenario, sweep_duration
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES, LEADING_EDGE
from dva_offline.training.defaults import DEFAULT_SPREADS, MAX_CANDIDATES, MIN_ACTIVATION

__all__ = [
    "ACCELERATION_CHANNELS",
    "CHANNELS",
    "DEFAULT_SPREADS",
    "MAX_CANDIDATES",
    "MIN_ACTIVATION",
    "Dwells",
    "NetworkMetrics",
    "SweepAdaptation",
    "TrainingData",
    "TrainingDataError",
    "TrainingOutcome",
    "adapt_sweep",
    "build_dataset",
    "build_dataset_from_rows",
    "condition_predictability",
    "find_dwells",
    "network_c2_per_condition",
    "network_metrics",
    "select_windows",
    "split_by_airspeed",
    "train_network",
]

#: Acceleration channels of a FlightLog, in its row order (the wing model's outputs).
ACCELERATION_CHANNELS = ACCELERATION_NAMES
#: Spectrum channels of the study's network (translational, rotational), as the spectrum node.
CHANNELS = ("plunge", "pitch")


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
    """Runs of samples with constant recorded airspeed, density and applied c2.

    Attributes
    ----------
    start, stop : ndarray of int, shape (n,)
        Sample index range ``[start, stop)`` of each dwell.
    airspeed : ndarray, shape (n,) [m/s]
    density : ndarray, shape (n,) [kg/m^3]
    damping : ndarray, shape (n,) [N s/m] applied c2
    """

    start: np.ndarray
    stop: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray


def find_dwells(airspeed, applied_damping, density=None) -> Dwells:
    """Cut a sweep where the recorded airspeed, density or applied c2 changes.

    Parameters
    ----------
    airspeed, applied_damping : array_like, shape (n,)
        Per-sample airspeed [m/s] and applied c2 [N s/m] (FlightLog fields).
    density : array_like, shape (n,), optional
        Per-sample air density [kg/m^3]; default: not cut on (NaN in the result).

    Raises
    ------
    TrainingDataError
        No damper state recorded (all c2 NaN) or no samples.
    """
    u = np.asarray(airspeed, dtype=float)
    c = np.asarray(applied_damping, dtype=float)
    rho = np.full(u.shape, np.nan) if density is None else np.asarray(density, dtype=float)
    if u.ndim != 1 or c.shape != u.shape or rho.shape != u.shape:
        raise ValueError(f"airspeed, applied_damping and density must be 1-D of equal length, "
                         f"got {u.shape}, {c.shape} and {rho.shape}")
    if u.size == 0:
        raise TrainingDataError("the log holds no samples")
    if np.all(np.isnan(c)):
        raise TrainingDataError("the log has no applied c2 (topic /dva/damper_state missing or "
                                "empty): dwells cannot be found")
    # NaN != NaN would cut at every sample; compare with NaN mapped to a sentinel.
    changed = np.zeros(u.size - 1, dtype=bool)
    for x in (u, c, rho):  # one key at a time: a sweep's arrays are large
        key = np.where(np.isnan(x), -1.0, x)
        changed |= np.diff(key) != 0
    cuts = np.flatnonzero(changed) + 1
    start = np.concatenate([[0], cuts]).astype(int)
    stop = np.concatenate([cuts, [u.size]]).astype(int)
    return Dwells(start=start, stop=stop, airspeed=u[start], density=rho[start],
                  damping=c[start])


@dataclass(frozen=True)
class TrainingData:
    """One window per usable dwell.

    Attributes
    ----------
    inputs : ndarray, shape (n, 33)
        Scaled spectra of the plunge and pitch accelerations (channel-major, 5..20 Hz), then c2.
    airspeed : ndarray, shape (n,) [m/s]
    density : ndarray, shape (n,) [kg/m^3]
    damping : ndarray, shape (n,) [N s/m] c2 applied during the window
    rms : ndarray, shape (n,) [m] measured leading-edge displacement RMS over the window
    window_start : ndarray of int, shape (n,)
        Sample index of each window's first sample.
    window : float
        [s] window length.
    sample_rate : float
        [Hz]
    skipped : dict
        Dwells not used, by reason ("short", "gap", "no_airspeed").
    input_names, input_units : tuple of str
        As :func:`aero_dva.control.rbf_network.spectrum_input_names`.
    """

    inputs: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    rms: np.ndarray
    window_start: np.ndarray
    window: float
    sample_rate: float
    skipped: dict
    input_names: tuple[str, ...]
    input_units: tuple[str, ...]

    @property
    def n_windows(self) -> int:
        return int(self.airspeed.size)


def build_dataset(log, window: float = 2.0, channels: Sequence[str] = CHANNELS,
                  frequencies=DEFAULT_FREQUENCIES, *, spectra_batch: int = 256) -> TrainingData:
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
    spectra_batch : int
        Windows whose spectra are computed in one product (1: one window at a time, the
        previous route; the spectra agree to rounding).

    Raises
    ------
    TrainingDataError
        No dwell long enough with complete samples.
    """
    unknown = [ch for ch in channels if ch not in ACCELERATION_CHANNELS]
    if unknown or not channels:
        raise ValueError(f"channels must be among {ACCELERATION_CHANNELS}, got {list(channels)}")
    rows = [log.accelerations[ACCELERATION_CHANNELS.index(ch)] for ch in channels]
    return _dataset(float(log.sample_rate), log.airspeed, log.density, log.applied_damping,
                    rows, log.displacements[LEADING_EDGE], window, channels, frequencies,
                    max(1, int(spectra_batch)))


def build_dataset_from_rows(flight, window: float = 2.0, channels: Sequence[str] = CHANNELS,
                            frequencies=DEFAULT_FREQUENCIES) -> TrainingData:
    """:func:`build_dataset` from the rows it uses alone
    (:func:`aero_dva.bag.flight_log_io.read_flight_rows` with the acceleration ``channels``
    and the leading-edge displacement): the same data set, without the whole flight log in
    memory."""
    from aero_dva.bag import channels as topics

    unknown = [ch for ch in channels if ch not in ACCELERATION_CHANNELS]
    if unknown or not channels:
        raise ValueError(f"channels must be among {ACCELERATION_CHANNELS}, got {list(channels)}")
    acc = flight.rows[topics.ACCELERATION]
    rows = [acc[ch] for ch in channels]
    leading_edge = flight.rows[topics.DISPLACEMENT][DISPLACEMENT_NAMES[LEADING_EDGE]]
    return _dataset(flight.sample_rate, flight.airspeed, flight.density, flight.applied_damping,
                    rows, leading_edge, window, channels, frequencies)


def _dataset(rate, airspeed, density, damping, acceleration_rows, leading_edge, window,
             channels, frequencies, spectra_batch: int = 256) -> TrainingData:
    n_win = int(round(window * rate))
    if not window > 0 or abs(n_win - window * rate) > 1e-6 * max(1.0, window * rate):
        raise ValueError(f"window * sample_rate must be a whole number of samples, got "
                         f"{window} s * {rate} Hz")
    dwells = find_dwells(airspeed, damping, density)
    names, units = spectrum_input_names(channels, frequencies)
    skipped = {"short": 0, "gap": 0, "no_airspeed": 0}
    inputs, speeds, rhos, c2s, rms, starts = [], [], [], [], [], []
    pending = []  # windows whose spectra are computed together

    def flush():
        k = len(acceleration_rows)
        if not pending:
            return
        magnitudes = scaled_spectrum(np.concatenate([w[0] for w in pending]), rate,
                                     frequencies).magnitudes
        for i, (_, u, rho, c, r, lo) in enumerate(pending):
            m = magnitudes[i * k:(i + 1) * k]
            if not np.all(np.isfinite(m)):
                skipped["gap"] += 1
                continue
            inputs.append(spectrum_input_vector(m, c))
            speeds.append(u)
            rhos.append(rho)
            c2s.append(c)
            rms.append(r)
            starts.append(lo)
        pending.clear()

    for a, b, u, rho, c in zip(dwells.start, dwells.stop, dwells.airspeed, dwells.density,
                               dwells.damping):
        if np.isnan(u) or np.isnan(c) or np.isnan(rho):
            skipped["no_airspeed"] += 1
            continue
        if b - a < n_win:
            skipped["short"] += 1
            continue
        lo = b - n_win
        acc = np.stack([row[lo:b] for row in acceleration_rows])
        disp = leading_edge[lo:b]
        if not (np.all(np.isfinite(acc)) and np.all(np.isfinite(disp))):
            skipped["gap"] += 1
            continue
        pending.append((acc, u, rho, c, float(np.sqrt(np.mean(disp ** 2))), lo))
        if len(pending) >= spectra_batch:
            flush()
    flush()
    if not inputs:
        raise TrainingDataError(
            f"no usable {window:g} s window in the log: {dwells.start.size} dwell(s) found "
            f"(by changes of airspeed or applied c2), skipped {skipped}")
    return TrainingData(
        inputs=np.array(inputs), airspeed=np.array(speeds), density=np.array(rhos),
        damping=np.array(c2s), rms=np.array(rms), window_start=np.array(starts, dtype=int),
        window=float(window), sample_rate=rate, skipped=skipped, input_names=names,
        input_units=units)


def select_windows(data: TrainingData, keep) -> TrainingData:
    """The windows ``keep`` (bool mask or indices) of ``data``."""
    keep = np.asarray(keep)
    per_window = ("inputs", "airspeed", "density", "damping", "rms", "window_start")
    return replace(data, **{name: getattr(data, name)[keep] for name in per_window})


# -- split, training --------------------------------------------------------------------------

def split_by_airspeed(airspeed, validation_every: int = 5, offset: int = 2) -> np.ndarray:
    """Hold out every ``validation_every``-th distinct airspeed, at every density.

    Parameters
    ----------
    airspeed : array_like, shape (n_windows,)
        [m/s] each window's airspeed.

    Returns
    -------
    ndarray of bool, shape (n_windows,)
        True for the training windows. Needs at least 2 training and 1 validation airspeed.
    """
    if isinstance(validation_every, bool) or not isinstance(validation_every, int) \
            or validation_every < 2:
        raise ValueError(f"validation_every must be an integer >= 2, got {validation_every!r}")
    speeds, index = np.unique(np.asarray(airspeed, dtype=float), return_inverse=True)
    idx = np.arange(speeds.size)
    held = (idx % validation_every) == (offset % validation_every)
    if not held.any() and speeds.size >= 3:
        held[speeds.size // 2] = True
    if held.sum() < 1 or (~held).sum() < 2:
        raise TrainingDataError(
            f"{speeds.size} airspeed(s) in the log: too few to hold out whole airspeeds for "
            f"validation (need at least 3)")
    return ~held[index.reshape(-1)]


@dataclass(frozen=True)
class NetworkMetrics:
    """How a network does on a set of windows.

    Attributes
    ----------
    rmse : float
        [N s/m] RMS error against the labels.
    r2 : float
        Coefficient of determination against the labels (1 - SSE / SST; NaN if the labels are
        constant).
    output_min, output_max : float
        [N s/m] the network's output range over the windows.
    median_peak_activation : float
        Median over the windows of the largest hidden-neuron response (1 at a centre): below
        :data:`MIN_ACTIVATION` the network mostly outputs its bias.
    """

    rmse: float
    r2: float
    output_min: float
    output_max: float
    median_peak_activation: float


def network_metrics(network, inputs: np.ndarray, targets: np.ndarray) -> NetworkMetrics:
    """:class:`NetworkMetrics` of ``network`` on ``inputs`` (n, 33) against ``targets`` (n,)."""
    hidden = network.hidden(inputs)
    pred = network.predict(inputs)  # the network's own output, as the node computes it
    err = pred - targets
    sst = float(np.sum((targets - targets.mean()) ** 2))
    peak = hidden.max(axis=1) if hidden.shape[1] else np.zeros(len(targets))
    return NetworkMetrics(rmse=float(np.sqrt(np.mean(err ** 2))),
                          r2=1.0 - float(err @ err) / sst if sst > 0 else math.nan,
                          output_min=float(pred.min()), output_max=float(pred.max()),
                          median_peak_activation=float(np.median(peak)))


@dataclass(frozen=True)
class TrainingOutcome:
    """A trained network and its errors.

    Attributes
    ----------
    result : OLSTrainingResult
        Training on the training airspeeds with the chosen spread (``result.network``).
    spreads : ndarray, shape (n_spreads,)
        The candidates.
    training : list of NetworkMetrics
        Per spread, on the training windows.
    validation : list of NetworkMetrics
        Per spread, on the held-out windows.
    chosen : int
        Index of the chosen spread.
    train_mask : ndarray of bool, shape (n_windows,)
        Which windows were used for training.
    n_candidates : int
        Candidate centres offered to the OLS selection.
    """

    result: OLSTrainingResult
    spreads: np.ndarray
    training: list
    validation: list
    chosen: int
    train_mask: np.ndarray
    n_candidates: int

    @property
    def network(self):
        return self.result.network

    @property
    def spread(self) -> float:
        return float(self.spreads[self.chosen])

    @property
    def training_metrics(self) -> NetworkMetrics:
        return self.training[self.chosen]

    @property
    def validation_metrics(self) -> NetworkMetrics:
        return self.validation[self.chosen]


def train_network(data: TrainingData, labels, *, spreads=DEFAULT_SPREADS,
                  validation_every: int = 5, tolerance: float = 1e-3,
                  max_neurons: int = 100, max_candidates: int = MAX_CANDIDATES
                  ) -> TrainingOutcome:
    """OLS-train the RBF network on the training airspeeds, one network per spread; keep the
    spread with the lowest validation RMS error among those with a median peak activation of
    at least :data:`MIN_ACTIVATION` on the held-out windows (the lowest error overall when no
    spread reaches it: the caller then refuses the network).

    The input scaling is fitted on all windows (min-max of inputs, not of labels), so the
    held-out windows lie in the scaled range the network was built for. ``labels`` is a
    :class:`~dva_offline.training.labels.Labels`.
    """
    if data.inputs.shape[1] != SPECTRUM_INPUT_DIM:
        raise ValueError(f"data has {data.inputs.shape[1]} inputs, the study's network "
                         f"{SPECTRUM_INPUT_DIM}")
    grid = np.array(spreads, dtype=float, ndmin=1)
    if grid.ndim != 1 or grid.size == 0 or not np.all(np.isfinite(grid)) or np.any(grid <= 0):
        raise ValueError(f"spreads must be finite values > 0, got {spreads}")
    if isinstance(max_candidates, bool) or not isinstance(max_candidates, int) \
            or max_candidates < 1:
        raise ValueError(f"max_candidates must be a positive integer, got {max_candidates!r}")
    train = split_by_airspeed(data.airspeed, validation_every)
    x, y = data.inputs, labels.targets
    rows = np.flatnonzero(train)
    if rows.size > max_candidates:
        rows = rows[np.unique(np.linspace(0, rows.size - 1, max_candidates).round()
                              .astype(int))]
    scaling = fit_input_scaling(x)
    results, on_train, on_val = [], [], []
    for spread in grid:
        res = train_rbf_ols(x[train], y[train], float(spread), tolerance=tolerance,
                            max_neurons=max_neurons, scaling=scaling, candidates=x[rows],
                            input_names=data.input_names, input_units=data.input_units)
        results.append(res)
        on_train.append(network_metrics(res.network, x[train], y[train]))
        on_val.append(network_metrics(res.network, x[~train], y[~train]))
    rmse = np.array([m.rmse for m in on_val])
    active = np.array([m.median_peak_activation >= MIN_ACTIVATION for m in on_val])
    chosen = int(np.argmin(np.where(active, rmse, np.inf))) if active.any() \
        else int(np.argmin(rmse))
    return TrainingOutcome(result=results[chosen], spreads=grid, training=on_train,
                           validation=on_val, chosen=chosen, train_mask=train,
                           n_candidates=int(rows.size))


def network_c2_per_condition(network, data: TrainingData, labels) -> np.ndarray:
    """Mean network output over each condition's windows [N s/m], shape (n_conditions,)."""
    pred = network.predict(data.inputs)
    out = np.zeros(labels.n_conditions)
    np.add.at(out, labels.condition_index, pred)
    return out / np.bincount(labels.condition_index, minlength=labels.n_conditions)


def condition_predictability(data: TrainingData, train_mask: np.ndarray) -> dict[str, float]:
    """How much of the airspeed and of the density one window's spectra carry.

    Least squares of each on the 32 scaled spectrum values (and a constant) over the training
    windows, R^2 on the held-out windows: a linear read-out, a lower bound of what the network
    can extract. NaN where the held-out windows have one value only.
    """
    x = np.column_stack([data.inputs[:, :-1], np.ones(data.n_windows)])
    out = {}
    for name, y in (("airspeed", data.airspeed), ("density", data.density)):
        coef, *_ = np.linalg.lstsq(x[train_mask], y[train_mask], rcond=None)
        held = y[~train_mask]
        sst = float(np.sum((held - held.mean()) ** 2))
        err = x[~train_mask] @ coef - held
        out[name] = 1.0 - float(err @ err) / sst if sst > 0 else math.nan
    return out
