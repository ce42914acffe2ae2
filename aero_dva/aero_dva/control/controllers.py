"""The controllers of the damper's c2, in one table that every tool reads (no ROS).

One :class:`Controller` entry per controller says who it is (name, label, the
``dva_msgs/DamperCommand`` source of its commands), where it runs, which law it runs and what
that law reads, its default command lag, its options and what a flight summary expects of it.
``run_flight`` starts a controller's nodes from its entry, ``dva replay`` re-runs its law,
``dva evaluate`` flies it (in process, on Ray, ``--graph``), ``dva report`` names it from its
commands' source, and the docs list it (docs/control.md, "Adding a control law").

Where a controller runs (:attr:`Controller.runs`):

- :data:`BLOCK`: at block rate, in a controller node: ``dva_controller``'s generic node hosts
  the entry's law by name (``ros2 run dva_controller controller NAME``; the built-in laws keep
  their own executables, ``fixed_controller`` and the like, as aliases of it); in process, the
  evaluation hands the law what the node would receive;
- :data:`SAMPLE`: every sample, in the simulator's damper path; a supervising node arms it
  with commands of the entry's source (:mod:`aero_dva.flight.per_sample`);
- :data:`REFERENCE`: in the in-process evaluation only: it reads what no sensor measures.

A block-rate law is an object with ``answer(kind, stamp_ns, value) -> LawStep`` for each input
it reads (:data:`TICK`: its node's timer; :data:`CONDITION`: a flight condition;
:data:`SPECTRUM`: a scaled spectrum; :data:`TRUTH`: the true airspeed and density ahead), made
by the entry's ``law`` factory from its parameter values. Optional: ``set(name, value)`` for a
parameter that may change at run time, ``status(last_command)`` for its node's periodic
diagnostics, ``describe()`` for its start-up line, ``counters`` (extra counts it reports).

Other Python packages add controllers through the entry-point group :data:`ENTRY_POINT_GROUP`
(as ros2cli takes verbs from its group): each entry point names a :class:`Controller`.
"""
from __future__ import annotations

import importlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from typing import TYPE_CHECKING

# The table imports named values only, never the numerics: every node's --help, run_flight's
# and the controller node's start read it (docs/performance.md, the start-up budget).
from aero_dva.control.law_defaults import FALLBACK_SOURCE, STUDY_BAND, WINDOW_FUNCTIONS
from aero_dva.flight.flight_limits import DAMPER_RANGE, MAX_DAMPING, SWITCHING_SOURCE
from aero_dva.input_ranges import MAX_AIRSPEED, SCHEDULE
from aero_dva.wing.channel_names import ACCELERATION_NAMES

if TYPE_CHECKING:
    import numpy as np

__all__ = ["BLOCK", "CONDITION", "ENTRY_POINT_GROUP", "NONE", "REFERENCE", "SAMPLE",
           "SPECTRUM", "TICK", "TRUTH", "Condition", "Controller", "LawParam", "LawStep",
           "Option", "SpectrumInput", "by_source", "controller", "controllers",
           "expected_commands", "names"]

BLOCK, SAMPLE, REFERENCE = "block", "sample", "reference"
#: ``--controller none``: nothing commands c2 (the damper holds its start-up value).
NONE = "none"
NONE_LABEL = "no DVA"
#: Entry-point group of controllers from other packages (each names a :class:`Controller`).
ENTRY_POINT_GROUP = "aero_dva.controllers"

# What a law reads. The topics that carry them are ``aero_dva.bag.channels.LAW_INPUTS``.
TICK = "tick"  # its node's timer, at the law's parameter ``rate`` [Hz]
CONDITION = "condition"  # flight/condition: Condition
SPECTRUM = "spectrum"  # dva/spectrum (made by the spectrum node): SpectrumInput
DISPLACEMENT = "displacement"  # wing/displacement (a per-sample law's supervisor)
DAMPER_STATE = "damper_state"  # dva/damper_state (a per-sample law's supervisor)
ACCELERATION = "acceleration"  # wing/acceleration (what the spectrum node reads)
TRUTH = "truth"  # in process only: (airspeed, density) where the command will act
#: Inputs another node of the graph makes: that node (dva_controller) and what it reads.
MADE_BY = {SPECTRUM: ("spectrum", (ACCELERATION, DAMPER_STATE))}


@dataclass(frozen=True)
class Condition:
    """A flight condition as a law reads it: airspeed [m/s], air density [kg/m^3]."""

    airspeed: float
    density: float


