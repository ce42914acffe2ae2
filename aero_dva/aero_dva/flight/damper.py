"""The tunable damper c2 of the Maxwell-element DVA as the simulator applies it.

Zhang (2006) treats c2 as ideal: whatever the controller asks for acts at once (section 7).
A real semi-active damper has a range, may lag, and must survive bad or missing commands, so
the simulator passes every command through :class:`DamperModel`:

- validation: NaN, infinite, negative, or above ``absurd_factor * max_damping`` commands are
  rejected and never applied (the previous target stays);
- saturation: accepted commands are clipped to ``[min_damping, max_damping]``;
- staleness: if no command is accepted for longer than ``stale_timeout``, the target becomes
  ``fallback_damping`` until the next accepted command;
- optional first-order lag ``tau dc/dt = target - c``, integrated exactly for a piecewise
  constant target: ``c(t + dt) = target + (c(t) - target) exp(-dt / tau)``;
- one range for every route: whatever sets c2 (a command, the per-sample law, a sweep, a
  training plan, a replay) is checked against the damper's range by
  :func:`damping_problem` / :meth:`DamperConfig.range_problem`, and the model itself never
  holds a c2 outside it (:meth:`DamperModel.record_mode` included);
- a per-sample law slot: a command from the source of a per-sample law (``"switching"``,
  ``"clipped_optimal"``: the flight's configuration says which sources have one) asks the
  damper's own controller to run that law every sample (its ``damping`` is the constant c2 to
  hold when the law cannot run). The flight runs the law
  (:mod:`aero_dva.flight.per_sample.stream`) and tells the model what it did
  (:meth:`DamperModel.record_mode`: the mode, the switching rate and the c2 the lag reached);
  a stale command ends it like any other.

Time is sim time in seconds, passed in by the caller; the model has no clock. The model's
state maps onto ``dva_msgs/DamperState`` (see :class:`DamperSnapshot`).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from aero_dva.flight.flight_limits import (  # their home: said once, re-exported here
    DAMPER_RANGE,
    DEFAULT_STALE_TIMEOUT,
    MAX_DAMPING,
    SWITCHING_SOURCE,
)
from aero_dva.text_input import loggable

__all__ = [
    "DAMPER_RANGE",
    "DEFAULT_STALE_TIMEOUT",
    "MAX_DAMPING",
    "CommandResult",
    "DamperConfig",
    "DamperMode",
    "DamperModel",
    "DamperSnapshot",
    "DamperStatus",
    "Rejection",
    "SWITCHING_SOURCE",
    "check_damping",
    "damping_problem",
]


def damping_problem(values, what: str, damping_range=DAMPER_RANGE) -> str | None:
    """Why the c2 value(s) ``values`` [N s/m] cannot be given to the damper of
    ``damping_range`` (NaN, infinite or outside the range), in one line naming ``what``; None
    when every value lies inside it. Every loader and command that carries a c2 asks this."""
    low, high = (float(v) for v in damping_range)
    try:
        array = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        return f"{what}: c2 must be numbers [N s/m]"
    bad = array[~((array >= low) & (array <= high))]  # NaN fails both comparisons
    if bad.size == 0:
        return None
    return (f"{what}: {float(bad[0]):g} N s/m lies outside the damper's range "
            f"[{low:g}, {high:g}] N s/m" + (f" ({bad.size} values)" if bad.size > 1 else ""))


def check_damping(values, what: str, damping_range=DAMPER_RANGE, error=ValueError) -> None:
    """Raise ``error`` with :func:`damping_problem`'s line when it finds one."""
    problem = damping_problem(values, what, damping_range)
    if problem is not None:
        raise error(problem)


class DamperStatus(enum.IntEnum):
    """Status codes, equal to ``dva_msgs/DamperState.STATUS_*``."""

    OK = 0
    SATURATED = 1
    FALLBACK_STALE = 2
    REJECTED = 3
    NO_COMMAND = 4


class DamperMode(enum.IntEnum):
    """Who sets c2, equal to ``dva_msgs/DamperState.MODE_*``."""

    CONSTANT = 0  # c2 held (a command, the start-up or the fallback value)
    SWITCHING = 1  # a per-sample law sets c2 every sample (the source says which)
    SWITCHING_REFUSED = 2  # the law was asked for but cannot run: the command's c2 is held


class Rejection(str, enum.Enum):
    """Why a command was rejected."""

    NOT_A_NUMBER = "not_a_number"
    INFINITE = "infinite"
    NEGATIVE = "negative"
    ABSURD = "absurd"


