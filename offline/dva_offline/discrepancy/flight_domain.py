"""Domain 2 of the discrepancy loop: flight logs (MCAP) against the wing + Maxwell DVA model.

Observations: H1 estimates of the frequency response from the measured aileron force to the
measured plunge and pitch accelerations, per flight segment (Hann windows, see
:mod:`.flight_frf`), at every other DFT bin of a band (default 2-20 Hz). One group per segment
and channel. Covariates per point: segment time, airspeed, reported c2, pitch displacement RMS,
time since the last c2 change (a per-sample law's flight: the commanded c2's switches per
second instead).

Two routes cut the log into segments (:data:`ROUTES`; chosen automatically, :func:`choose_route`):

- ``segments``: runs where airspeed, density and the reported c2 stay nearly constant (a
  stepped flight with c2 held per dwell);
- ``whole-flight``: the whole analysable span of the log, whatever the conditions do (a ramp,
  a per-sample law's flight: :mod:`.flight_varying`).

Model values (output error through the estimator): the model is simulated along the whole log,
driven by the logged force at the logged airspeed, density and c2, and the same estimator is
applied to its accelerations on the same windows. Leakage and the transients of each window
are then the same in both and cancel: a correct model leaves the sensor noise alone (a
noise-free flight is reproduced to 1e-6), where comparing with the estimator's expectation
left a leakage scatter 3 times the noise that hid the smaller effects. The segments route
holds the condition per block of :data:`BLOCK` samples (the discrete wing in modal form,
:mod:`aero_dva.flight.modal_simulator`); the whole-flight route steps each sample at its own
c2 (:mod:`aero_dva.flight.varying_simulator`): the c2 a per-sample law commanded, through the
damper's lag the model declares (:attr:`FlightDomain.declared_lag`: none unless given, the wing
file's model has an ideal damper).

Weights: w_j = median(eps) / (|H_j| eps_j), eps_j = sqrt(G_nn / S_xx,j) / |H_j| the relative
error the sensor noise alone gives the estimate (G_nn per channel from the output power not
coherent with the force well above the modes), so the residual w_j (H_model,j - H_j) is the
relative error scaled to the median point's noise and a correct model leaves residuals of about
equal size everywhere (the loop's noise floor and consistency test assume that).

Baseline: :class:`~aero_dva.wing.model.AeroelasticModel` of the wing file (chapter-6 wing
by default) with its Maxwell DVA and aerodynamics, calibrated by three parameters: pitch
stiffness k_alpha, plunge stiffness k and the structural damping factor beta (each within a
factor 1.5 of the file's value).

Candidates (each the baseline plus its parameters):

- ``actuator_lag`` T [s]: the c2 acting is the logged c2 through a first-order lag (a
  per-sample law's flight: the commanded c2 through a lag T in place of the declared one).
- ``sensor_delay`` tau [s]: accelerations delayed, H e^{-j w tau}.
- ``cubic_stiffness`` kappa [1/rad^2]: pitch moment k_alpha (alpha + kappa alpha^3); the
  cubic part enters as a pitch-moment input computed from the logged pitch angle, so the
  simulation is exact for the nonlinear wing (its distortion included) and stays linear.
- ``unsteady_aero`` s [-]: Wagner/Jones finite-state aerodynamics, lag amplitudes x s.
- ``parameter_drift`` (absorber_stiffness | pitch_stiffness | plunge_stiffness) r [1/s]:
  p(t) = p_0 (1 + r t), t from the start of the log (for the wing's stiffnesses beta K
  follows, C = beta K; p_0 is the calibrated value, the DVA spring's is the wing file's).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from aero_dva.bag import channels
from aero_dva.flight.discrete_model import (
    FLIGHT_QUANTUM,
    DiscreteWing,
    moment_probe,
    pitch_moment_input,
)
from aero_dva.flight.held_kernel import compiled_expm
from aero_dva.flight.modal_simulator import ModalBlocks, simulate
from aero_dva.flight.per_sample.switching_law import maxwell_index
from aero_dva.flight.varying_simulator import VaryingSteps, simulate_varying
from aero_dva.wing.aerodynamics import QuasiSteadyAero, TheodorsenAero, WagnerAero
from aero_dva.wing.model import AeroelasticModel
from dva_offline.discrepancy.fitting import (
    ModelSpec,
    NotApplicable,
    Observations,
    ParamSpec,
)
from dva_offline.discrepancy.flight_frf import (
    estimate_segments,
    hann,
    runs_of_constant_condition,
)
from dva_offline.discrepancy.flight_varying import (
    SPAN_WINDOW_S,
    analysable_stop,
    lagged_c2,
)
from dva_offline.discrepancy.loop import DecisionRule

CHANNELS = ("plunge", "pitch")  # accelerometer channels used (leading edge = their combination)
OUTPUTS = tuple(f"{channel}_acceleration" for channel in CHANNELS)  # the discrete wing's names
BLOCK = 50  # [samples] conditions are held per block (the hidden plant's drift/lag resolution)
CALIBRATION = ("pitch_stiffness", "plunge_stiffness", "damping_factor")
CALIBRATION_RANGE = 1.5  # calibrated parameters stay within a factor of the file's values
DRIFT_PARAMETERS = ("absorber_stiffness", "pitch_stiffness", "plunge_stiffness")
NOISE_BAND = 5.0  # the sensor noise level is measured from this multiple of the band's top
DRIFT_STEP_S = 0.5  # [s] a drifting parameter is held for this long in the simulation
SIGNATURES = {
    "actuator_lag": "residual in the segments right after c2 steps (depends on the time since "
                    "the last c2 change), none in steady segments; a per-sample law's flight: "
                    "the response to each switch of the commanded c2 comes late",
    "sensor_delay": "phase of H_meas/H_model falls linearly with frequency in every segment, "
                    "magnitude unchanged",
    "cubic_stiffness": "pitch mode stiffer in segments with larger pitch response (depends "
                       "on the response level)",
    "unsteady_aero": "airspeed-dependent change of the aeroelastic modes' frequency and "
                     "damping (circulatory lift lags the motion)",
    "parameter_drift": "modes shift steadily with flight time (depends on time, not on "
                       "level or c2)",
}


def delay_outputs(outputs: np.ndarray, samples: float) -> np.ndarray:
    """``outputs`` (p, n) delayed by ``samples`` (fractional: a linear phase over the whole
    record, zero-padded so nothing wraps round from the end; samples before 0 are zero)."""
    if samples == 0:
        return outputs
    n = outputs.shape[-1]
    m = 1 << int(np.ceil(np.log2(n + int(np.ceil(abs(samples))) + 2)))
    spec = np.fft.rfft(outputs, m, axis=-1)
    spec *= np.exp(-2j * np.pi * np.fft.rfftfreq(m) * samples)
    return np.fft.irfft(spec, m, axis=-1)[..., :n]


ROUTES = ("auto", "segments", "whole-flight")
SEGMENT_WINDOWS = {"segments": 7, "whole-flight": 3}  # the default windows per segment
# The resolution of a log's inputs (the whole-flight route's known noise): the flight layer
# renews a held airspeed only when it moved by FLIGHT_QUANTUM, and flies a lagged damper's c2
# on a table of levels (aero_dva.flight.per_sample.flight), which the logged c2 acting shows.
AIRSPEED_RESOLUTION = FLIGHT_QUANTUM
RESOLUTION_DRAWS = 4
LAG_RANGE = (1e-4, 2.0)  # [s] a per-sample law's damper lag: from none to far too slow


class FlightDataError(ValueError):
    """The log cannot be analysed (missing topic, too short, no usable segments)."""


@dataclass(frozen=True)
class FlightSettings:
    """How the log is turned into observations.

    Attributes
    ----------
    band : (float, float)
        [Hz] frequency band of the observations.
    window_s : float
        [s] DFT window (boxcar) length: the frequency resolution is 1 / window_s.
    segment_windows : int, optional
        Windows per segment (segments shorter than 2 windows are dropped); default
        :data:`SEGMENT_WINDOWS` of the route (a 4 s dwell is one segment; along a ramp 2 s
        segments follow the changing condition and give more points).
    tolerance : float
        Relative change of airspeed, density or c2 that starts a new run.
    settle_s : float
        [s] start of the log not analysed (the model is simulated from rest from the log's
        start; the response to the unknown state before it dies out in about a second).
    route : str
        One of :data:`ROUTES` (``auto``: :func:`choose_route`).
    """

    band: tuple[float, float] = (2.0, 20.0)
    window_s: float = 1.0
    segment_windows: int | None = None
    tolerance: float = 0.02
    settle_s: float = 1.0
    route: str = "auto"

    def __post_init__(self):
        lo, hi = self.band
        if not 0 < lo < hi:
            raise ValueError(f"band must satisfy 0 < low < high [Hz], got {self.band}")
        if not self.window_s > 0:
            raise ValueError(f"window must be > 0 s, got {self.window_s}")
        if self.segment_windows is not None and self.segment_windows < 2:
            raise ValueError(f"segment_windows must be >= 2, got {self.segment_windows}")
        if not 0 <= self.settle_s < 1e4:
            raise ValueError(f"settle must be in [0, 1e4) s, got {self.settle_s}")
        if self.route not in ROUTES:
            raise ValueError(f"route must be one of {', '.join(ROUTES)}, got {self.route!r}")

    def windows_per_segment(self, route: str) -> int:
        """The segments' windows on ``route`` (:data:`SEGMENT_WINDOWS` unless given)."""
        return self.segment_windows or SEGMENT_WINDOWS[route]