@dataclass(frozen=True)
class SpectrumInput:
    """The content of one ``dva_msgs/ScaledSpectrum`` as a law reads it.

    Attributes
    ----------
    stamp_ns : int
        [ns] time of the last sample in the window.
    channel_names : tuple of str
    frequencies : ndarray, shape (n_freq,)
        [Hz]
    magnitudes : ndarray, shape (channels, n_freq)
        [1] scaled magnitudes (eq. 7.3).
    window_duration : float
        [s]
    window_function, scaling : str
    damping : float
        [N s/m] c2 during the window (may be NaN).
    """

    stamp_ns: int
    channel_names: tuple[str, ...]
    frequencies: np.ndarray
    magnitudes: np.ndarray
    window_duration: float
    window_function: str
    scaling: str
    damping: float


@dataclass(frozen=True)
class LawStep:
    """What a law did with one input: ``kind`` "command" (``damping`` [N s/m] set),
    "rejected" (``reason`` says why; the node reports it), or another word its node counts
    (e.g. "rate_limited") or "" (nothing to say). ``values``: what a report of it carries;
    ``counted``: more of the law's counters this input adds to."""

    kind: str
    damping: float = math.nan
    reason: str = ""
    values: Mapping = field(default_factory=dict)
    counted: tuple[str, ...] = ()

    @classmethod
    def command(cls, damping: float, **kw) -> LawStep:
        return cls("command", float(damping), **kw)


@dataclass(frozen=True)
class LawParam:
    """A parameter of a law: its node declares it (``--help`` prints it) and the offline tools
    fill it in. The fields are those of ``dva_ros_common.node_params.Param``."""

    name: str
    default: object
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    nan_means: str = ""
    default_text: str = ""
    dynamic: bool = False
    needs: str = ""
    excludes: str = ""


@dataclass(frozen=True)
class Option:
    """A controller's option of ``run_flight`` and ``dva replay`` (``--NAME``) and the
    parameter of its node it sets.

    ``kind``: "file" or "number"; ``required``: it cannot fly without it; ``simulator``: the
    simulator's parameter it sets too (a per-sample law's file); ``default_file``: the
    package data file used when it is not given."""

    name: str
    param: str
    help: str
    kind: str = "file"
    required: bool = False
    simulator: str = ""
    default_file: str = ""


