"""The block-rate command laws without ROS: what c2 a controller commands for an input.

The controller node (dva_controller's generic node) hosts these by their table entry
(:mod:`aero_dva.control.controllers`), ``dva replay --offline`` calls them on a recorded bag and
``dva evaluate`` in its in-process flights, so all give the same commands.

- :class:`FixedLaw`: a constant c2 at every tick of its node's timer;
- :class:`ScheduleLaw`: ``c2 = a0 + a1 U`` (eq. 7.1) for a valid airspeed, clamped to the
  damper, at most one command per ``min_period`` of time (stamps of the flight conditions);
- :class:`RBFLaw`: the network's output for a scaled spectrum and the current c2 (eq. 7.4-7.5,
  input as :func:`~aero_dva.control.rbf_network.spectrum_input_vector`), clamped to the damper.

Each has ``answer(kind, stamp_ns, value)``, the table's interface, and a factory
(:func:`fixed_law`, :func:`schedule_law`, :func:`rbf_law`) from its parameter values.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.controllers import LawStep, SpectrumInput
from aero_dva.control.rbf_network import RBFNetwork, spectrum_input_names, spectrum_input_vector
from aero_dva.control.spectrum import DEFAULT_FREQUENCIES
from aero_dva.flight.damper import MAX_DAMPING
from aero_dva.wing.model import ACCELERATION_NAMES

__all__ = ["FixedLaw", "RBFLaw", "ScheduleCommand", "ScheduleLaw", "check_network_inputs",
           "clamp", "damping_range", "fixed_law", "rbf_law", "schedule_law", "spectrum_shape"]

FREQUENCY_TOLERANCE = 1.0e-6  # [Hz] spectrum frequencies must match the training ones this well
DURATION_TOLERANCE = 1.0e-6  # [s]
#: Hidden activations below this everywhere mean the input is far from every training centre.
FAR_ACTIVATION = 1.0e-3
BAND_SUM = "band_sum"  # dva_msgs/ScaledSpectrum.SCALING_BAND_SUM: the network's inputs


def clamp(value: float, low: float, high: float) -> float:
    """``value`` limited to ``[low, high]``."""
    return min(max(value, low), high)


# -- fixed ---------------------------------------------------------------------------------------

class FixedLaw:
    """A constant c2 [N s/m], at every tick of its node's timer (``rate`` [Hz])."""

    counters = ()

    def __init__(self, damping: float, rate: float):
        self.damping = self._checked(damping)
        self.rate = float(rate)

    @staticmethod
    def _checked(value) -> float:
        value = float(value)
        if not math.isfinite(value) or not 0.0 <= value <= MAX_DAMPING:
            raise ValueError(
                f"parameter 'damping' must be in [0, {MAX_DAMPING:g}] N s/m, got {value}")
        return value

    def set(self, name: str, value) -> None:
        """A run-time change of ``damping`` (ValueError: refused, naming it)."""
        if name == "damping":
            self.damping = self._checked(value)

    def answer(self, kind: str, stamp_ns: int, value) -> LawStep:
        return LawStep.command(self.damping)

    def condition_law(self) -> float:
        """c2 as a function of the flight condition (the stability boundaries'): a constant."""
        return self.damping

    def describe(self) -> str:
        return f"commanding c2 = {self.damping:g} N s/m at {self.rate:g} Hz"


def fixed_law(values: Mapping) -> FixedLaw:
    return FixedLaw(values["damping"], values["rate"])


# -- airspeed schedule ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ScheduleCommand:
    """What :meth:`ScheduleLaw.step` did with one flight condition: ``kind`` is "command"
    (``damping`` set), "rejected" (``reason`` says why) or "rate_limited"."""

    kind: str
    damping: float = math.nan
    reason: str = ""


