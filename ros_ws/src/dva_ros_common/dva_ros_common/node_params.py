"""One parameter table per node: the node declares its parameters from it and ``--help`` prints it.

A node module defines a :class:`NodeSpec` (name, package, what it does, its topics) holding a
tuple of :class:`Param` rows (name, default, unit, range or choices, description). The node's
constructor calls :func:`declare_parameters` with the table, and ``run_node`` prints
:func:`help_text` of the same table for ``-h``/``--help``, so the help cannot drift from what the
node declares. Nothing here needs an rclpy context: ``--help`` answers without starting ROS.

Ranges are checked when the node starts (one-line ``ValueError`` naming the parameter, exit 2):
for numbers through the parameter descriptor's range (so ``ros2 param describe`` shows it), for
parameters whose NaN means "take another value" by this module, for strings by ``choices``.
"""
from __future__ import annotations

import math
import sys
import textwrap
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from aero_dva import exits

HELP_WIDTH = 99
#: Parameters every rclpy node has; listed in the help, declared by rclpy itself.
ROS_STANDARD = (
    ("use_sim_time", "bool", "false", "follow /clock (sim time) instead of the wall clock; "
     "true in run_flight's graph and config/graph.yaml"),
)


@dataclass(frozen=True)
class Param:
    """One row of a node's parameter table.

    Attributes
    ----------
    name : str
        Parameter name.
    default : bool, int, float, str or list
        Default value; its type is the parameter's type (a list of str: string array, of
        float: double array; an empty string array is declared as ``[""]``, as rcl needs a
        typed value).
    description : str
        What it does, without the unit (one short sentence).
    unit : str
        SI unit ("s", "N s/m", "Hz", ...), "" for none.
    low, high : float, optional
        Inclusive range of a number (or of every element of a double array).
    choices : tuple of str
        Allowed values of a string (or of every element of a string array).
    nan_means : str
        If set, NaN is allowed and means this (e.g. "the wing file's value").
    default_text : str
        How the help shows the default when the value alone would not say it.
    dynamic : bool
        May change while the node runs (``ros2 param set``); others are read at start-up.
    needs, excludes : str
        Another parameter this one acts only with (set: not empty, not false, not zero) or
        only without; given a value other than its default against that, it is refused (never
        ignored).
    """

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

    @property
    def type_name(self) -> str:
        value = self.default
        if isinstance(value, bool):
            return "bool"
        if isinstance(value, int):
            return "int"
        if isinstance(value, float):
            return "float"
        if isinstance(value, str):
            return "string"
        if all(isinstance(v, str) for v in value):
            return "string array"
        return "double array"

    def constraints(self) -> list[str]:
        """The interval, the allowed choices and what NaN means, as short phrases."""
        parts = []
        if self.low is not None or self.high is not None:
            low = "-inf" if self.low is None else f"{self.low:g}"
            high = "inf" if self.high is None else f"{self.high:g}"
            parts.append(f"[{low}, {high}]")
        if self.choices:
            parts.append("one of " + ", ".join(self.choices))
        if self.nan_means:
            parts.append(f"NaN: {self.nan_means}")
        if self.needs:
            parts.append(f"only with {self.needs} set")
        if self.excludes:
            parts.append(f"not with {self.excludes} set")
        return parts

    def range_text(self) -> str:
        return "; ".join(self.constraints())

    def default_shown(self) -> str:
        if self.default_text:
            return self.default_text
        value = self.default
        if isinstance(value, bool):
            return str(value).lower()
        if isinstance(value, str):
            return repr(value)
        if isinstance(value, float):
            return "NaN" if math.isnan(value) else f"{value:g}"
        if isinstance(value, list):
            items = [v for v in value if v != ""]
            if not items:
                return "[] (none)"
            return "[" + ", ".join(f"{v:g}" if isinstance(v, float) else str(v)
                                   for v in items) + "]"
        return str(value)