@dataclass(frozen=True)
class Controller:
    """One controller of c2 (module docstring).

    Attributes
    ----------
    name : str
        ``--controller NAME``.
    label : str
        Its name in tables and plots.
    source : str
        ``dva_msgs/DamperCommand.source`` of its commands (``sources``: others it sends).
    runs : str
        :data:`BLOCK`, :data:`SAMPLE` or :data:`REFERENCE`.
    law : str
        ``"module:callable"``: called with the parameter values (a mapping) it returns the law
        (:data:`BLOCK`, :data:`REFERENCE`), or (:data:`SAMPLE`) loads the law the damper runs.
    inputs : tuple of str
        What its node reads (:data:`TICK`, :data:`CONDITION`, ...); the first is the input
        each command answers, what a flight summary counts commands against
        (:func:`expected_commands`).
    command_lag : float
        [s] ``run_flight``'s default ``--max-command-lag``: how far the flight may run ahead
        of the newest command's input.
    summary : str
        What its node does (the node's ``--help``).
    params : tuple of LawParam
        Its law's parameters (its node adds its own after them).
    options : tuple of Option
    flight_values : mapping
        Parameters ``run_flight`` sets on its node (the fixed controller's 20 Hz).
    damper_lag : float or None
        [s] a per-sample law's damper lag as designed (``run_flight``'s default).
    sensor_noise : float
        A per-sample law's sensor noise as designed: std of the noise on its observer's
        measurements as a fraction of each one's RMS at U_cr (the simulator's
        ``damper_sensor_noise``; ``run_flight``'s and ``dva evaluate``'s default).
    node : str
        Its node's name and executable (default ``NAME_controller``).
    sources : tuple of str
        Other ``DamperCommand.source`` values its nodes send.
    study_ratios : mapping
        The study's single flights of it, U_div / U_cr by the density variation mu (the
        ``dva evaluate --graph`` table shows them beside the flown ones).
    origin : str
        "" for the project's own, else the distribution that registered it.
    """

    name: str
    label: str
    source: str
    runs: str
    law: str
    inputs: tuple[str, ...]
    command_lag: float
    summary: str
    params: tuple[LawParam, ...] = ()
    options: tuple[Option, ...] = ()
    flight_values: Mapping = field(default_factory=dict)
    damper_lag: float | None = None
    sensor_noise: float = 0.0
    node: str = ""
    sources: tuple[str, ...] = ()
    study_ratios: Mapping = field(default_factory=dict)
    origin: str = ""

    def __post_init__(self):
        if not self.name.isidentifier() or self.name == NONE:
            raise ValueError(f"controller name {self.name!r} must be an identifier, not "
                             f"{NONE!r}")
        if self.runs not in (BLOCK, SAMPLE, REFERENCE):
            raise ValueError(f"controller {self.name!r}: runs must be {BLOCK!r}, {SAMPLE!r} "
                             f"or {REFERENCE!r}, got {self.runs!r}")
        known = (TICK, CONDITION, SPECTRUM, DISPLACEMENT, DAMPER_STATE, TRUTH)
        unknown = [k for k in self.inputs if k not in known]
        if unknown or not self.inputs:
            raise ValueError(f"controller {self.name!r}: inputs must be some of {known}, got "
                             f"{self.inputs!r}")
        if TRUTH in self.inputs and self.runs != REFERENCE:
            raise ValueError(f"controller {self.name!r}: only a reference reads the truth")
        if TICK in self.inputs and "rate" not in {p.name for p in self.params}:
            raise ValueError(f"controller {self.name!r} reads its timer: it needs a 'rate' "
                             "parameter")
        if not (math.isfinite(self.command_lag) and self.command_lag >= 0):
            raise ValueError(f"controller {self.name!r}: command_lag must be >= 0 s")
        object.__setattr__(self, "node", self.node or f"{self.name}_controller")

    @property
    def node_reads(self) -> tuple[str, ...]:
        """The simulator's outputs this controller's nodes read (the simulator waits for
        them before its first block)."""
        out = []
        for kind in self.inputs:
            out += MADE_BY[kind][1] if kind in MADE_BY else [kind]
        return tuple(k for k in dict.fromkeys(out) if k not in (TICK, TRUTH))

    @property
    def helpers(self) -> tuple[str, ...]:
        """Other nodes its graph needs (the spectrum node for a law of spectra)."""
        return tuple(MADE_BY[k][0] for k in self.inputs if k in MADE_BY)

    @property
    def shared_commands(self) -> bool:
        """Its commands depend on time and the flight condition only, the same for every
        flight of a case (the evaluation flies those of many seeds at once)."""
        return set(self.inputs) <= {TICK, CONDITION, TRUTH}

    def option(self, name: str) -> Option | None:
        return next((o for o in self.options if o.name == name), None)

    def defaults(self) -> dict:
        """Its law's parameters at their defaults."""
        return {p.name: p.default for p in self.params}

    def make_law(self, values: Mapping | None = None):
        """The law, from its parameters (``values`` over the defaults). Raises ValueError for a
        bad value or file (naming it)."""
        return load_callable(self.law)({**self.defaults(), **dict(values or {})})


# -- the project's controllers ------------------------------------------------------------------

#: damping_min, damping_max: the damper's range, which a law clamps its commands to.
DAMPER_RANGE_PARAMS = (
    LawParam("damping_min", DAMPER_RANGE[0], "damper range, lower end; commands are clamped to "
             "it", "N s/m", 0.0, MAX_DAMPING),
    LawParam("damping_max", DAMPER_RANGE[1], "damper range, upper end (the simulator's default "
             "range)", "N s/m", 0.0, MAX_DAMPING),
)
#: channels, frequencies, window, window_duration of the eq. 7.3 spectra (the spectrum node
#: makes them; a law of spectra checks it reads what it was made for).
SPECTRUM_SHAPE = (
    LawParam("channels", ["plunge", "pitch"], "acceleration channels of the spectra, in order",
             choices=ACCELERATION_NAMES),
    LawParam("frequencies", list(STUDY_BAND),
             "frequencies of the spectra: distinct, below the blocks' Nyquist frequency", "Hz",
             low=1.0e-2, high=1.0e4, default_text=f"{STUDY_BAND[0]:g}, "
             f"{STUDY_BAND[1]:g}, ..., {STUDY_BAND[-1]:g} "
             f"({STUDY_BAND[1] - STUDY_BAND[0]:g} Hz steps)"),
    LawParam("window", "rectangular", "window function (rectangular: the study's)",
             choices=tuple(WINDOW_FUNCTIONS)),
    LawParam("window_duration", 2.0,
             "window length; times the blocks' sample rate a whole number of samples", "s",
             1.0e-3, 3600.0),
)