@dataclass(frozen=True)
class FlightArrays:
    """What the domain needs from a log (time on the last axis, SI units).

    ``damping`` is the c2 the analysis reads: the reported c2 of blocks over which it was held
    and, where a per-sample law flew (``law_flew``), the c2 the law commanded; ``reported``
    the damper state's c2 of every block (at the start of a law's block, its c2 then);
    ``law_sources`` the laws that flew (their commands' source); ``c2_resolution`` half the
    spacing in log c2 of the levels the c2 acting took where a law flew (a lagged damper flown
    on a table of levels; 0 when it took only the values commanded).
    """

    sample_rate: float
    force: np.ndarray
    accelerations: np.ndarray  # (2, n) plunge, pitch
    pitch: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    law_flew: np.ndarray | None = None
    reported: np.ndarray | None = None
    law_sources: tuple[str, ...] = ()
    c2_resolution: float = 0.0

    @property
    def per_sample(self) -> bool:
        """A per-sample law set c2 within blocks of this log."""
        return self.law_flew is not None and bool(self.law_flew.any())


def arrays_from_log(log, law_sources: tuple[str, ...] = ()) -> FlightArrays:
    """Check a :class:`~aero_dva.bag.flight_log_io.FlightLog` and take the needed channels
    (``law_sources``: :func:`~aero_dva.bag.flight_log_io.law_sources` of its bag).

    Where a per-sample law flew, the analysis reads the c2 it *commanded*
    (``DamperBlock.commanded_damping``), never the c2 that acted: that one already followed
    the damper's lag, which the analysis is to find.

    Raises FlightDataError naming what is missing.
    """
    missing = []
    if np.all(np.isnan(log.accelerations)):
        missing.append(f"{channels.ACCELERATION.absolute()} (accelerations)")
    if np.all(np.isnan(log.force)):
        missing.append(f"{channels.EXCITATION.absolute()} (aileron force)")
    if np.all(np.isnan(log.applied_damping)):
        missing.append(f"{channels.DAMPER_STATE.absolute()} (c2)")
    if missing:
        raise FlightDataError("the log lacks " + ", ".join(missing)
                              + "; a flight log needs force, accelerations, flight condition "
                                "and damper state")
    reported = np.asarray(log.applied_damping, dtype=float)
    acted = getattr(log, "law_damping", None)
    law_flew = np.zeros(reported.size, dtype=bool) if acted is None else np.isfinite(acted)
    command = getattr(log, "law_command", None)
    if law_flew.any() and (command is None or not np.all(np.isfinite(command[law_flew]))):
        raise FlightDataError(
            f"a per-sample law flew {int(law_flew.sum())} samples, but the log lacks the c2 it "
            f"commanded ({channels.DAMPER_BLOCK.absolute()} commanded_damping: a bag recorded "
            "before that field); the c2 that acted already followed the damper's lag, so "
            "the analysis cannot use it: fly the flight again")
    damping = reported if not law_flew.any() else np.where(law_flew, command, reported)
    return FlightArrays(c2_resolution=_level_resolution(acted, command, law_flew),
        sample_rate=float(log.sample_rate), force=np.asarray(log.force, dtype=float),
        accelerations=np.asarray(log.accelerations[:2], dtype=float),
        pitch=np.asarray(log.displacements[1], dtype=float),
        airspeed=np.asarray(log.airspeed, dtype=float),
        density=np.asarray(log.density, dtype=float), damping=np.asarray(damping, dtype=float),
        law_flew=law_flew, reported=reported, law_sources=tuple(law_sources))


