"""How every executable of the project ends: the exit-code table, said once, and signals.

``dva``, the nodes, ``run_flight``, ``replay_flight`` and the README's scripts exit with one of
:data:`TABLE`'s codes, each with one meaning; their ``--help`` prints :func:`help_text` and
docs/reliability.md quotes it. A ``--json`` output carries the code as ``exit_code``.

SIGINT and SIGTERM mean the same (a user's Ctrl-C, a scheduler's stop): inside
:func:`signals_interrupt` both raise :class:`Interrupted`, so ``finally`` blocks run (nodes are
stopped, temporary files removed) and the process ends with one line and :data:`INTERRUPTED`.
"""
from __future__ import annotations

import contextlib
import errno
import os
import signal
from collections.abc import Iterator

__all__ = ["BAD_INPUT", "CLOSED_PIPE", "DONE", "FAILED", "INTERRUPTED", "PARTIAL", "TABLE",
           "Failure", "Interrupted", "debug", "help_text", "interrupt_in", "meaning",
           "os_error_code", "os_error_line", "signals_interrupt"]

DONE = 0
PARTIAL = 1
BAD_INPUT = 2
FAILED = 3
INTERRUPTED = 130
CLOSED_PIPE = 141  # 128 + SIGPIPE: what a shell reports for a Unix tool a closed pipe ended

#: Code -> meaning, for every executable of the project.
TABLE = {
    DONE: "done, nothing lost",
    PARTIAL: "completed, but the result is partial or failed its own check (messages lost "
             "in a recovery or a replay, a flight on the fallback c2, failed flights in an "
             "evaluation)",
    BAD_INPUT: "bad input: an option, a file or an output path, named in the one-line error "
               "(nothing was done)",
    FAILED: "failed: an internal error, or the run could not complete (a node that died, no "
            "space left, a timeout), named in the one-line error",
    INTERRUPTED: "interrupted by SIGINT or SIGTERM",
    CLOSED_PIPE: "stdout closed by its reader (as `| head`): stopped quietly",
}


def meaning(code: int) -> str:
    """What exit code ``code`` means (any other code: a process killed by a signal, -N)."""
    if code in TABLE:
        return TABLE[code]
    return f"killed by signal {-code}" if code < 0 else f"unknown exit code {code}"


def help_text() -> str:
    """The table in one paragraph, for ``--help`` epilogues."""
    return "Exit codes: " + "; ".join(f"{code} {text}" for code, text in TABLE.items()) + "."


def debug() -> bool:
    """``DVA_DEBUG`` is set: show tracebacks instead of the one-line errors."""
    return bool(os.environ.get("DVA_DEBUG"))


class Failure(Exception):
    """An error said in one line (``str(exc)``, without the program's name) that carries its
    own exit code (default :data:`FAILED`): a run whose node died, a recorded file that does
    not read back."""

    def __init__(self, text: str, exit_code: int = FAILED) -> None:
        super().__init__(text)
        self.exit_code = exit_code


def os_error_code(exc: OSError) -> int:
    """The exit code of an OSError met while writing an output: the path the user chose
    (it exists, a parent is a file, no permission, a read-only file system) is bad input;
    anything else (no space left, an I/O error) fails the run."""
    bad_path = (FileExistsError, PermissionError, NotADirectoryError, IsADirectoryError,
                FileNotFoundError)
    # a read-only file system, a path too long for it, a loop of links: the path is wrong
    bad_errno = (errno.EROFS, errno.ENAMETOOLONG, errno.ELOOP)
    return BAD_INPUT if isinstance(exc, bad_path) or exc.errno in bad_errno else FAILED


def os_error_line(exc: OSError) -> str:
    """An OSError in one line: its text, its file, and "no space left" said plainly."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return "no space left on the device" + (f" writing {exc.filename!s}"
                                                if exc.filename else "")
    return str(exc) if exc.filename is None else f"{exc.strerror or exc}: {exc.filename!s}"


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived; ``signal_name`` says which."""

    def __init__(self, signum: int = signal.SIGINT) -> None:
        self.signum = signum
        self.signal_name = signal.Signals(signum).name
        super().__init__(f"interrupted by {self.signal_name}")


def interrupt_in(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The interrupt ``exc`` is, or that it was raised while handling (its context chain):
    an interrupt lands anywhere, and cleaning up after it can fail in turn (a progress bar
    half made when the signal came); the command was still interrupted, not broken."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _raise(signum, _frame) -> None:
    raise Interrupted(signum)


@contextlib.contextmanager
def signals_interrupt() -> Iterator[None]:
    """Within the block SIGINT and SIGTERM raise :class:`Interrupted` (a KeyboardInterrupt, so
    code that already stops cleanly on Ctrl-C does on SIGTERM too); the handlers before are
    restored after. Only the main thread can install handlers: elsewhere this does nothing."""
    try:
        before = {s: signal.signal(s, _raise) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)


if __name__ == "__main__":  # the table for the shell scripts' --help: python3 exits.py
    print(help_text())