#: The parameters a per-sample law's supervisor has besides its gains file.
SUPERVISOR_PARAMS = (
    LawParam("wing", "", "wing YAML the gains must be made for",
             default_text="the package's chapter-6 wing"),
    LawParam("safe_damping", 624.7, "constant c2 held when the law is not armed (the "
             "best constant c2 of the chapter-6 wing)", "N s/m", 0.0, MAX_DAMPING),
    LawParam("peak_limit", 0.013, "leading-edge displacement that counts as a burst "
             "(20x the fixed damper's RMS at 0.8 U_cr, docs/switching.md)", "m", 1.0e-9,
             1.0e3),
    LawParam("rearm_after", 2.0, "sim time after a burst's last sample before the law "
             "is armed again", "s", 0.0, 1.0e12),
    LawParam("rate", 20.0, "command rate, in ROS time (sim time with use_sim_time)",
             "Hz", 0.01, 1000.0),
)

#: [N s/m] The best constant c2 of the default (chapter-6) wing: the constant c2 with the highest
#: flutter airspeed (``dva_offline.evaluation.inputs.best_fixed_damping_of``: 624.71; a test
#: checks the rounding), the fixed controller's default.
BEST_FIXED_DAMPING = 624.7

BUILTIN = (
    Controller(
        name="fixed", label="best fixed c2", source="fixed", runs=BLOCK,
        law="aero_dva.control.command_laws:fixed_law", inputs=(TICK,),
        # the 20 Hz period of run_flight's timer
        command_lag=0.1, node="fixed_controller",
        summary="Publish a constant damper command c2: the fixed-c2 baseline of chapter 7 of "
                "Zhang (2006).",
        params=(
            LawParam("damping", BEST_FIXED_DAMPING, "c2 to command; the default is the best "
                     "constant c2 of the default (chapter-6) wing, the c2 with the highest "
                     "flutter airspeed (115.05 m/s = 1.1505 U_cr), which dva evaluate's fixed "
                     "controller flies (the simulator's start-up and fallback c2 is the wing "
                     "file's design c2, 500 N s/m, the DVA as designed without control)", "N s/m",
                     0.0, MAX_DAMPING, dynamic=True),
            LawParam("rate", 20.0, "publishing rate, in ROS time (sim time with "
                     "use_sim_time); run_flight's", "Hz", 0.01, 1000.0),
        ),
        options=(Option("damping", "damping", "c2 [N s/m] of the fixed controller", "number"),),
        flight_values={"rate": 20.0}),
    Controller(
        name="schedule", label="airspeed schedule", source="airspeed_schedule", runs=BLOCK,
        law="aero_dva.control.command_laws:schedule_law", inputs=(CONDITION,),
        # one 50 ms block: the schedule answers each flight condition
        command_lag=0.05, node="airspeed_controller",
        summary="Command c2 from the measured airspeed with the linear schedule c2 = a0 + a1 U "
                "(eq. 7.1 of Zhang (2006)): one command per accepted flight condition, clamped "
                "to the damper's range. NaN, infinite, negative or too large airspeeds are "
                "ignored and reported on /diagnostics.",
        params=(
            LawParam("a0", -2150.0, "eq. 7.1 intercept (used when schedule_file is empty)",
                     "N s/m", SCHEDULE["a0"].low, SCHEDULE["a0"].high,
                     excludes="schedule_file"),
            LawParam("a1", 31.5, "eq. 7.1 slope (used when schedule_file is empty)",
                     "N s^2/m^2", SCHEDULE["a1"].low, SCHEDULE["a1"].high,
                     excludes="schedule_file"),
            LawParam("schedule_file", "", "JSON airspeed schedule (dva control schedule); when "
                     "set, its a0, a1 and ranges replace the parameters",
                     default_text="'' (use a0, a1)"),
            LawParam("extrapolate", True, "continue the schedule file's line outside its "
                     "fitted airspeeds (false: hold the end values)", needs="schedule_file"),
            *DAMPER_RANGE_PARAMS,
            LawParam("min_period", 0.0, "least ROS time between two commands (0: one per "
                     "flight condition)", "s", 0.0, 3600.0),
            LawParam("max_airspeed", MAX_AIRSPEED, "larger airspeeds are treated as sensor or "
                     "unit errors and ignored", "m/s", 1.0, 1.0e4),
        ),
        options=(Option("schedule", "schedule_file", "airspeed schedule JSON", required=True),),
        study_ratios={0.0: 1.17, 0.05: 1.11, 0.1: 1.04}),  # fig. 7.5-7.7
    Controller(
        name="rbf", label="RBF network", source="rbf_network", runs=BLOCK,
        law="aero_dva.control.command_laws:rbf_law", inputs=(SPECTRUM,),
        # one 0.1 s spectrum hop plus a block
        command_lag=0.15, node="rbf_controller",
        summary="Command c2 from each scaled vibration spectrum with a trained RBF network "
                "(section 7.2 of Zhang (2006)). The spectra's shape below must be the one the "
                "network was trained on (the file's input names are checked at start-up); "
                "commands are clamped to the damper's range.",
        params=(
            LawParam("network_file", "", "trained RBF network (.npz, dva train rbf); required",
                     default_text="none (required)"),
            *SPECTRUM_SHAPE,
            *DAMPER_RANGE_PARAMS,
        ),
        options=(Option("network", "network_file", "RBF network .npz", required=True),),
        study_ratios={0.0: 1.16, 0.05: 1.13, 0.1: 1.11}),  # fig. 7.13, 7.15, 7.16
    Controller(
        name="switching", label="switching law", source=SWITCHING_SOURCE, runs=SAMPLE,
        sources=(FALLBACK_SOURCE,),
        law="aero_dva.control.switching_io:supervised_law",
        inputs=(TICK, DISPLACEMENT, DAMPER_STATE),
        # the 20 Hz period of its supervisor's commands
        command_lag=0.1, damper_lag=0.01, sensor_noise=0.05, node="switching_controller",
        summary="Supervise the per-sample switching c2 law that runs in the damper's own "
                "controller (the simulator's damper path): arm it, or hold a safe constant c2 "
                "on an invalid gains file or after a burst (leading edge beyond peak_limit), "
                "and say why. When this node falls silent the damper's stale-command fallback "
                "ends the law.",
        params=(
            LawParam("gains_file", "", "switching gains JSON (dva switching design)",
                     default_text="the package's switching_gains.json"),
            *SUPERVISOR_PARAMS,
        ),
        options=(
            Option("gains", "gains_file", "switching gains JSON (default: the package's "
                   "switching_gains.json)", simulator="switching_gains",
                   default_file="switching_gains.json"),
            Option("damping", "safe_damping", "the safe constant c2 [N s/m] of the switching "
                   "law", "number"),
        ),
        flight_values={"rate": 20.0}),
    Controller(
        name="clipped_optimal", label="clipped-optimal law", source="clipped_optimal",
        runs=SAMPLE, sources=("clipped_optimal_fallback",),
        law="aero_dva.control.switching_io:clipped_optimal_law",
        inputs=(TICK, DISPLACEMENT, DAMPER_STATE),
        # the 20 Hz period of its supervisor's commands
        command_lag=0.1, damper_lag=0.01, sensor_noise=0.05,
        summary="Supervise the clipped-optimal law of Dyke et al. (1996), scheduled with the "
                "airspeed, that runs per sample in the damper's own controller (the "
                "simulator's damper path; docs/clipped_optimal.md): arm it, or hold a safe "
                "constant c2 on an invalid gains file or after a burst (leading edge beyond "
                "peak_limit), and say why. When this node falls silent the damper's "
                "stale-command fallback ends the law.",
        params=(
            LawParam("gains_file", "", "clipped-optimal gains JSON (dva switching design "
                     "--design clipped_optimal)",
                     default_text="the package's clipped_optimal_gains.json"),
            *SUPERVISOR_PARAMS,
        ),
        options=(
            Option("gains", "gains_file", "clipped-optimal gains JSON (default: the package's "
                   "clipped_optimal_gains.json)", simulator="clipped_optimal_gains",
                   default_file="clipped_optimal_gains.json"),
            Option("damping", "safe_damping", "the safe constant c2 [N s/m] of the "
                   "clipped-optimal law", "number"),
        ),
        flight_values={"rate": 20.0}),
    Controller(
        name="oracle", label="oracle c2*(U, rho)", source="oracle", runs=REFERENCE,
        law="aero_dva.control.oracle:oracle_law", inputs=(TRUTH,), command_lag=0.0,
        summary="c2*(U, rho), the exact stationary RMS optimum at the true airspeed and density "
                "of the block a command acts on: the upper bound no measurement-based "
                "controller can beat (in process only)."),
)