@dataclass(frozen=True)
class NodeSpec:
    """What ``--help`` says about a node, and the table it declares its parameters from.

    Attributes
    ----------
    name : str
        Node name and executable name (``ros2 run <package> <name>``).
    package : str
        ROS package of the executable.
    summary : str
        What the node does (a few sentences; wrapped as written).
    params : tuple of Param
        The parameter table, in help order.
    topics : str
        What it subscribes and publishes (a few lines, as written).
    """

    name: str
    package: str
    summary: str
    params: tuple[Param, ...]
    topics: str = ""
    _by_name: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        by_name = {p.name: p for p in self.params}
        if len(by_name) != len(self.params):
            raise ValueError(f"node {self.name!r}: a parameter is listed twice")
        object.__setattr__(self, "_by_name", by_name)

    def __getitem__(self, name: str) -> Param:
        return self._by_name[name]

    @property
    def read_at_start(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params if not p.dynamic)


#: Keep-last depth of the writers of data a recorder must get whole (blocks, commands, spectra).
#: A reader whose process is starved can overflow its transport buffers; a reliable writer then
#: sends again only what is still in its history, and the rest is lost for good (the recorder
#: reports such losses). The simulator's 50 lasted 0.25 s at 10x real time and a loaded
#: recorder once missed one block on all five topics after a 0.29 s pause; the controllers'
#: 10 commands lasted 25 ms at 20x and a loaded recorder lost two (docs/reliability.md).
#: 1000 blocks last 5 s at 10x, about 2 MB per topic.
DATA_DEPTH = 1000  # (a table's default: here, before ROS is imported)

#: The rows of ``dva_ros_common.node_tools.InputHealth`` for a node's parameter table.
INPUT_HEALTH_PARAMS = (
    Param("stale_timeout", 1.0, "ROS time without input after which the status turns WARN", "s",
          1.0e-3, 3600.0),
    Param("diagnostic_period", 1.0, "ROS time between status reports on /diagnostics", "s",
          1.0e-2, 3600.0),
)
#: The row of a node's parameter table that sets ``dva_ros_common.held_publisher``'s gate.
HOLD_PARAM = Param(
    "hold_until_subscribers", 0, "hold the first outputs until the output topic has this many "
    "matched subscribers (run_flight: whoever must not miss them; 0: publish at once)", "",
    0, 1000)


def _wrap(text: str, indent: str, then: str | None = None) -> list[str]:
    return textwrap.wrap(text, HELP_WIDTH, initial_indent=indent,
                         subsequent_indent=indent if then is None else then,
                         break_on_hyphens=False)


def help_text(spec: NodeSpec) -> str:
    """The ``--help`` text of a node: usage, what it does, every parameter with its unit,
    default and range, its topics."""
    lines = [
        f"usage: ros2 run {spec.package} {spec.name} [-h]",
        "         [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] [-r FROM:=TO ...]]",
        "",
        *_wrap(spec.summary.strip(), ""),
        "",
        "parameters (set with --ros-args -p NAME:=VALUE, or --params-file FILE):",
    ]
    for p in spec.params:
        unit = f" [{p.unit}]" if p.unit else ""
        facts = [f"default {p.default_shown()}",
                 *(f"range {c}" if c.startswith("[") else c for c in p.constraints())]
        if p.dynamic:
            facts.append("can change at run time")
        lines += _wrap(f"{p.name} ({p.type_name}{unit}): {p.description}", "  ", " " * 6)
        lines += _wrap("; ".join(facts), " " * 6)
    for name, type_name, default, text in ROS_STANDARD:
        lines += _wrap(f"{name} ({type_name}): {text} (every node)", "  ", " " * 6)
        lines.append(f"      default {default}")
    if spec.topics:
        lines += ["", "topics:", *("  " + t.strip() for t in spec.topics.strip().splitlines())]
    lines += [
        "",
        "options:",
        "  -h, --help    print this help and exit (the node does not start)",
        "  Other arguments outside --ros-args are refused (exit code 2).",
        "",
        *_wrap(f"{exits.help_text()} {NODE_STOP}", ""),
    ]
    return "\n".join(lines) + "\n"


#: How a node's stop maps to the exit-code table.
NODE_STOP = ("SIGINT and SIGTERM stop a node cleanly: one that runs until it is stopped (the "
             "recorder, the controllers) then exits 0; one with a job of its own (the "
             "simulator's flight, the player's bag) exits 130 when stopped before the job is "
             "done.")


