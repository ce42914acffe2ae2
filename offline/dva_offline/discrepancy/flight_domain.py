"""Domain 2 of the discrepancy loop: flight logs (MCAP) against the wing + Maxwell DVA model.

Observations: H1 estimates of the frequency response from the measured aileron force to the
measured plunge and pitch accelerations, per flight segment (airspeed, density and reported
c2 nearly constant; Hann windows, see :mod:`.flight_frf`), at every other DFT bin of a band
(default 2-20 Hz). One group per segment and channel. Covariates per point: segment time,
airspeed, reported c2, pitch displacement RMS, time since the last c2 change.

Model values (output error through the estimator): the model is simulated along the whole log,
driven by the logged force at the logged airspeed, density and c2, held per block of
:data:`BLOCK` samples (the discrete wing in modal form, :mod:`aero_dva.flight.modal_simulator`),
and the same estimator is applied to its accelerations on the same windows. Leakage and the
transients of each window are then the same in both and cancel: a correct model leaves the
sensor noise alone (a noise-free flight is reproduced to 1e-6), where comparing with the
estimator's expectation left a leakage scatter 3 times the noise that hid the smaller effects.

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

- ``actuator_lag`` T [s]: the c2 acting is the logged c2 through a first-order lag.
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

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from aero_dva.bag import channels
from aero_dva.flight.discrete_model import DiscreteWing, pitch_moment_input
from aero_dva.flight.modal_simulator import ModalBlocks, simulate
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
                    "the last c2 change), none in steady segments",
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
    segment_windows : int
        Windows per segment (segments shorter than 2 windows are dropped).
    tolerance : float
        Relative change of airspeed, density or c2 that starts a new run.
    settle_s : float
        [s] start of the log not analysed (the model is simulated from rest from the log's
        start; the response to the unknown state before it dies out in about a second).
    """

    band: tuple[float, float] = (2.0, 20.0)
    window_s: float = 1.0
    segment_windows: int = 7
    tolerance: float = 0.02
    settle_s: float = 1.0

    def __post_init__(self):
        lo, hi = self.band
        if not 0 < lo < hi:
            raise ValueError(f"band must satisfy 0 < low < high [Hz], got {self.band}")
        if not self.window_s > 0:
            raise ValueError(f"window must be > 0 s, got {self.window_s}")
        if self.segment_windows < 2:
            raise ValueError(f"segment_windows must be >= 2, got {self.segment_windows}")
        if not 0 <= self.settle_s < 1e4:
            raise ValueError(f"settle must be in [0, 1e4) s, got {self.settle_s}")


@dataclass(frozen=True)
class FlightArrays:
    """What the domain needs from a log (time on the last axis, SI units)."""

    sample_rate: float
    force: np.ndarray
    accelerations: np.ndarray  # (2, n) plunge, pitch
    pitch: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray


def arrays_from_log(log) -> FlightArrays:
    """Check a :class:`~aero_dva.bag.flight_log_io.FlightLog` and take the needed channels.

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
    return FlightArrays(
        sample_rate=float(log.sample_rate), force=np.asarray(log.force, dtype=float),
        accelerations=np.asarray(log.accelerations[:2], dtype=float),
        pitch=np.asarray(log.displacements[1], dtype=float),
        airspeed=np.asarray(log.airspeed, dtype=float),
        density=np.asarray(log.density, dtype=float),
        damping=np.asarray(log.damping, dtype=float))  # a per-sample law's c2 where it flew


class FlightDomain:
    """The flight-log domain (module docstring) for :func:`.loop.run`.

    Parameters
    ----------
    data : FlightArrays
    wing_file : WingConfig
        From :func:`aero_dva.wing.wing_io.load_wing` (its wing, Maxwell absorber, aerodynamics).
    settings : FlightSettings, optional
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

    def __init__(self, data: FlightArrays, wing_file, settings: FlightSettings | None = None):
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
        finite = np.isfinite(data.force) & np.all(np.isfinite(data.accelerations), axis=0)
        cols = [np.where(finite, c, np.nan) for c in (data.airspeed, data.density, data.damping)]
        # The model is simulated from rest from the log's start: windows in the first settle_s
        # of data (where an unknown initial state still rings) are not used.
        settle = int(np.argmax(finite)) + int(round(self.settings.settle_s * fs))
        runs = [(max(a, settle), b)
                for a, b in runs_of_constant_condition(cols, self.settings.tolerance, 1)
                if b - max(a, settle) >= 2 * n_window]
        segs = estimate_segments(data.force, data.accelerations, runs, self.window, bins,
                                 self.settings.segment_windows)
        if len(segs) < 2:
            raise FlightDataError(
                f"too short a log: {len(segs)} segment(s) of >= 2 windows of "
                f"{self.settings.window_s:g} s with airspeed, density and c2 within "
                f"{100 * self.settings.tolerance:g} % (need >= 2; fly a few seconds per "
                "condition, e.g. a stepped or constant-airspeed flight: a ramp changes the "
                "airspeed too fast)")
        self.segments = segs
        self._build_tables()
        self.observations = self._observations()

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
        self._moment_cache: dict = {}
        self._condition_cache: dict = {}
        self._build_blocks()

    def _build_blocks(self):
        """Per simulation block: the logged condition and time; and the force DFTs of every
        window (the estimator applied to the simulated outputs)."""
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
        cov = {k: [] for k in ("time_s", "airspeed_mps", "damper_c2", "pitch_rms_rad",
                               "since_c2_change_s")}
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
                                 ("since_c2_change_s", self.seg_since_change[i])):
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

    def _predict(self, cal, *, lag=0.0, delay=0.0, kappa=0.0, aero_scale=None,
                 drift=None) -> np.ndarray:
        """Model values at every observation point (order of :attr:`observations`)."""
        aero = None
        if aero_scale is not None:
            jones = WagnerAero()
            aero = WagnerAero(a1=jones.a1 * aero_scale, b1=jones.b1,
                              a2=jones.a2 * aero_scale, b2=jones.b2)
        model = self._model(cal, aero)
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
        if delay:
            y = delay_outputs(y, delay / self.dt)
        # the segments' estimator applied to the simulated accelerations
        spec = self._band_spectrum(y[:, self._win_idx])  # (p, W, F)
        seg = np.tensordot(self._seg_of_win, self._win_xc * spec, axes=([1], [1]))  # (S, p, F)
        seg /= self._seg_sxx[:, None, :]
        if not np.all(np.isfinite(seg)):  # an unstable candidate diverges: a huge residual
            seg = np.where(np.isfinite(seg), seg, 1e12)
        return seg.reshape(-1)

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
            name=f"wing+maxwell({self._aero_name()})", effect=None, params=params, n_added=0,
            predict=lambda v: self._predict(v[:3]))

    def _aero_name(self) -> str:
        return "quasi-steady" if isinstance(self.aero, QuasiSteadyAero) else "wagner"

    def candidates(self, base, features):
        cal = [base.value(n) for n in CALIBRATION]
        params = tuple(self._cal_params(cal))
        name0 = f"wing+maxwell({self._aero_name()})"
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

        if self.has_c2_steps:
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