def load_callable(text: str):
    """The callable of a ``"module:attribute"`` reference."""
    module, _, attribute = text.partition(":")
    return getattr(importlib.import_module(module), attribute)


@cache
def _table() -> tuple[tuple[Controller, ...], tuple[str, ...]]:
    """The project's controllers and those of the entry-point group, and what could not be
    loaded (one line each)."""
    from importlib.metadata import entry_points

    table = {c.name: c for c in BUILTIN}
    problems = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        origin = ep.dist.name if ep.dist is not None else ep.value
        try:
            entry = ep.load()
            if not isinstance(entry, Controller):
                raise TypeError(f"{ep.value} is a {type(entry).__name__}, not a Controller")
        except Exception as exc:  # a broken plug-in must not take the project's own down
            problems.append(f"controller {ep.name!r} of {origin}: {exc}")
            continue
        if entry.name in table:
            problems.append(f"controller {entry.name!r} of {origin}: the name is taken")
            continue
        table[entry.name] = Controller(**{**entry.__dict__, "origin": origin})
    return tuple(table.values()), tuple(problems)


def controllers(runs: tuple[str, ...] = (BLOCK, SAMPLE, REFERENCE),
                builtin_only: bool = False) -> tuple[Controller, ...]:
    """Every controller (the project's first, in table order), or those that run as
    ``runs``."""
    return tuple(c for c in _table()[0] if c.runs in runs and not (builtin_only and c.origin))


