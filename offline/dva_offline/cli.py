"""The ``dva`` command: one entry point, one subcommand per offline tool (git/ros2 style).

Each subcommand lives in its own module exposing ``register(subparsers)``; the module adds a
parser whose ``func`` default is called with the parsed arguments and returns an exit code.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings

from dva_offline import __version__
from dva_offline.cli_failures import INTERNAL_ERROR_EXIT, internal_error_line, is_input_error

# name -> module; a module registers exactly one top-level subcommand.
SUBCOMMAND_MODULES = {
    "info": "dva_offline.info_cli",
    "wing": "dva_offline.wing_cli",
    "isolator": "dva_offline.isolator.cli",
    "discrepancy": "dva_offline.discrepancy.cli",
    "control": "dva_offline.control_cli",
    "train": "dva_offline.train_cli",
    "evaluate": "dva_offline.evaluation_cli",
    "report": "dva_offline.run_report_cli",
    "replay": "dva_offline.replay_cli",
    "bag": "dva_offline.bag_cli",
}


class CliError(Exception):
    """A user-facing error: printed as ``dva: error: ...`` with exit code 2, no traceback."""


def input_limits() -> str:
    """The limits every command reads its files within, and the exit codes (for --help)."""
    from aero_dva.safe_files import LIMITS
    from dva_offline.isolator.isolator_io import MAX_FRF_POINTS, MAX_ROWS

    return (f"Limits: {LIMITS}; CSV tables at most {MAX_ROWS:,} rows, FRF tables at most "
            f"{MAX_FRF_POINTS:,} points; .npz arrays no larger than the file. Exit codes: 0 "
            f"done, 2 bad input, {INTERNAL_ERROR_EXIT} internal error, 130 interrupted.")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dva",
        description=(
            "Offline tools for the aeroelastic wing with a tunable Maxwell-element dynamic "
            "vibration absorber (DVA). Run 'dva <command> --help' for a command's options."
        ),
        epilog=input_limits(),
    )
    parser.add_argument("--version", action="version", version=f"dva {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="<command>")
    for module_name in SUBCOMMAND_MODULES.values():
        importlib.import_module(module_name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    # Runtime warnings (e.g. reading a cut bag with --allow-truncated) are said once each, in
    # one line, before the command's result or error.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        try:
            code = int(args.func(args) or 0)
        except KeyboardInterrupt:
            print(f"dva {args.command}: interrupted", file=sys.stderr)
            return 130
        except Exception as exc:
            # Input problems are reported in one line naming the bad input (exit 2), a fault
            # of the tools as an internal error (exit 3), never as a traceback (DVA_DEBUG=1
            # shows it when hunting a bug).
            _say_warnings(args.command, caught)
            if not is_input_error(exc, (CliError,)):
                print(internal_error_line(args.command, exc), file=sys.stderr)
                if os.environ.get("DVA_DEBUG"):
                    raise
                return INTERNAL_ERROR_EXIT
            if os.environ.get("DVA_DEBUG"):
                raise
            print(f"dva {args.command}: error: {exc}", file=sys.stderr)
            return 2
    _say_warnings(args.command, caught)
    return code


def _say_warnings(command: str, caught: list) -> None:
    for text in dict.fromkeys(str(w.message) for w in caught):
        print(f"dva {command}: warning: {text}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