class ScheduleLaw:
    """Commands of the airspeed schedule for a stream of flight conditions.

    Parameters
    ----------
    schedule : AirspeedSchedule
    damping_range : (float, float)
        [N s/m] the damper's range; commands are clamped to it.
    extrapolate : bool
        Continue the schedule's line outside its fitted airspeeds.
    max_airspeed : float
        [m/s] larger airspeeds (and NaN, inf, negative ones) are rejected.
    min_period_ns : int
        [ns] least time between two commands (stamps); 0: one per condition.
    origin : str
        Where the schedule came from (for the start-up line).
    """

    counters = ("rate_limited",)

    def __init__(self, schedule: AirspeedSchedule, damping_range: tuple[float, float],
                 extrapolate: bool, max_airspeed: float, min_period_ns: int = 0,
                 origin: str = "") -> None:
        self.schedule = schedule
        self.damping_range = damping_range
        self.extrapolate = extrapolate
        self.max_airspeed = max_airspeed
        self.min_period_ns = int(min_period_ns)
        self.origin = origin
        self._last_ns: int | None = None

    def command_for(self, airspeed: float) -> float:
        """[N s/m] the clamped eq. 7.1 command at a valid airspeed [m/s]."""
        c2 = self.schedule.evaluate(airspeed, extrapolate=self.extrapolate)
        return clamp(c2, *self.damping_range)

    def step(self, stamp_ns: int, airspeed: float) -> ScheduleCommand:
        """The command for a flight condition stamped ``stamp_ns`` [ns] at ``airspeed``."""
        if not (math.isfinite(airspeed) and 0.0 <= airspeed <= self.max_airspeed):
            return ScheduleCommand("rejected", reason=f"airspeed {airspeed} m/s is not in "
                                   f"[0, {self.max_airspeed:g}] m/s")
        last = self._last_ns
        if last is not None and 0 <= stamp_ns - last < self.min_period_ns:
            return ScheduleCommand("rate_limited")
        self._last_ns = stamp_ns
        return ScheduleCommand("command", self.command_for(airspeed))

    def answer(self, kind: str, stamp_ns: int, value) -> LawStep:
        """A flight condition (``value``: :class:`~.controllers.Condition`)."""
        result = self.step(stamp_ns, value.airspeed)
        if result.kind == "command":
            return LawStep.command(result.damping)
        return LawStep(result.kind, reason=result.reason,
                       values={"airspeed": value.airspeed, "stamp_ns": stamp_ns}
                       if result.kind == "rejected" else {})

    def condition_law(self):
        """c2(U, rho) of the schedule's line (the stability boundaries'; eq. 7.1 clamped to
        the schedule's range)."""
        schedule, extrapolate = self.schedule, self.extrapolate
        return lambda airspeed, density: schedule.evaluate(airspeed, extrapolate=extrapolate)

    def describe(self) -> str:
        low, high = self.damping_range
        return (f"c2 = {self.schedule.a0:g} + {self.schedule.a1:g} U N s/m ({self.origin}), "
                f"clamped to [{low:g}, {high:g}] N s/m")


def damping_range(low: float, high: float) -> tuple[float, float]:
    """Validate the ``damping_min``/``damping_max`` pair."""
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 <= low < high):
        raise ValueError(
            f"parameters 'damping_min' and 'damping_max' must satisfy 0 <= min < max, "
            f"got {low}, {high} N s/m"
        )
    return float(low), float(high)


def schedule_law(values: Mapping) -> ScheduleLaw:
    """The airspeed controller's law: the schedule file's line and ranges (``schedule_file``)
    or ``a0``, ``a1``, clamped to the damper's range (and the file's)."""
    from aero_dva.control.schedule_io import load_schedule

    low, high = damping_range(float(values["damping_min"]), float(values["damping_max"]))
    max_airspeed = float(values["max_airspeed"])
    path = str(values["schedule_file"])
    if path:
        schedule = load_schedule(path)  # ScheduleFileError (a ValueError) names the file
        file_low, file_high = schedule.damping_range
        low, high = max(low, file_low), min(high, file_high)
        if low > high:
            raise ValueError(
                f"airspeed schedule {path!r}: its damping range {schedule.damping_range} "
                "N s/m does not overlap the damper range of 'damping_min'/'damping_max'"
            )
        origin = f"schedule file {path}"
    else:
        schedule = AirspeedSchedule(a0=float(values["a0"]), a1=float(values["a1"]),
                                    airspeed_range=(0.0, max_airspeed),
                                    damping_range=(low, high))
        origin = "parameters a0, a1"
    return ScheduleLaw(schedule, (low, high), bool(values["extrapolate"]), max_airspeed,
                       round(float(values["min_period"]) * 1e9), origin)