def command_line(spec: NodeSpec, argv: Sequence[str]) -> int | None:
    """Answer ``-h``/``--help`` (0) or refuse unknown non-ROS arguments (2); None: start the node.

    ``argv`` is the full command line (``sys.argv``: the program first). ROS arguments (after
    ``--ros-args``, up to ``--``) are left to rcl; only the rest is checked here. A ``-h`` or
    ``--help`` anywhere is help, answered before rclpy is imported.
    """
    if set(argv[1:]) & {"-h", "--help"}:
        sys.stdout.write(help_text(spec))
        return 0
    from rclpy.utilities import remove_ros_args  # parses; creates no context

    try:
        rest = remove_ros_args(list(argv))[1:]
    except Exception as exc:  # rclpy's UnknownROSArgsError / RCLInvalidROSArgsError
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if type(exc).__name__ == "UnknownROSArgsError":
            if "'-h'" in text or "'--help'" in text:  # e.g. `--ros-args --help`
                sys.stdout.write(help_text(spec))
                return 0
            text = f"unknown ROS arguments {text}"
        print(f"{spec.name}: error: {text} (see --help)", file=sys.stderr)
        return 2
    if rest:
        print(f"{spec.name}: error: unrecognized arguments: {' '.join(rest)} (node parameters "
              f"go after --ros-args as -p NAME:=VALUE; see --help)", file=sys.stderr)
        return 2
    return None


def node_main(spec: NodeSpec, node: str, args=None, node_args: tuple = (),
              **run_options) -> int:
    """The body of a node executable's ``main``: ``-h``/``--help`` and refused arguments are
    answered from ``spec`` before ROS, numpy or the node's module are imported (a node module
    keeps its table in a module of its own for this: docs/performance.md, the start-up
    budget); otherwise the node ``"module:Class"`` (built with ``node_args`` first) runs
    (:func:`dva_ros_common.node_tools.run_node` with ``args`` and ``run_options``)."""
    code = command_line(spec, sys.argv if args is None else args)
    if code is not None:
        return code
    import functools
    import importlib

    from dva_ros_common.node_tools import run_node

    module, _, name = node.partition(":")
    node_class = getattr(importlib.import_module(module), name)
    return run_node(functools.partial(node_class, *node_args), spec, args, **run_options)


def _descriptor(p: Param):
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
    )

    unit = f" [{p.unit}]" if p.unit else ""
    descriptor = ParameterDescriptor(description=p.description + unit,
                                     additional_constraints=p.range_text())
    numeric = p.type_name in ("float", "int") and not p.nan_means
    if numeric and (p.low is not None or p.high is not None):
        low = -math.inf if p.low is None else p.low
        high = math.inf if p.high is None else p.high
        if p.type_name == "int":
            descriptor.integer_range = [IntegerRange(from_value=int(max(low, -2**62)),
                                                     to_value=int(min(high, 2**62)), step=0)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(from_value=float(low),
                                                                  to_value=float(high))]
    if p.type_name == "double array":
        descriptor.dynamic_typing = True  # "[5, 6]" parses as an integer array
    return descriptor


def check_value(p: Param, value):
    """``value`` of parameter ``p`` if it is allowed; else ValueError naming the parameter."""
    unit = f" {p.unit}" if p.unit else ""
    if p.type_name == "double array":
        try:
            items = [float(v) for v in value]
        except (TypeError, ValueError):
            raise ValueError(f"parameter '{p.name}' must be numbers, got {value!r}") from None
    elif p.type_name == "float":
        items = [float(value)]
    elif p.type_name == "int":
        items = [int(value)]
    elif p.type_name == "string array":
        items = [str(v) for v in value if v != ""]  # [""] is rcl's typed empty array
    else:
        items = [value]
    for item in items:
        if isinstance(item, float):
            if math.isnan(item):
                if p.nan_means:
                    continue
                raise ValueError(f"parameter '{p.name}' is NaN")
            if (p.low is not None and item < p.low) or (p.high is not None and item > p.high):
                nan = f" (NaN: {p.nan_means})" if p.nan_means else ""
                raise ValueError(f"parameter '{p.name}' must be in {p.constraints()[0]}{unit}"
                                 f"{nan}, got {item:g}{unit}")
        elif isinstance(item, int) and not isinstance(item, bool):
            if (p.low is not None and item < p.low) or (p.high is not None and item > p.high):
                raise ValueError(f"parameter '{p.name}' must be in {p.range_text()}, got {item}")
        if p.choices and item not in p.choices:
            raise ValueError(f"parameter '{p.name}' must be one of {list(p.choices)}, "
                             f"got {item!r}")
    return value