def _level_resolution(acted, command, law_flew) -> float:
    """Half the median spacing in log c2 of the distinct values the c2 acting took where a
    law flew, when it took values the law never commanded (a lagged damper on a table of
    levels), else 0. Only the values' spacing is read, never their course in time."""
    if acted is None or not law_flew.any():
        return 0.0
    levels = np.unique(acted[law_flew])
    if np.isin(levels, np.unique(command[law_flew])).all() or levels.size < 3:
        return 0.0
    return float(0.5 * np.median(np.diff(np.log(levels))))


def choose_route(data: FlightArrays, settings: FlightSettings, segments: int) -> tuple:
    """(route, why): ``whole-flight`` for a per-sample law's flight (no two samples need
    share c2) or a log with fewer than 2 segments of constant condition (a ramp),
    ``segments`` otherwise, or the route ``settings`` asks for."""
    if settings.route != "auto":
        return settings.route, "asked for"
    if data.per_sample:
        return "whole-flight", "a per-sample law set c2 every sample"
    if segments < 2:
        return "whole-flight", (f"{segments} segment(s) of constant airspeed, density and c2 "
                                "(a ramp)")
    return "segments", f"{segments} segments of constant airspeed, density and c2"


class FlightDomain:
    """The flight-log domain (module docstring) for :func:`.loop.run`.

    Parameters
    ----------
    data : FlightArrays
    wing_file : WingConfig
        From :func:`aero_dva.wing.wing_io.load_wing` (its wing, Maxwell absorber, aerodynamics).
    settings : FlightSettings, optional
    damper_lag : float, optional
        [s] the damper lag the model declares for a per-sample law's flight (default: the
        lag the law was designed for, its controller table entry): the baseline flies the
        commanded c2 through it, and ``actuator_lag`` fits another in its place. A flight
        with c2 held per block declares none (the reported c2 acted).

    Attributes
    ----------
    route, route_reason : str
        The route taken (:data:`ROUTES`) and why.
    declared_lag : float
        [s] the damper lag of the baseline.
    span : (int, int)
        Samples [start, stop) analysed; ``span_reason`` says why it stops where it does.
    """

    name = "flight"
    # segments of one flight are no test conditions of a covariate: no saturated reference
    per_condition_reference = False
    # H1 estimates of neighbouring segments share windows and the noise floor from second
    # differences is only approximate here: a clearly significant candidate is not hidden by
    # a high noise floor estimate (loop.DecisionRule.strict_consistency).
    decision_rule = DecisionRule(strict_consistency=True)
    error_definition = (
        "RMS over held-out points j (not used in any fit) of w_j |H_model_j - H_j|, "
        "w_j = median(eps) / (|H_j| eps_j): the relative error of each H1 estimate scaled by "
        "the relative error eps_j the sensor noise alone gives it, relative to the median "
        "point's; H_model is the same estimator applied, on the same windows, to the model's "
        "response to the logged force; error_l2 = sqrt(sum |H_model - H|^2 / sum |H|^2) over "
        "the same points")

    def __init__(self, data: FlightArrays, wing_file, settings: FlightSettings | None = None,
                 damper_lag: float | None = None):
        self.settings = settings or FlightSettings()
        self.data = data
        self.wing = wing_file.wing
        self.absorber = wing_file.maxwell_design
        self.aero = wing_file.aero
        if isinstance(self.aero, TheodorsenAero):
            raise ValueError("the wing file's aerodynamics must have a time-domain form "
                             "(quasi-steady or wagner), not theodorsen")
        fs = data.sample_rate
        self.dt = 1.0 / fs
        n_window = int(round(self.settings.window_s * fs))
        lo, hi = self.settings.band
        df = fs / n_window
        # every other bin: Hann-windowed estimates of neighbouring bins are correlated
        bins = np.arange(int(np.ceil(lo / df)), int(np.floor(hi / df)) + 1, 2)
        if bins.size < 5 or hi >= fs / 2:
            raise FlightDataError(f"band {lo:g}-{hi:g} Hz holds {bins.size} bins at "
                                  f"{df:g} Hz resolution (need >= 5, below {fs / 2:g} Hz)")
        self.n_window, self.bins = n_window, bins
        self.window = hann(n_window)
        self._condition_cache: dict = {}
        if damper_lag is not None and not (math.isfinite(damper_lag) and damper_lag >= 0):
            raise ValueError(f"damper lag must be finite and >= 0 s, got {damper_lag}")
        finite = np.isfinite(data.force) & np.all(np.isfinite(data.accelerations), axis=0)
        cols = [np.where(finite, c, np.nan) for c in (data.airspeed, data.density, data.damping)]
        # The model is simulated from rest from the log's start: windows in the first settle_s
        # of data (where an unknown initial state still rings) are not used.
        settle = int(np.argmax(finite)) + int(round(self.settings.settle_s * fs))
        runs = [(max(a, settle), b)
                for a, b in runs_of_constant_condition(cols, self.settings.tolerance, 1)
                if b - max(a, settle) >= 2 * n_window]
        segs = estimate_segments(data.force, data.accelerations, runs, self.window, bins,
                                 self.settings.windows_per_segment("segments"))
        self.route, self.route_reason = choose_route(data, self.settings, len(segs))
        self.declared_lag, self.lag_reason = 0.0, "c2 held per block: the reported c2 acted"
        if damper_lag is not None and not data.per_sample:
            raise FlightDataError("a damper lag is declared for a per-sample law's commands, "
                                  "and no per-sample law flew this log (c2 held per block: "
                                  "the reported c2 acted); leave out --damper-lag")
        if data.per_sample and damper_lag is None:
            self.lag_reason = "the wing file's ideal damper; --damper-lag declares one"
        elif data.per_sample:
            self.declared_lag, self.lag_reason = float(damper_lag), "--damper-lag"
        self.span = (settle, finite.size)
        self.span_reason = "the end of the log"
        self.span_growth = np.zeros(0)
        if self.route == "whole-flight":
            self._varying_setup()
            segs = self._whole_flight_segments(finite, settle)
        elif data.per_sample:
            raise FlightDataError("a per-sample law set c2 every sample: no segment holds c2 "
                                  "constant; analyse it with the whole-flight route")
        if len(segs) < 2:
            if self.route == "whole-flight":
                raise FlightDataError(
                    f"too short a log: {len(segs)} segment(s) of "
                    f"{self.settings.windows_per_segment(self.route)} windows of "
                    f"{self.settings.window_s:g} s in the "
                    f"{(self.span[1] - self.span[0]) / fs:.1f} s analysed (samples from "
                    f"{self.span[0] / fs:.1f} s to {self.span[1] / fs:.1f} s, ending at "
                    f"{self.span_reason}; need >= 2 segments: fly longer)")
            raise FlightDataError(
                f"too short a log: {len(segs)} segment(s) of >= 2 windows of "
                f"{self.settings.window_s:g} s with airspeed, density and c2 within "
                f"{100 * self.settings.tolerance:g} % (need >= 2; fly a few seconds per "
                "condition, e.g. a stepped or constant-airspeed flight)")
        self.segments = segs
        self._build_tables()
        self.observations = self._observations()
        # noise the residual's second differences cannot see (loop.with_known_noise)
        self.known_noise = self._resolution_floor() if self.route == "whole-flight" else None

    # -- the whole-flight route ------------------------------------------------------------
    def _varying_setup(self):
        """Per sample: the block's condition, the command and where a lag acts on it."""
        d = self.data
        n = d.force.size
        self._command = np.nan_to_num(d.damping, nan=float(np.nanmean(d.damping)))
        # a per-sample law's flight: its commands lag; a flight with c2 held per block: the
        # reported c2 (actuator_lag filters it, as the segments route does)
        self._lag_mask = d.law_flew.copy() if d.per_sample else np.ones(n, dtype=bool)
        reported = d.reported if d.reported is not None else d.damping
        self._lag_start = np.where(np.isfinite(reported), reported, self._command)
        both = np.concatenate([self._command, self._lag_start])
        if not np.all(both > 0):
            raise FlightDataError("the logged c2 must be > 0 N s/m at every sample")
        k2 = self.absorber.series_stiffness
        self._rate_range = (k2 / both.max(), k2 / both.min())

    def _rates(self, lag: float) -> np.ndarray:
        """[1/s] r = k2 / c2 of each sample with the commands through a lag ``lag`` [s]."""
        c2 = lagged_c2(self._command, self._lag_mask, self._lag_start, lag, self.dt)
        return self.absorber.series_stiffness / c2

    def _whole_flight_segments(self, finite, settle):
        """Segments of the analysable span (:func:`.flight_varying.analysable_stop` with the
        wing file's model and the declared lag), cut where the data are not finite."""
        fs = self.data.sample_rate
        window = int(round(SPAN_WINDOW_S * fs))
        self._build_condition_index()
        nominal = (self.wing.pitch_stiffness, self.wing.plunge_stiffness,
                   self.wing.damping_factor)
        steps, _ = self._varying_steps(self._model(nominal), drift=None, kappa=False)
        stop, growth = analysable_stop(steps, self._sample_condition(False),
                                       self._rates(self.declared_lag), settle, finite.size,
                                       window)
        self.span_growth = growth
        if stop < finite.size:
            u = np.nanmean(self.data.airspeed[stop:stop + window])
            self.span_reason = (f"{stop / fs:.1f} s (U = {u:.1f} m/s), where the wing along "
                                "the log stops damping its own state (the spectral radius of "
                                f"its {SPAN_WINDOW_S:g} s state transition reaches 1): beyond, "
                                "output error grows without bound")
        self.span = (settle, stop)
        cols = [np.where(finite[:stop], 1.0, np.nan)]
        runs = [(max(a, settle), b) for a, b in runs_of_constant_condition(cols, 0.0, 1)
                if b - max(a, settle) >= 2 * self.n_window]
        return estimate_segments(self.data.force, self.data.accelerations, runs, self.window,
                                 self.bins, self.settings.windows_per_segment("whole-flight"))

    # -- tables ----------------------------------------------------------------------------
    def _build_tables(self):
        d, segs = self.data, self.segments
        wins = np.concatenate([s.windows for s in segs])
        self.win_segment = np.concatenate([np.full(len(s.windows), i)
                                           for i, s in enumerate(segs)])
        self.win_start, self.win_stop = wins[:, 0], wins[:, 1]
        csum = {name: np.concatenate([[0.0], np.cumsum(np.nan_to_num(arr))])
                for name, arr in (("U", d.airspeed), ("c2", d.damping))}
        length = self.win_stop - self.win_start

        def window_mean(name):
            return (csum[name][self.win_stop] - csum[name][self.win_start]) / length

        self.win_u, self.win_c2 = window_mean("U"), window_mean("c2")  # covariates
        fs = d.sample_rate
        self.win_time = 0.5 * (self.win_start + self.win_stop) / fs
        pitch = np.nan_to_num(d.pitch)
        seg_var = np.array([np.var(pitch[s.start:s.stop]) for s in segs])
        self.seg_pitch_rms = np.sqrt(seg_var)
        self.win_pitch_var = seg_var[self.win_segment]
        # time since the last change of the reported c2 (covariate of the actuator lag)
        c2 = d.damping
        change = np.flatnonzero(np.abs(np.diff(np.nan_to_num(c2))) > 1e-9 * np.nanmax(
            np.abs(c2)).clip(1e-12)) + 1
        seg_start = np.array([s.start for s in segs])
        last = np.searchsorted(change, seg_start, side="right") - 1
        since = np.where(last >= 0, (seg_start - change[np.clip(last, 0, None)]) / fs,
                         seg_start / fs)
        self.seg_since_change = since
        self.has_c2_steps = change.size > 0
        # the logged c2 per sample (the lag candidate filters it)
        self._c2_samples = np.nan_to_num(c2, nan=float(np.nanmean(c2)))
        # a per-sample law's flight: how often the commanded c2 switches in each segment
        switched = np.concatenate([[0], np.cumsum(np.diff(self._c2_samples) != 0)])
        self.seg_switch_rate = np.array([(switched[s.stop - 1] - switched[s.start])
                                         * fs / max(s.stop - s.start - 1, 1) for s in segs])
        self._moment_cache: dict = {}
        self._build_blocks()

    def _build_condition_index(self):
        """Per simulation block of :data:`BLOCK` samples: the logged condition and time."""
        if hasattr(self, "blk_u"):
            return
        d, blk = self.data, BLOCK
        n = d.force.size
        nb = -(-n // blk)

        def block_mean(x):
            padded = np.full(nb * blk, np.nan)
            padded[:n] = x
            rows = padded.reshape(nb, blk)
            count = np.isfinite(rows).sum(1)
            mean = np.where(count > 0, np.nansum(rows, 1) / np.maximum(count, 1), np.nan)
            # blocks without a finite sample take the previous block's value (then the next's)
            good = np.flatnonzero(np.isfinite(mean))
            if good.size == 0:
                raise FlightDataError("no finite sample in a logged condition")
            return mean[good[np.clip(np.searchsorted(good, np.arange(nb), "right") - 1, 0,
                                             None)]]

        self.blk_u, self.blk_rho = block_mean(d.airspeed), block_mean(d.density)
        self.blk_c2 = block_mean(d.damping)
        self.blk_time = (np.arange(nb) + 0.5) * blk / d.sample_rate

    def _build_blocks(self):
        """The block conditions (:meth:`_build_condition_index`) and the force DFTs of every
        window (the estimator applied to the simulated outputs)."""
        d = self.data
        self._build_condition_index()
        self._force = np.nan_to_num(d.force)
        self._pitch = np.nan_to_num(d.pitch)
        idx = np.concatenate([s.windows[:, :1] for s in self.segments]) + np.arange(
            self.n_window)
        self._win_idx = idx
        # The windowed DFT at the band's bins only, as one real matrix (N, 2F) [cos | -sin]:
        # a fit asks for a few bins of every window thousands of times, where a whole FFT
        # per window computed every bin
        phase = 2.0 * np.pi * np.outer(np.arange(self.n_window), self.bins) / self.n_window
        self._dft = self.window[:, None] * np.concatenate([np.cos(phase), -np.sin(phase)], 1)
        # the windows of each segment summed by one matrix product (S, W)
        self._seg_of_win = (self.win_segment[None, :] == np.arange(len(self.segments))[:, None]
                            ).astype(float)
        x = self._band_spectrum(self._force[idx])
        self._win_xc = np.conj(x)  # (W, F)
        self._seg_sxx = self._seg_of_win @ np.abs(x) ** 2

    def _noise_eps(self, h) -> np.ndarray:
        """Expected relative error of each estimate from the sensor noise alone.

        The model's H1 comes from the same windows of the same force, so leakage cancels and
        the residual of a correct model is sum_w conj(X_w) N_w / sum_w |X_w|^2 (N the
        accelerometer noise), of variance G_nn / S_xx: G_nn the noise power per window DFT,
        S_xx the segment's force power at the bin. G_nn (white noise: one value per channel)
        is the output power not coherent with the force well above the wing's modes
        (NOISE_BAND x the band's upper end up to 0.4 fs), where the FRF is flat and leakage
        does not bias the coherence as it does near the lightly damped modes.
        """
        fs = self.data.sample_rate
        df = fs / self.n_window
        lo = max(NOISE_BAND * self.settings.band[1], self.settings.band[1] + 5.0)
        high = np.arange(int(np.ceil(lo / df)), int(0.4 * fs / df) + 1)
        if high.size < 5:  # a low sample rate: fall back on the band itself
            high = self.bins
        win = self.window
        idx = self._win_idx
        x = np.fft.rfft(win * self._force[idx], axis=-1)[:, high]  # (W, F)
        y = np.fft.rfft(win * np.nan_to_num(self.data.accelerations)[:, idx],
                        axis=-1)[..., high]  # (p, W, F)
        runs = np.array([self.segments[i].run for i in self.win_segment])
        gnn = []
        for r in np.unique(runs):
            w = runs == r
            gxx = np.mean(np.abs(x[w]) ** 2, 0)
            gxy = np.mean(np.conj(x[w]) * y[:, w], 1)
            gyy = np.mean(np.abs(y[:, w]) ** 2, 1)
            # incoherent power; n_w / (n_w - 1): the coherence of n_w windows is biased up
            n_w = int(w.sum())
            gnn.append(np.clip(gyy - np.abs(gxy) ** 2 / gxx, 0.0, None) * n_w / max(n_w - 1, 1))
        noise = np.median(np.concatenate(gnn, axis=1), axis=1)  # (p,)
        per = np.sqrt(noise[None, :, None] / self._seg_sxx[:, None, :])  # (S, p, F)
        e = per.reshape(-1) / np.abs(h)
        return np.maximum(e, 0.2 * np.median(e))  # |H| ~ 0 or noise ~ 0: do not trust eps

    def _observations(self) -> Observations:
        segs = self.segments
        n_ch, n_f = len(CHANNELS), self.bins.size
        values, groups, freq = [], [], []
        # a per-sample law's c2 changes every few samples: its switching rate instead
        last = "c2_switches_per_s" if self.data.per_sample else "since_c2_change_s"
        cov = {k: [] for k in ("time_s", "airspeed_mps", "damper_c2", "pitch_rms_rad", last)}
        fs = self.data.sample_rate
        for i, s in enumerate(segs):
            w = self.win_segment == i
            for ch in range(n_ch):
                values.append(s.h[ch])
                groups.append(np.full(n_f, i * n_ch + ch))
                freq.append(self.bins * fs / self.n_window)
                for key, val in (("time_s", 0.5 * (s.start + s.stop) / fs),
                                 ("airspeed_mps", self.win_u[w].mean()),
                                 ("damper_c2", self.win_c2[w].mean()),
                                 ("pitch_rms_rad", self.seg_pitch_rms[i]),
                                 ("since_c2_change_s", self.seg_since_change[i]),
                                 ("c2_switches_per_s", self.seg_switch_rate[i])):
                    if key not in cov:
                        continue
                    cov[key].append(np.full(n_f, float(val)))
        y = np.concatenate(values)
        e = self._noise_eps(y)
        weights = np.median(e) / (np.abs(y) * e)
        return Observations(y, weights, np.concatenate(freq), np.concatenate(groups),
                            {k: np.concatenate(v) for k, v in cov.items()})

    # -- the model -------------------------------------------------------------------------
    def _model(self, cal, aero=None) -> AeroelasticModel:
        wing = self.wing.replace(pitch_stiffness=cal[0], plunge_stiffness=cal[1],
                                 damping_factor=cal[2])
        return AeroelasticModel(wing, self.absorber, self.aero if aero is None else aero)

    def _predict(self, cal, *, lag=None, delay=0.0, kappa=0.0, aero_scale=None,
                 drift=None) -> np.ndarray:
        """Model values at every observation point (order of :attr:`observations`);
        ``lag`` [s] the damper's (None: :attr:`declared_lag`)."""
        aero = None
        if aero_scale is not None:
            jones = WagnerAero()
            aero = WagnerAero(a1=jones.a1 * aero_scale, b1=jones.b1,
                              a2=jones.a2 * aero_scale, b2=jones.b2)
        model = self._model(cal, aero)
        lag = self.declared_lag if lag is None else float(lag)
        if self.route == "whole-flight":
            y = self._simulate_varying(model, cal, aero, lag, kappa, drift)
        else:
            y = self._simulate_blocks(model, cal, aero, lag, kappa, aero_scale, drift)
        if delay:
            y = delay_outputs(y, delay / self.dt)
        return self._estimates(y)

    def _estimates(self, y: np.ndarray) -> np.ndarray:
        """The segments' estimator applied to accelerations ``y`` (p, n): the model values
        at every observation point."""
        spec = self._band_spectrum(y[:, self._win_idx])  # (p, W, F)
        seg = np.tensordot(self._seg_of_win, self._win_xc * spec, axes=([1], [1]))  # (S, p, F)
        seg /= self._seg_sxx[:, None, :]
        if not np.all(np.isfinite(seg)):  # an unstable candidate diverges: a huge residual
            seg = np.where(np.isfinite(seg), seg, 1e12)
        return seg.reshape(-1)

    def _simulate_varying(self, model, cal, aero, lag, kappa, drift,
                          moved=None) -> np.ndarray:
        """Accelerations (p, n) of ``model`` along the log, each sample at its own c2
        (``moved``: factors on the blocks' airspeeds and the samples' c2, or None)."""
        u_factor, c2_factor = (None, None) if moved is None else moved
        steps, drifting = self._varying_steps(model, drift=drift, kappa=kappa > 0, cal=cal,
                                              aero=aero, u_factor=u_factor)
        stop = self.span[1]  # no window reaches beyond the span
        inputs = self._force[:stop, None]
        if kappa > 0:  # the cubic pitch moment from the logged pitch angle (see below)
            inputs = np.column_stack([inputs[:, 0], -kappa * cal[0] * self._pitch[:stop]**3])
        rates = self._rates(lag)
        if c2_factor is not None:
            rates = np.clip(rates / c2_factor, *self._rate_range)
        y = np.zeros((len(OUTPUTS), self.data.force.size))
        y[:, :stop] = simulate_varying(
            steps, self._sample_condition(drifting, u_factor)[:stop], rates[:stop], inputs)
        return y

    def _sample_condition(self, drift: bool, u_factor=None) -> np.ndarray:
        """(n,) each sample's index into :meth:`_varying_keys`."""
        keys, inverse = self._varying_keys(drift, u_factor)
        n = self.data.force.size
        return np.repeat(inverse, BLOCK)[:n]

    def _varying_keys(self, drift: bool, u_factor=None):
        """The distinct block conditions (rows u, rho[, drift time]) and each block's index
        (``u_factor``: the blocks' airspeeds moved by these factors; not kept)."""
        cached = None if u_factor is not None else self._condition_cache.get(("varying", drift))
        if cached is None:
            cols = [self.blk_u if u_factor is None else self.blk_u * u_factor, self.blk_rho]
            if drift:
                cols.append(np.round(self.blk_time / DRIFT_STEP_S) * DRIFT_STEP_S)
            keys, inverse = np.unique(np.stack(cols, axis=1), axis=0, return_inverse=True)
            cached = (keys, inverse.reshape(-1))
            if u_factor is None:
                self._condition_cache[("varying", drift)] = cached
        return cached

    def _resolution_floor(self) -> tuple[float, str]:
        """(sigma, why): what the model cannot reproduce of a noise-free log because its
        inputs are known only to their resolution, in the residual's units: the RMS change of
        the weighted estimates (wing file's model, declared lag) when each block's airspeed
        moves uniformly within +-:data:`AIRSPEED_RESOLUTION` (relative) and, where a lagged
        damper flew a per-sample law's c2 on a table of levels, each sample's c2 within
        +-half a level (:attr:`FlightArrays.c2_resolution`), over :data:`RESOLUTION_DRAWS`
        seeded draws."""
        nominal = (self.wing.pitch_stiffness, self.wing.plunge_stiffness,
                   self.wing.damping_factor)
        model = self._model(nominal)
        lag = self.declared_lag
        y0 = self._estimates(self._simulate_varying(model, nominal, None, lag, 0.0, None))
        rng = np.random.default_rng(0)
        n = self.data.force.size
        half = self.data.c2_resolution
        lagging = half > 0
        power = []
        for _ in range(RESOLUTION_DRAWS):
            u_factor = 1.0 + AIRSPEED_RESOLUTION * rng.uniform(-1, 1, self.blk_u.size)
            c2_factor = np.where(self._lag_mask, np.exp(half * rng.uniform(-1, 1, n)), 1.0)
            y = self._simulate_varying(model, nominal, None, lag, 0.0, None,
                                       moved=(u_factor, c2_factor))
            change = self.observations.weights * (self._estimates(y) - y0)
            power.append(np.mean(np.abs(change) ** 2))
        sigma = float(np.sqrt(np.mean(power)))
        why = (f"the log's inputs are known to their resolution only (airspeed "
               f"+-{100 * AIRSPEED_RESOLUTION:g} % per block"
               + (f", a per-sample law's lagged c2 +-{100 * (np.exp(half) - 1):.1f} %"
                  if lagging else "") + ")")
        return sigma, why

    def _varying_steps(self, model, *, drift=None, kappa=False, cal=None, aero=None,
                       u_factor=None):
        """The per-sample steps of ``model`` at the log's block conditions
        (:class:`~aero_dva.flight.varying_simulator.VaryingSteps`; inputs: the force, and a
        pitch moment with ``kappa``) and whether they carry the drift's time column."""
        keys, _ = self._varying_keys(drift is not None, u_factor)
        wing = DiscreteWing(model, self.data.sample_rate, hold=BLOCK)
        rows_out = wing.output_index(OUTPUTS)
        probe = moment_probe(model) if kappa else None

        def build(rows):
            u, rho = rows[:, 0], rows[:, 1]
            inf = np.full(u.size, np.inf)
            k1 = None
            if drift is not None and drift[0] == "absorber_stiffness":
                k1 = self.absorber.stiffness * (1.0 + drift[1] * rows[:, 2])
            a, b = model.matrices(u, rho, inf, k1)
            if drift is not None and k1 is None:
                name, rate = drift
                step = np.array(cal, dtype=float)
                step[0 if name == "pitch_stiffness" else 1] *= 1.01
                a_step, _ = self._model(step, aero).matrices(u, rho, inf)
                # A is affine in each stiffness (beta K follows): p(t) = p (1 + r t)
                a = a + (rate * rows[:, 2] / 0.01)[:, None, None] * (a_step - a)
            cols = [b]
            if kappa:
                cols.append(pitch_moment_input(model, u, rho, inf, probe))
            b = np.stack(cols, axis=-1)
            c, d = wing.output_matrices(a, b)
            return a, b, c[:, rows_out], d[:, rows_out]

        steps = VaryingSteps(build, keys, self._rate_range, self.dt, maxwell_index(model),
                             expm=compiled_expm)
        return steps, drift is not None

    def _simulate_blocks(self, model, cal, aero, lag, kappa, aero_scale, drift) -> np.ndarray:
        """Accelerations (p, n) of ``model`` along the log, the condition held per block
        (the segments route)."""
        c2 = self.blk_c2
        if lag > 0:
            g = np.exp(-self.dt / lag)
            x = self._c2_samples
            true, _ = lfilter([1.0 - g], [1.0, -g], x, zi=[g * x[0]])
            padded = np.full(c2.size * BLOCK, true[-1])
            padded[:true.size] = true
            c2 = padded.reshape(-1, BLOCK).mean(1)
        keys, inverse = self._conditions(c2, drift is not None, lag > 0)
        u, rho, c = keys[:, 0], keys[:, 1], keys[:, 2]
        k1 = None
        if drift is not None and drift[0] == "absorber_stiffness":
            k1 = self.absorber.stiffness * (1.0 + drift[1] * keys[:, 3])
        a, b = model.matrices(u, rho, c, k1)
        if drift is not None and k1 is None:
            name, rate = drift
            index = 0 if name == "pitch_stiffness" else 1
            step = np.array(cal, dtype=float)
            step[index] *= 1.01
            a_step, _ = self._model(step, aero).matrices(u, rho, c)
            # A is affine in each stiffness (beta K follows): p(t) = p (1 + r t)
            a = a + (rate * keys[:, 3] / 0.01)[:, None, None] * (a_step - a)
        wing = DiscreteWing(model, self.data.sample_rate, hold=BLOCK)
        modes = ModalBlocks.of(wing, a, b, OUTPUTS)
        y = simulate(modes, inverse, self._force)
        if kappa > 0:
            # the cubic part of the pitch spring as a pitch moment input computed from the
            # logged pitch angle: exact for the nonlinear wing, distortion included
            bm = self._moment_column(model, aero_scale, u, rho, c)
            _, d_m = wing.output_matrices(a, bm)
            moment = -kappa * cal[0] * self._pitch**3
            y = y + simulate(modes.with_input(bm, d_m[:, wing.output_index(OUTPUTS)]), inverse,
                             moment)
        return y

    def _band_spectrum(self, frames: np.ndarray) -> np.ndarray:
        """rfft(window * frames)[..., bins] of frames (..., N), by the band's DFT matrix."""
        both = frames @ self._dft
        n = self.bins.size
        return both[..., :n] + 1j * both[..., n:]

    def _conditions(self, c2, drift: bool, lagged: bool) -> tuple[np.ndarray, np.ndarray]:
        """The distinct conditions of the blocks (rows u, rho, c2[, drift time]) and each
        block's index into them: blocks share few conditions, so each distinct one is
        discretised once. Without a lag the c2 column is the logged one, so the answer is
        the same on every call of a fit and kept."""
        cached = None if lagged else self._condition_cache.get(drift)
        if cached is not None:
            return cached
        cols = [self.blk_u, self.blk_rho, c2]
        if drift:
            cols.append(np.round(self.blk_time / DRIFT_STEP_S) * DRIFT_STEP_S)
        keys, inverse = np.unique(np.stack(cols, axis=1), axis=0, return_inverse=True)
        found = keys, inverse.reshape(-1)
        if not lagged:
            self._condition_cache[drift] = found
        return found

    def _moment_column(self, model, aero_scale, u, rho, c) -> np.ndarray:
        """Pitch-moment input columns at the conditions (they depend on mass and density
        only, so they are cached per aerodynamic model and condition set)."""
        key = (aero_scale, u.tobytes(), rho.tobytes(), c.tobytes())
        cached = self._moment_cache.get(key)
        if cached is None:
            if len(self._moment_cache) > 256:
                self._moment_cache.clear()
            cached = pitch_moment_input(model, u, rho, c)
            self._moment_cache[key] = cached
        return cached

    def _cal_params(self, values=None) -> list[ParamSpec]:
        nominal = (self.wing.pitch_stiffness, self.wing.plunge_stiffness,
                   self.wing.damping_factor)
        start = nominal if values is None else values
        units = ("N m/rad", "N/m", "s")
        r = CALIBRATION_RANGE
        # Bounds slightly asymmetric: a start at the exact centre of the logistic map is z = 0
        # for every parameter, where MINPACK's relative x-tolerance stops at once.
        return [ParamSpec(n, u, float(np.clip(v, p / r * 1.001, p * r / 1.001)), p / r,
                          p * r * 1.05, log=True)
                for n, u, v, p in zip(CALIBRATION, units, start, nominal)]

    def baseline(self, train: np.ndarray) -> ModelSpec:
        params = tuple(self._cal_params())
        return ModelSpec(
            name=self._base_name(), effect=None, params=params, n_added=0,
            predict=lambda v: self._predict(v[:3]))

    def _aero_name(self) -> str:
        return "quasi-steady" if isinstance(self.aero, QuasiSteadyAero) else "wagner"

    def _base_name(self) -> str:
        lag = f", damper lag {1e3 * self.declared_lag:g} ms" if self.declared_lag > 0 else ""
        return f"wing+maxwell({self._aero_name()}{lag})"

    def candidates(self, base, features):
        cal = [base.value(n) for n in CALIBRATION]
        params = tuple(self._cal_params(cal))
        name0 = self._base_name()
        out = []

        nominal = [self.wing.pitch_stiffness, self.wing.plunge_stiffness,
                   self.wing.damping_factor]

        def spec(effect, added, predict, starts, label="", nominal_starts=()):
            # nominal_starts: from the wing file's calibration as well (a large effect pulls
            # the baseline's calibration far from the truth, a local minimum for the fit)
            full = params + tuple(added)
            return ModelSpec(
                name=f"{name0} + {effect}" + (f"({label})" if label else ""), effect=effect,
                params=full, n_added=len(added), predict=predict,
                starts=tuple(np.array(cal + list(s), dtype=float) for s in starts)
                + tuple(np.array(nominal + list(s), dtype=float) for s in nominal_starts),
                signature=SIGNATURES[effect], label=label)

        if self.data.per_sample:
            # the lag in place of the declared one, from it and a grid (the fit in T is not
            # convex: a lag shifts each switch's response by a fraction of a period)
            lo, hi = LAG_RANGE
            t0 = float(np.clip(self.declared_lag, 2 * lo, hi / 2))
            grid = [(t,) for t in (1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3) if abs(t - t0) > 0.1 * t0]
            out.append(spec(
                "actuator_lag", [ParamSpec("time_constant", "s", t0, lo, hi, log=True)],
                lambda v: self._predict(v[:3], lag=v[3]), grid))
        elif self.has_c2_steps:
            out.append(spec(
                "actuator_lag", [ParamSpec("time_constant", "s", 1.0, 1e-3, 20.0, log=True)],
                lambda v: self._predict(v[:3], lag=v[3]), []))
        else:
            out.append(NotApplicable("actuator_lag", "the reported c2 never changes in the "
                                                     "log: a lag of the actuator cannot show"))
        delay0 = 0.004  # informed by the residual's phase slope when it shows a delay
        if features.phase is not None and np.isfinite(features.phase.equivalent_delay_s):
            delay0 = float(np.clip(features.phase.equivalent_delay_s, 0.001, 0.045))
        out.append(spec(
            "sensor_delay", [ParamSpec("delay", "s", delay0, 0.0, 0.05, scale=1e-3)],
            lambda v: self._predict(v[:3], delay=v[3]),
            [(0.002,), (0.005,), (0.01,), (0.02,), (0.035,)],  # the phase is periodic
            nominal_starts=[(delay0,)]))
        var = self.win_pitch_var
        if not np.any(np.isfinite(self.data.pitch)):
            out.append(NotApplicable("cubic_stiffness", "the log has no pitch angle "
                                     "(wing/displacement): the cubic moment cannot be formed"))
        elif var.max() > 0 and var.max() > 1.5 * var.min():
            kmax = 1.0 / var.max()  # +300 % pitch stiffness at the largest response
            out.append(spec(
                "cubic_stiffness",
                [ParamSpec("kappa", "1/rad^2", 0.1 * kmax, 0.0, kmax, scale=0.01 * kmax)],
                lambda v: self._predict(v[:3], kappa=v[3]), []))
        else:
            out.append(NotApplicable("cubic_stiffness", "the pitch response level hardly "
                                     "varies over the flight: amplitude dependence cannot show"))
        if isinstance(self.aero, WagnerAero):
            out.append(NotApplicable("unsteady_aero", "the baseline already has unsteady "
                                                      "(Wagner) aerodynamics"))
        else:
            out.append(spec(
                "unsteady_aero", [ParamSpec("lag_scale", "-", 1.0, 0.02, 1.9)],
                lambda v: self._predict(v[:3], aero_scale=v[3]), [],
                nominal_starts=[(0.5,), (1.0,)]))
        span = self.win_time.max()
        rmax = 0.6 / span
        for name in DRIFT_PARAMETERS:
            out.append(spec(
                "parameter_drift",
                [ParamSpec("rate", "1/s", 0.01 / span, -rmax, rmax, scale=1e-3)],
                lambda v, name=name: self._predict(v[:3], drift=(name, v[3])), [], label=name))
        return out

    def variants(self, spec):
        return []
