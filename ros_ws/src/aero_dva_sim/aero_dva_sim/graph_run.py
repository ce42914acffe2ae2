"""What every run of a node graph shares (``run_flight``, ``replay_flight``): its outputs, its
ROS domain, its node processes, and how it ends.

A run ends in one of the exit codes of :mod:`aero_dva.exits`, with one line on stderr that
names the cause and the run (its bag), never a traceback (``DVA_DEBUG=1`` shows it): a node
that exits or dies before its time, a file system that refuses the output, a signal, a fault
of the runner itself. The reserved ROS domain is released and the nodes are stopped whatever
happens.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
from pathlib import Path

from aero_dva import exits
from aero_dva.atomic_io import new_directory, unique_directory

__all__ = ["RunFailed", "claim_outputs", "die_with_parent", "failure", "node_failure",
           "run_on_domain"]

LOGS = "_logs"  # a bag's node logs: the folder <bag>_logs beside it


class RunFailed(exits.Failure):
    """A run that failed for a reason it names: ``str(exc)`` is the one line (without the
    program's name), ``exit_code`` one of :mod:`aero_dva.exits`."""


def claim_outputs(output: str | None, default_stem: str, option: str = "--output"
                  ) -> tuple[Path, Path]:
    """Create the run's bag directory and its ``<bag>_logs`` folder, both empty and this run's
    alone: ``output`` if given (refused when it or its logs folder exists), else the first
    free name of ``default_stem``, ``default_stem_2``, ... (two runs started in one second
    never meet). The recorder writes into the empty bag directory."""
    if output:
        bag = new_directory(Path(output).resolve(), option, siblings=(LOGS,))
    else:
        bag = unique_directory(Path(default_stem).resolve(), "bag", siblings=(LOGS,))
    return bag, bag.with_name(bag.name + LOGS)


def remove_if_empty(*paths: Path) -> None:
    """Remove the directories ``paths`` that are empty (a run that failed before writing)."""
    for path in paths:
        with contextlib.suppress(OSError):
            path.rmdir()


def die_with_parent() -> None:
    """In a child before exec: on Linux, get SIGTERM when the runner dies (even by SIGKILL), so
    no node outlives its run and talks on a ROS_DOMAIN_ID that is no longer reserved."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass  # not Linux: the runner's finally-block still stops the nodes


def last_error(log: Path) -> str | None:
    """A node log's last error line, if it has one."""
    try:
        lines = log.read_text(errors="replace").strip().splitlines()
    except OSError:
        return None
    said = [line.strip() for line in lines if "ERROR" in line or "error:" in line
            or "Error:" in line]
    return said[-1][:300] if said else None


def node_failure(name: str, code: int, log: Path, when: str) -> RunFailed:
    """The failure of node ``name`` that exited with ``code`` ``when`` (e.g. "before the
    flight ended"), with the last error line of its log: a node that refused its input (2)
    makes the run's exit code 2, any other end (a crash, a signal, -9 for a kill) 3."""
    how = f"was killed by signal {-code}" if code < 0 else f"exited with {code}"
    error = last_error(log)
    said = f" ({error})" if error else ""
    return RunFailed(f"{name} {how}{' ' + when if when else ''}{said}; see {log}",
                     exits.BAD_INPUT if code == exits.BAD_INPUT else exits.FAILED)


def failure(exc: BaseException) -> tuple[str, int]:
    """The one line (without the program's name) and exit code of an exception that ended a
    run."""
    if isinstance(exc, exits.Failure):
        return str(exc), exc.exit_code
    exc = exits.interrupt_in(exc) or exc  # (a failure while stopping on a signal)
    if isinstance(exc, KeyboardInterrupt):
        name = getattr(exc, "signal_name", "SIGINT")
        return f"interrupted by {name}", exits.INTERRUPTED
    if isinstance(exc, SystemExit):  # a plain SystemExit("run_flight: error: ...")
        if isinstance(exc.code, int):
            return f"exited with {exc.code}", exc.code
        return str(exc.code).split("error: ", 1)[-1], exits.FAILED
    if isinstance(exc, OSError):
        return exits.os_error_line(exc), exits.os_error_code(exc)
    if isinstance(exc, ValueError):  # the project's checks of the inputs raise these
        return str(exc), exits.BAD_INPUT
    detail = " ".join(str(exc).split())[:200]
    return (f"internal error ({type(exc).__name__}: {detail}); rerun with DVA_DEBUG=1 for the "
            "traceback", exits.FAILED)


def run_on_domain(prog: str, run, args) -> tuple[dict | None, int]:
    """``(run(args), 0)`` on ``args.domain_id`` or on a ROS domain reserved for this run
    (released after), with SIGINT and SIGTERM as :class:`~aero_dva.exits.Interrupted` and the
    discovery range of ``args.discovery``; ``(None, exit code)`` with the one line said when it
    fails (also left in ``args.failure``). ``run`` names its run by setting ``args.run_name``
    (its bag) as soon as it has one.
    """
    from dva_ros_common.ros_domain import reserved_domain, use_discovery

    use_discovery(getattr(args, "discovery", None))
    args.run_name = None
    try:
        with exits.signals_interrupt(), contextlib.ExitStack() as stack:
            if args.domain_id is None:
                args.domain_id = stack.enter_context(reserved_domain())
            return run(args), exits.DONE
    except (Exception, KeyboardInterrupt, SystemExit) as exc:  # every end in one line
        if exits.debug():
            raise
        text, code = failure(exc)
        run_name = getattr(args, "run_name", None)
        if run_name and str(run_name) not in text:
            text += f" (run {run_name})"
        word = "" if code == exits.INTERRUPTED else "error: "
        print(f"{prog}: {word}{text}", file=sys.stderr)
        args.failure = text
        return None, code


def environment(domain: int) -> dict:
    """The nodes' environment: this one with the run's ROS domain, unbuffered output."""
    return dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