# -- RBF network ---------------------------------------------------------------------------------

@dataclass(eq=False)
class RBFLaw:
    """c2 from a scaled spectrum with a trained RBF network, clamped to ``damping_range``;
    the spectra must have the shape it was trained on (``channels``, ``frequencies``,
    ``window``, ``window_duration``)."""

    network: RBFNetwork
    damping_range: tuple[float, float]
    channels: tuple[str, ...] = ("plunge", "pitch")
    frequencies: np.ndarray = field(default_factory=lambda: DEFAULT_FREQUENCIES.copy())
    window: str = "rectangular"
    window_duration: float = 2.0
    path: str = ""
    last_activation: float = field(default=math.nan, init=False)

    counters = ("far_inputs",)

    def command(self, magnitudes, damping: float) -> tuple[float, float]:
        """Clamped output [N s/m] for ``magnitudes`` (channels, n_freq) and the current c2
        ``damping`` [N s/m], and the largest hidden activation (1.0 for a network of no
        neurons). The output is NaN (not clamped) if the network gives no finite value."""
        x = spectrum_input_vector(np.asarray(magnitudes, dtype=float), damping)
        activation = float(self.network.hidden(x).max()) if self.network.n_neurons else 1.0
        c2 = float(self.network.predict(x))
        if not math.isfinite(c2):
            return c2, activation
        return clamp(c2, *self.damping_range), activation

    def mismatch(self, spectrum: SpectrumInput) -> str | None:
        """Why a spectrum is not an input of this network (None if it is)."""
        if spectrum.channel_names != self.channels:
            return f"channels {list(spectrum.channel_names)}, network has {list(self.channels)}"
        freqs = spectrum.frequencies
        if freqs.shape != self.frequencies.shape or not np.allclose(
            freqs, self.frequencies, rtol=0.0, atol=FREQUENCY_TOLERANCE
        ):
            return (
                f"{freqs.size} frequencies {freqs.tolist()} Hz, network has "
                f"{self.frequencies.size} ({self.frequencies.tolist()} Hz)"
            )
        if spectrum.scaling != BAND_SUM:
            return f"scaling {spectrum.scaling!r}, network needs {BAND_SUM!r}"
        if spectrum.window_function != self.window:
            return f"window {spectrum.window_function!r}, network has {self.window!r}"
        if abs(spectrum.window_duration - self.window_duration) > DURATION_TOLERANCE:
            return (
                f"window duration {spectrum.window_duration:g} s, network has "
                f"{self.window_duration:g} s"
            )
        if not np.all(np.isfinite(spectrum.magnitudes)):
            return "magnitudes hold NaN or inf"
        if not (math.isfinite(spectrum.damping) and spectrum.damping >= 0.0):
            return f"current c2 (damping) is {spectrum.damping}, not a finite value >= 0"
        return None

    def answer(self, kind: str, stamp_ns: int, value: SpectrumInput) -> LawStep:
        """A spectrum: its command, or why it gives none."""
        problem = self.mismatch(value)
        if problem is None:
            c2, activation = self.command(value.magnitudes, value.damping)
            if not math.isfinite(c2):
                problem = f"the network's output is {c2}"
        if problem is not None:
            return LawStep("rejected", reason=problem)
        self.last_activation = activation
        return LawStep.command(c2, values={"activation": activation},
                               counted=("far_inputs",) if activation < FAR_ACTIVATION else ())

    def status(self, last_command: float) -> tuple[str, str, dict]:
        """The node's periodic status: a warning while the last input is far from every
        training centre (the output is then close to the bias)."""
        values = {"last_command": last_command, "largest_activation": self.last_activation}
        if self.last_activation < FAR_ACTIVATION:
            return "warn", (f"last input is far from every training centre (largest "
                            f"activation {self.last_activation:.2g}): the output is close to "
                            "the bias"), values
        return "ok", f"last command {last_command:.6g} N s/m", values

    def describe(self) -> str:
        low, high = self.damping_range
        return (f"RBF network {self.path}: {self.network.n_neurons} neurons, "
                f"{self.network.input_dim} inputs ({list(self.channels)} x "
                f"{self.frequencies.size} frequencies + c2); commands clamped to "
                f"[{low:g}, {high:g}] N s/m")