def _real(value, name: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    return float(value)


@dataclass(frozen=True)
class DamperConfig:
    """Damper limits and behaviour.

    Attributes
    ----------
    min_damping, max_damping : float
        [N s/m] range of c2, ``0 <= min_damping < max_damping``.
    fallback_damping : float
        [N s/m] c2 applied when commands go stale; inside the range.
    initial_damping : float or None
        [N s/m] c2 applied before the first accepted command; None means ``fallback_damping``.
    stale_timeout : float
        [s] longest sim time without an accepted command before the fallback applies
        (``math.inf`` disables the fallback).
    time_constant : float
        [s] first-order lag of the damper; 0 is the study's ideal damper.
    absurd_factor : float
        Commands above ``absurd_factor * max_damping`` are rejected rather than saturated.
    """

    min_damping: float
    max_damping: float
    fallback_damping: float
    initial_damping: float | None = None
    stale_timeout: float = DEFAULT_STALE_TIMEOUT
    time_constant: float = 0.0
    absurd_factor: float = 10.0

    def __post_init__(self):
        lo = _real(self.min_damping, "min_damping")
        hi = _real(self.max_damping, "max_damping")
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0.0 or hi <= lo:
            raise ValueError(
                f"need 0 <= min_damping < max_damping (finite), got ({lo}, {hi}) N s/m"
            )
        fallback = _real(self.fallback_damping, "fallback_damping")
        initial = (
            fallback
            if self.initial_damping is None
            else _real(self.initial_damping, "initial_damping")
        )
        for name, value in (("fallback_damping", fallback), ("initial_damping", initial)):
            if not lo <= value <= hi:
                raise ValueError(f"{name} must lie in [{lo}, {hi}] N s/m, got {value}")
        timeout = _real(self.stale_timeout, "stale_timeout")
        if not timeout > 0.0:
            raise ValueError(f"stale_timeout must be > 0 s (inf disables), got {timeout}")
        tau = _real(self.time_constant, "time_constant")
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ValueError(f"time_constant must be finite and >= 0 s, got {tau}")
        factor = _real(self.absurd_factor, "absurd_factor")
        if not (math.isfinite(factor) and factor >= 1.0):
            raise ValueError(f"absurd_factor must be finite and >= 1, got {factor}")
        for name, value in (
            ("min_damping", lo),
            ("max_damping", hi),
            ("fallback_damping", fallback),
            ("initial_damping", initial),
            ("stale_timeout", timeout),
            ("time_constant", tau),
            ("absurd_factor", factor),
        ):
            object.__setattr__(self, name, value)

    @property
    def absurd_limit(self) -> float:
        """[N s/m] commands above this are rejected."""
        return self.absurd_factor * self.max_damping

    @property
    def damping_range(self) -> tuple[float, float]:
        """[N s/m] ``(min_damping, max_damping)``."""
        return self.min_damping, self.max_damping

    def range_problem(self, values, what: str) -> str | None:
        """:func:`damping_problem` against this damper's range."""
        return damping_problem(values, what, self.damping_range)


@dataclass(frozen=True)
class CommandResult:
    """What happened to one command.

    Attributes
    ----------
    accepted : bool
        Whether the command became the damper's target.
    rejection : Rejection or None
        Why it was rejected.
    saturated : bool
        Whether it was clipped to the damper's range.
    target : float
        [N s/m] the damper's target after the command.
    """

    accepted: bool
    rejection: Rejection | None
    saturated: bool
    target: float


@dataclass(frozen=True)
class DamperSnapshot:
    """The damper's state, field for field ``dva_msgs/DamperState`` plus the time.

    Attributes
    ----------
    time : float
        [s] sim time of the snapshot (the message's header stamp).
    commanded_damping : float
        [N s/m] last received command, accepted or not (NaN if none).
    applied_damping : float
        [N s/m] c2 acting in the model now.
    min_damping, max_damping : float
        [N s/m] the damper's range.
    command_age : float
        [s] sim time since the last accepted command (inf if none).
    status : DamperStatus
        See :class:`DamperStatus`; precedence FALLBACK_STALE, REJECTED, NO_COMMAND, SATURATED, OK.
    source : str
        Source of the last accepted command, or "fallback" / "initial".
    rejection : Rejection or None
        Reason for the latest command's rejection, if it was rejected.
    mode : DamperMode
        Who set c2 over the last block.
    switching_rate : float
        [1/s] changes of the law's target per second over the last block (0 unless switching).
    """

    time: float
    commanded_damping: float
    applied_damping: float
    min_damping: float
    max_damping: float
    command_age: float
    status: DamperStatus
    source: str
    rejection: Rejection | None
    mode: DamperMode = DamperMode.CONSTANT
    switching_rate: float = 0.0


class DamperModel:
    """Validated, saturated, optionally lagged damper with a stale-command fallback.

    Parameters
    ----------
    config : DamperConfig
        Limits and behaviour.
    start_time : float
        [s] sim time at which the model starts (applied c2 = ``initial_damping``).
    """

    def __init__(self, config: DamperConfig, start_time: float = 0.0):
        if not isinstance(config, DamperConfig):
            raise TypeError(f"config must be a DamperConfig, got {type(config).__name__}")
        start = _real(start_time, "start_time")
        if not math.isfinite(start):
            raise ValueError(f"start_time must be finite, got {start}")
        self.config = config
        self._time = start
        self._applied = config.initial_damping
        self._commanded = math.nan
        self._accepted_time: float | None = None
        self._accepted_value = math.nan  # after clipping
        self._accepted_source = ""
        self._accepted_saturated = False
        self._last_rejection: Rejection | None = None
        self._mode = DamperMode.CONSTANT
        self._switching_rate = 0.0

    @property
    def source_in_force(self) -> str | None:
        """The source of the command in force (accepted, not stale), or None: the flight
        runs a per-sample law when it has one for this source."""
        if self._accepted_time is None or self._is_stale():
            return None
        return self._accepted_source

    def record_mode(self, mode: DamperMode, switching_rate: float = 0.0,
                    applied: float | None = None) -> None:
        """What the damper did over the block that ended at the model's time: ``mode``, the
        law's ``switching_rate`` [1/s] and, after the law ran, the c2 its lag reached (the
        constant path's lag goes on from there)."""
        self._mode = DamperMode(mode)
        self._switching_rate = float(switching_rate)
        if applied is not None:
            problem = self.config.range_problem(applied, "the per-sample law's c2")
            if problem is not None:  # the flight refuses such a law before it runs
                raise RuntimeError(problem)
            self._applied = float(applied)

    @property
    def time(self) -> float:
        """[s] sim time the model has been advanced to."""
        return self._time

    @property
    def applied_damping(self) -> float:
        """[N s/m] c2 acting now."""
        return self._applied

    def _stale_at(self) -> float:
        """Sim time after which the last accepted command is stale (inf if never)."""
        if self._accepted_time is None:
            return math.inf
        return self._accepted_time + self.config.stale_timeout

    def _is_stale(self) -> bool:
        return self._time > self._stale_at()

    def _target(self) -> float:
        if self._accepted_time is None:
            return self.config.initial_damping
        if self._is_stale():
            return self.config.fallback_damping
        return self._accepted_value

    def _check_time(self, time) -> float:
        t = _real(time, "time")
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {t}")
        if t < self._time:
            raise ValueError(f"time must not go backwards: {t} s < {self._time} s")
        return t

    def _relax(self, until: float) -> None:
        # Callers split intervals at the stale instant, so the target at the end of the
        # interval is the target throughout it.
        dt = until - self._time
        self._time = until
        target = self._target()
        tau = self.config.time_constant
        if tau == 0.0:
            self._applied = target
        elif dt > 0.0:
            self._applied = target + (self._applied - target) * math.exp(-dt / tau)

    def update(self, time: float) -> float:
        """Advance to sim time ``time`` and return the applied c2 [N s/m].

        The target switches to the fallback exactly when the last accepted command becomes
        stale, so the lag sees the switch at the right instant.
        """
        t = self._check_time(time)
        stale_at = self._stale_at()
        if self._time < stale_at < t:
            self._relax(stale_at)
        self._relax(t)
        return self._applied

    def command(self, damping, time: float, source: str = "") -> CommandResult:
        """Receive a command at sim time ``time``.

        Parameters
        ----------
        damping : float
            [N s/m] commanded c2.
        time : float
            [s] sim time of reception (not earlier than the model's time).
        source : str
            Which controller sent it (``DamperCommand.source``).

        Returns
        -------
        CommandResult
        """
        value = _real(damping, "damping")
        if not isinstance(source, str):
            raise TypeError(f"source must be a string, got {type(source).__name__}")
        self.update(time)
        self._commanded = value
        if math.isnan(value):
            rejection = Rejection.NOT_A_NUMBER
        elif math.isinf(value):
            rejection = Rejection.INFINITE
        elif value < 0.0:
            rejection = Rejection.NEGATIVE
        elif value > self.config.absurd_limit:
            rejection = Rejection.ABSURD
        else:
            rejection = None
        self._last_rejection = rejection
        if rejection is not None:
            return CommandResult(False, rejection, False, self._target())
        clipped = min(max(value, self.config.min_damping), self.config.max_damping)
        self._accepted_time = self._time
        self._accepted_value = clipped
        # echoed in every damper state from here on: outside text, escaped and cut (a 10 MB
        # source would otherwise fill each state, and the bag, with it)
        self._accepted_source = loggable(source)
        self._accepted_saturated = clipped != value
        if self.config.time_constant == 0.0:
            self._applied = clipped
        return CommandResult(True, None, self._accepted_saturated, clipped)

    def snapshot(self) -> DamperSnapshot:
        """The state at the model's current time (see :class:`DamperSnapshot`)."""
        if self._accepted_time is None:
            age = math.inf
        else:
            age = self._time - self._accepted_time
        if self._is_stale():
            status, source = DamperStatus.FALLBACK_STALE, "fallback"
        elif self._last_rejection is not None:
            status = DamperStatus.REJECTED
            source = "initial" if self._accepted_time is None else self._accepted_source
        elif self._accepted_time is None:
            status, source = DamperStatus.NO_COMMAND, "initial"
        elif self._accepted_saturated:
            status, source = DamperStatus.SATURATED, self._accepted_source
        else:
            status, source = DamperStatus.OK, self._accepted_source
        return DamperSnapshot(
            time=self._time,
            commanded_damping=self._commanded,
            applied_damping=self._applied,
            min_damping=self.config.min_damping,
            max_damping=self.config.max_damping,
            command_age=age,
            status=status,
            source=source,
            rejection=self._last_rejection,
            mode=self._mode,
            switching_rate=self._switching_rate,
        )