def load_problems() -> tuple[str, ...]:
    """Why a registered controller could not be loaded (one line each; empty: none)."""
    return _table()[1]


def names(runs: tuple[str, ...] = (BLOCK, SAMPLE, REFERENCE),
          builtin_only: bool = False) -> tuple[str, ...]:
    return tuple(c.name for c in controllers(runs, builtin_only))


def controller(name: str) -> Controller:
    """The entry of ``name``; ValueError naming the known ones if there is none."""
    for entry in BUILTIN:  # the project's own first: no other package's can take their names
        if entry.name == name:
            return entry
    for entry in _table()[0]:
        if entry.name == name:
            return entry
    problems = "".join(f"; {p}" for p in load_problems())
    raise ValueError(f"unknown controller {name!r}: known are {', '.join(names())}"
                     f"{problems}")


def by_node(node: str) -> Controller | None:
    """The entry whose node (executable) is ``node``, or None (the project's own looked at
    first, without reading the other packages' entry points)."""
    return next((c for c in BUILTIN if c.node == node), None) or \
        next((c for c in _table()[0] if c.node == node), None)


def by_source(source: str) -> Controller | None:
    """The controller that sends commands of ``source``, or None."""
    return next((c for c in _table()[0] if source == c.source or source in c.sources), None)


def add_options(parser, entries) -> None:
    """``--OPTION`` of every controller in ``entries`` on an argparse ``parser``: one per
    name, its help saying whose (``run_flight``, ``replay_flight``, ``dva replay``)."""
    seen: dict[str, list] = {}
    for entry in entries:
        for option in entry.options:
            seen.setdefault(option.name, []).append((entry, option))
    for name, users in seen.items():
        number = users[0][1].kind == "number"
        inside = f", inside the damper's range {DAMPER_RANGE[0]:g}..{DAMPER_RANGE[1]:g}" \
            if number else ""
        parser.add_argument(f"--{name}", type=float if number else str, default=None,
                            metavar="C2" if number else "FILE",
                            help="; ".join(f"{o.help} (--controller {e.name})"
                                           for e, o in users) + inside)


def expected_commands(entry: Controller | None, blocks: int, block_duration: float,
                      spectra: int) -> int:
    """Commands the simulator should receive from ``entry``'s node over a flight of ``blocks``
    blocks, by the input each command answers: one per flight condition but the last (the
    answer to the last one comes after the flight), one per spectrum, one per period of its
    timer (at ``run_flight``'s rate); none without a controller."""
    if entry is None:
        return 0
    kind = entry.inputs[0]
    if kind == CONDITION:
        return max(blocks - 1, 0)
    if kind == SPECTRUM:
        return spectra
    if kind == TICK:
        return int(blocks * block_duration * flight_rate(entry) + 1e-9)
    return 0


def flight_rate(entry: Controller) -> float:
    """[Hz] its timer's rate in ``run_flight`` (its ``flight_values``, else the default)."""
    return float(entry.flight_values.get("rate", entry.defaults().get("rate", math.nan)))