def check_network_inputs(network: RBFNetwork, path: str, channels: tuple[str, ...],
                         frequencies: np.ndarray) -> None:
    """Raise ValueError unless the network's inputs are the spectrum inputs of the parameters."""
    names, units = spectrum_input_names(channels, frequencies)
    if network.input_names != names:
        diff = [(i, a, b) for i, (a, b) in enumerate(zip(network.input_names, names)) if a != b]
        i, got, want = diff[0]
        raise ValueError(
            f"RBF network file {path!r}: input {i} is {got!r} but channels {list(channels)} "
            f"and frequencies {frequencies.tolist()} Hz give {want!r} "
            f"({len(diff)} of {len(names)} input names differ)"
        )
    if network.input_units != units:
        raise ValueError(
            f"RBF network file {path!r}: input units {list(network.input_units)} are not "
            f"{list(units)}"
        )


def rbf_law(values: Mapping) -> RBFLaw:
    """The RBF controller's law: the network file (checked against the spectra's shape) and
    the damper's range."""
    from aero_dva.control.rbf_io import load_rbf_network

    channels, frequencies, window, window_duration = spectrum_shape(values)
    low, high = damping_range(float(values["damping_min"]), float(values["damping_max"]))
    path = str(values["network_file"])
    if not path:
        raise ValueError("parameter 'network_file' is required (a trained RBF network .npz)")
    dim = len(channels) * frequencies.size + 1
    network = load_rbf_network(path, expected_input_dim=dim)  # RBFFileError names it
    check_network_inputs(network, path, channels, frequencies)
    return RBFLaw(network, (low, high), channels, frequencies, window, window_duration, path)


# -- the spectra's shape -------------------------------------------------------------------------

def spectrum_shape(values) -> tuple[tuple[str, ...], np.ndarray, str, float]:
    """``channels, frequencies, window, window_duration`` from parameter values (the rows of
    :data:`~aero_dva.control.controllers.SPECTRUM_SHAPE`), checked."""
    return (checked_channels(values["channels"]), checked_frequencies(values["frequencies"]),
            str(values["window"]), float(values["window_duration"]))


def checked_channels(value) -> tuple[str, ...]:
    """Validate the ``channels`` parameter (known names, at least one, none twice)."""
    channels = tuple(c for c in value if c)
    if not channels:
        raise ValueError("parameter 'channels' must name at least one channel")
    unknown = [c for c in channels if c not in ACCELERATION_NAMES]
    if unknown:
        raise ValueError(
            f"parameter 'channels': unknown channel(s) {unknown}, "
            f"expected some of {list(ACCELERATION_NAMES)}"
        )
    if len(set(channels)) != len(channels):
        raise ValueError(f"parameter 'channels' lists a channel twice: {list(channels)}")
    return channels


def checked_frequencies(value) -> np.ndarray:
    """Validate the ``frequencies`` parameter (numbers, finite, > 0, distinct)."""
    try:
        freqs = np.array([float(f) for f in value])
    except (TypeError, ValueError):
        raise ValueError(f"parameter 'frequencies' must be numbers, got {value!r}") from None
    if freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs <= 0.0):
        raise ValueError(
            f"parameter 'frequencies' must be finite values > 0 Hz, got {freqs.tolist()}"
        )
    if np.unique(freqs).size != freqs.size:
        raise ValueError(f"parameter 'frequencies' has repeated values: {freqs.tolist()}")
    return freqs