def refuse_changes(node, names) -> None:
    """Refuse run-time changes of the parameters ``names``, which the node reads at start-up."""
    from rcl_interfaces.msg import SetParametersResult

    def check(params) -> SetParametersResult:
        for param in params:
            if param.name in names:
                return SetParametersResult(
                    successful=False, reason=f"'{param.name}' is read at start-up"
                )
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(check)


def given_parameters(node) -> set[str]:
    """The parameters given to ``node`` (``-p``, ``--params-file``, overrides)."""
    return set(getattr(node, "_parameter_overrides", {}))  # rclpy keeps no public accessor


def _is_set(value) -> bool:
    if isinstance(value, list):
        return any(v != "" for v in value)
    return bool(value) and not (isinstance(value, float) and math.isnan(value))


def refuse_unused(node, spec: NodeSpec, values: dict) -> None:
    """ValueError naming a parameter given a value of its own that has no use with the others'
    values (its ``needs`` not set, or its ``excludes`` set). Its default value, as a file that
    lists every parameter gives it, changes nothing and passes."""
    given = given_parameters(node)
    for p in spec.params:
        if p.name not in given or values.get(p.name) == p.default:
            continue
        if p.needs and not _is_set(values.get(p.needs)):
            raise ValueError(f"parameter '{p.name}' acts only with '{p.needs}' set, and it is "
                             f"not: drop '{p.name}' or set '{p.needs}'")
        if p.excludes and _is_set(values.get(p.excludes)):
            raise ValueError(f"parameter '{p.name}' has no use with '{p.excludes}' set "
                             f"({values[p.excludes]!r}): drop one of them")


def refuse_undeclared(node, spec: NodeSpec) -> None:
    """ValueError naming a parameter given to ``node`` (``-p``, ``--params-file``, overrides)
    that neither its table nor rclpy declares: a misspelt ``-p dampng:=750.0`` would else be
    ignored without a word."""
    given = given_parameters(node)
    known = {p.name for p in spec.params}
    unknown = sorted(n for n in given if n not in known and not node.has_parameter(n))
    if unknown:
        s = "s" if len(unknown) > 1 else ""
        raise ValueError(f"unknown parameter{s} {', '.join(repr(n) for n in unknown)}: "
                         f"{spec.name} has " + ", ".join(p.name for p in spec.params)
                         + " (see --help)")


def declare_parameters(node, spec: NodeSpec, names: Iterable[str] | None = None) -> dict:
    """Declare the table's parameters (or only ``names``) on ``node``; return their values.

    With the whole table (``names`` None), a parameter given to the node that the table does
    not hold is refused first (:func:`refuse_undeclared`), and one given where its ``needs`` or
    ``excludes`` say it has no use after (:func:`refuse_unused`). Values outside a row's range or
    choices raise ValueError naming the parameter. Parameters not marked ``dynamic`` refuse
    run-time changes (they are read at start-up).
    """
    rows = spec.params if names is None else tuple(spec[n] for n in names)
    if names is None:
        refuse_undeclared(node, spec)
    values = {}
    from rclpy.exceptions import InvalidParameterValueException

    for p in rows:
        try:
            node.declare_parameter(p.name, p.default, _descriptor(p))
        except InvalidParameterValueException as exc:  # the descriptor's range refused it
            value = str(exc).partition("(")[2].partition(")")[0]
            unit = f" {p.unit}" if p.unit else ""
            raise ValueError(f"parameter '{p.name}' must be in {p.range_text()}{unit}, "
                             f"got {value}{unit}") from None
        values[p.name] = check_value(p, node.get_parameter(p.name).value)
    if names is None:
        refuse_unused(node, spec, values)
    fixed = [p.name for p in rows if not p.dynamic]
    if fixed:
        refuse_changes(node, fixed)
    return values
