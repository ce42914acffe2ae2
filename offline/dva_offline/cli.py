"""The ``dva`` command: one entry point, one subcommand per offline tool (git/ros2 style).

Each command family is a folder of ``dva_offline`` whose ``cli`` module exposes
``register(subparsers)``: it adds a parser whose ``func`` default is called with the parsed
arguments and returns an exit code. Those modules import their numerics inside the handlers,
so building the parser (``dva --help``) loads neither scipy nor matplotlib.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings


def _stopped_while_loading(signum, frame) -> None:
    """SIGINT or SIGTERM before the command has begun (imports, the parser): nothing was
    started, so nothing is left; one line, exit 130, as later (no traceback from an import,
    no silent 143)."""
    os.write(2, b"dva: interrupted\n")
    os._exit(130)


if __name__ == "__main__" or os.path.basename(sys.argv[0]) == "dva":  # the program itself
    for _signal in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_signal, _stopped_while_loading)

from aero_dva import exits  # noqa: E402
from aero_dva.text_input import loggable  # noqa: E402
from dva_offline import __version__, info  # noqa: E402
from dva_offline.bag import cli as bag_cli  # noqa: E402
from dva_offline.cli_failures import internal_error_line, is_input_error  # noqa: E402
from dva_offline.cli_tools import CliError, exit_code_in_json, outputs_held  # noqa: E402
from dva_offline.control import cli as control_cli  # noqa: E402
from dva_offline.discrepancy import cli as discrepancy_cli  # noqa: E402
from dva_offline.evaluation import cli as evaluation_cli  # noqa: E402
from dva_offline.isolator import cli as isolator_cli  # noqa: E402
from dva_offline.replay import cli as replay_cli  # noqa: E402
from dva_offline.report import cli as report_cli  # noqa: E402
from dva_offline.switching import cli as switching_cli  # noqa: E402
from dva_offline.training import cli as training_cli  # noqa: E402
from dva_offline.wing import cli as wing_cli  # noqa: E402

__all__ = ["CLOSED_PIPE_EXIT", "COMMANDS", "CliError", "build_parser", "main"]

# name -> the function that adds it, in the order `dva --help` lists them
COMMANDS = {
    "info": info.register,
    "wing": wing_cli.register,
    "isolator": isolator_cli.register,
    "discrepancy": discrepancy_cli.register,
    "control": control_cli.register,
    "train": training_cli.register,
    "evaluate": evaluation_cli.register,
    "report": report_cli.register,
    "replay": replay_cli.register,
    "bag": bag_cli.register,
    "switching": switching_cli.register,
}


#: Exit code when the reader of stdout went away (``dva bag info BAG | head -1``), in the table.
CLOSED_PIPE_EXIT = exits.CLOSED_PIPE


def input_limits() -> str:
    """The limits every command reads its files within, and the exit codes (for --help)."""
    from aero_dva.bag.chunk_limits import MAX_CHUNK_BYTES
    from aero_dva.flight.flight_limits import MAX_FLIGHT_SAMPLES, SAMPLE_RATE_RANGE
    from aero_dva.safe_files import LIMITS
    from dva_offline.isolator.files import MAX_FRF_POINTS, MAX_ROWS

    return (f"Limits: {LIMITS}; CSV tables at most {MAX_ROWS:,} rows, FRF tables at most "
            f"{MAX_FRF_POINTS:,} points; .npz arrays no larger than the file; bag chunks at "
            f"most {MAX_CHUNK_BYTES // 2**20} MiB decompressed, each file of a bag listed "
            f"once; flights, scenarios and training plans at most {MAX_FLIGHT_SAMPLES:,} "
            f"samples (duration x sample rate, {SAMPLE_RATE_RANGE[0]:g}.."
            f"{SAMPLE_RATE_RANGE[1]:g} Hz; docs/reliability.md). Two runs never write into "
            "one output: a second run into an output another is writing is refused. "
            + exits.help_text().replace(
                "Exit codes: ", "Exit codes, of every command (also exit_code in --json): ",
                1))


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
    for register in COMMANDS.values():
        register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return exits.BAD_INPUT
    if argv is None and signal.getsignal(signal.SIGTERM) is _stopped_while_loading:
        # loaded: from here on the command's own handling of signals (exits)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    result: dict = {}
    try:
        with exit_code_in_json(args, result):
            result["code"] = _run(args, result)
        sys.stdout.flush()  # here, so that a closed pipe is met inside the try
    except BrokenPipeError:
        return _closed_pipe()
    return result["code"]


def _run(args, result: dict) -> int:
    """The command's exit code; its one-line error (if any) said and left in ``result``."""
    # Runtime warnings (e.g. reading a cut bag with --allow-truncated) are said once each, in
    # one line, before the command's result or error. SIGTERM stops a command as SIGINT does.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        try:
            with exits.signals_interrupt(), outputs_held(args):
                code = int(args.func(args) or 0)
                sys.stdout.flush()  # here, so that a closed pipe is met inside the try
        except BrokenPipeError:
            raise  # (main stops quietly)
        except KeyboardInterrupt as exc:
            _say_warnings(args.command, caught)
            line = str(exc) if isinstance(exc, exits.Interrupted) else "interrupted"
            return _said(args, result, line, exits.INTERRUPTED)
        except Exception as exc:
            # Input problems are reported in one line naming the bad input (exit 2), a fault
            # of the tools as an internal error (exit 3), never as a traceback (DVA_DEBUG=1
            # shows it when hunting a bug); a failure that names its own code keeps it.
            _say_warnings(args.command, caught)
            if exits.debug():
                raise
            interrupt = exits.interrupt_in(exc)  # a failure while stopping on a signal
            if interrupt is not None:
                line = str(interrupt) if isinstance(interrupt, exits.Interrupted) \
                    else "interrupted"
                return _said(args, result, line, exits.INTERRUPTED)
            if isinstance(exc, exits.Failure):
                return _said(args, result, f"error: {exc}", exc.exit_code)
            if isinstance(exc, OSError) and exc.errno is not None and exc.strerror:
                # from the system: an output that cannot be written (bad input), no space
                # left or an I/O error (failed), not a fault of the tools
                return _said(args, result, f"error: {exits.os_error_line(exc)}",
                             exits.os_error_code(exc))
            if not is_input_error(exc, (CliError,)):
                line = internal_error_line(args.command, exc).split(": ", 1)[1]
                return _said(args, result, line, exits.FAILED)
            return _said(args, result, f"error: {exc}", exits.BAD_INPUT)
    _say_warnings(args.command, caught)
    return code


#: Most characters of an error's line said (the rest is counted, not printed).
ERROR_CHARS = 1000


def _said(args, result: dict, line: str, code: int) -> int:
    # one line whatever the input put in the message (a name with a newline or an escape
    # code, a huge value): control characters escaped, the length bounded
    line = loggable(line, ERROR_CHARS)
    print(f"dva {args.command}: {line}", file=sys.stderr)
    result["error"] = line.removeprefix("error: ")
    return code


def _closed_pipe() -> int:
    """The reader of stdout closed the pipe: stop quietly, as Unix tools do. Whatever is
    still buffered goes to /dev/null, so that Python's flush at exit cannot complain."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return CLOSED_PIPE_EXIT


def _say_warnings(command: str, caught: list) -> None:
    for text in dict.fromkeys(str(w.message) for w in caught):
        print(f"dva {command}: warning: {loggable(text, ERROR_CHARS)}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
