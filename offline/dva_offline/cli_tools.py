"""What every ``dva`` command shares: its error, help, ranges on the command line, JSON output.

Kept free of numerics imports (numpy is looked up only when a value is one) so that building
the parser stays fast.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
from collections.abc import Iterator
from pathlib import Path

__all__ = ["OUTPUT_OPTIONS", "CliError", "command_family", "emit", "exit_code_in_json",
           "finite", "given", "json_safe", "not_with", "outputs_held", "range2", "range3",
           "show_help"]

#: The attributes of a command's parsed arguments that name what it writes, and their options.
OUTPUT_OPTIONS = {"out": "--out", "plot": "--plot", "plot_dir": "--plot-dir"}


class CliError(Exception):
    """A user-facing error: printed as ``dva: error: ...`` with exit code 2, no traceback."""


def given(args, option: str) -> bool:
    """Whether ``option`` (``"--plot-dir"``) was given: its value is not None or False (an
    option whose use depends on the mode has the default None, resolved where it is used)."""
    return getattr(args, option.lstrip("-").replace("-", "_"), None) not in (None, False)


def not_with(args, why: str, *options: str) -> None:
    """Refuse the first of ``options`` that was given, in one line: ``OPTION why``. For the
    options a mode has no use for, so that none is parsed and then ignored."""
    for option in options:
        if given(args, option):
            raise CliError(f"{option} {why}")


@contextlib.contextmanager
def outputs_held(args) -> Iterator[None]:
    """Hold every output the command's arguments name (:data:`OUTPUT_OPTIONS`) for the
    command's run: a second ``dva`` run into one of them meanwhile, or an output that could
    not be written (a read-only folder, a file in its path), is refused in one line before it
    does anything (:func:`aero_dva.atomic_io.output_lock`, ``check_writable``)."""
    from aero_dva.atomic_io import check_writable, output_lock

    with contextlib.ExitStack() as stack:
        for attribute, option in OUTPUT_OPTIONS.items():
            value = getattr(args, attribute, None)
            if isinstance(value, str) and value:
                check_writable(value, option)  # refused now, not after the work
                stack.enter_context(output_lock(Path(value), option))
        yield


@contextlib.contextmanager
def exit_code_in_json(args, result: dict) -> Iterator[None]:
    """With ``--json``: what the command prints on stdout is held back, and one JSON object
    printed gets the field ``exit_code`` (``result["code"]``, set by the caller before the
    block ends); a command that ends in an error prints ``{"exit_code": N, "error": line}``
    (``result["error"]``). Without ``--json`` the output passes as it is."""
    if not getattr(args, "json", False) or not isinstance(args.json, bool):
        yield
        return
    held = io.StringIO()
    try:
        with contextlib.redirect_stdout(held):
            yield
    finally:
        text = held.getvalue()
        payload = None
        with contextlib.suppress(ValueError):
            payload = json.loads(text) if text.strip() else None
        code = result.get("code")
        if isinstance(payload, dict) and code is not None:
            payload.setdefault("exit_code", code)
            print(json.dumps(payload))
        else:
            print(text, end="")
            if not text.strip() and result.get("error") is not None:
                print(json.dumps({"exit_code": code, "error": result["error"]}))


def show_help(parser) -> int:
    """A command group called without its subcommand: its help, exit code 2."""
    parser.print_help()
    return 2


def command_family(subparsers, name: str, help_text: str, description: str, dest: str):
    """A command group (``dva NAME <subcommand>``): its parser and its subparsers; called
    without a subcommand it prints its help (exit code 2)."""
    parser = subparsers.add_parser(name, help=help_text, description=description,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest=dest, metavar=f"<{name}-command>")
    parser.set_defaults(func=lambda args: show_help(parser))
    return parser, sub


def range3(option: str, text: str, names: str = "START:STOP:N", minimum: float | None = None):
    """``START:STOP:N`` -> (start, stop, n): finite ``start < stop`` (both >= ``minimum`` if
    given) and ``n >= 2``; a one-line ValueError naming ``option`` otherwise."""
    parts = text.split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise ValueError(f"{option} expects {names}, got {text!r}") from None
    if not (math.isfinite(start) and math.isfinite(stop)) or n < 2 or stop <= start \
            or (minimum is not None and start < minimum):
        low = "" if minimum is None else f"{minimum:g} <= "
        raise ValueError(f"{option} needs finite {low}{names.split(':')[0]} < "
                         f"{names.split(':')[1]} and N >= 2, got {text!r}")
    return start, stop, n


def range2(option: str, text: str):
    """``MIN:MAX`` -> (low, high), finite and ``low < high``."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        low, high = float(parts[0]), float(parts[1])
    except ValueError:
        raise ValueError(f"{option} expects MIN:MAX, got {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
        raise ValueError(f"{option} needs finite MIN < MAX, got {text!r}")
    return low, high


def finite(value) -> float | None:
    """``float(value)``, or None for None, NaN and infinities (JSON has no NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def json_safe(value):
    """A copy fit for strict JSON: numpy scalars and arrays as Python values, NaN and
    infinities as None, tuples as lists, mapping keys as strings."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return json_safe(value.tolist())
    return value


def emit(args, payload: dict, lines: list[str]) -> None:
    """Print ``payload`` as one strict JSON object (``--json``) or ``lines`` as text."""
    if args.json:
        print(json.dumps(json_safe(payload), allow_nan=False))
    else:
        print("\n".join(lines))
