"""Tell a bad input (exit 2) from a failure of the tools themselves (exit 3) in ``dva``'s main.

An input error is one the project raises on purpose about what the user gave: the error types
of the project (``CliError``, ``RBFFileError``, ``ScenarioError``, ...), a missing file, or a
ValueError/TypeError raised by a ``raise`` statement of the project's own code (or by its
``float()``/``int()`` of a user's text). Anything else (a ValueError from inside numpy or
scipy, an unpacking error, an IndexError, an OverflowError) is the tools' own failure: saying
"error: <numpy message>" would blame the user's file for it.
"""
from __future__ import annotations

import errno
import linecache
import os
from pathlib import Path

#: Exit code of an internal error (2 is a bad input, 130 an interrupt).
INTERNAL_ERROR_EXIT = 3

_PROJECT_PACKAGES = ("aero_dva", "dva_offline", "aero_dva_sim", "aero_dva_control")
_CONVERSIONS = ("could not convert", "invalid literal for")
_ALWAYS_INPUT = (FileNotFoundError, FileExistsError, NotADirectoryError, IsADirectoryError,
                 PermissionError)
#: OSErrors that say a path the user gave cannot be one (too long, a loop of links)
_PATH_ERRNOS = (errno.ENAMETOOLONG, errno.ELOOP)


def _in_project(filename: str) -> bool:
    parts = Path(filename).parts
    return any(package in parts for package in _PROJECT_PACKAGES)


def _raising_frame(exc: BaseException):
    tb = exc.__traceback__
    if tb is None:
        return None
    while tb.tb_next is not None:
        tb = tb.tb_next
    return tb


def is_input_error(exc: BaseException, input_types: tuple = ()) -> bool:
    """Whether ``exc`` reports a bad input (see the module docstring); ``input_types`` are
    further types that always do (the CLI's own error type)."""
    if isinstance(exc, (*input_types, *_ALWAYS_INPUT)):
        return True
    if isinstance(exc, OSError) and exc.errno in _PATH_ERRNOS:
        return True
    if not isinstance(exc, (ValueError, TypeError)):
        return False
    module = type(exc).__module__.split(".")[0]
    if module in _PROJECT_PACKAGES:
        return True  # a project error type: raised on purpose
    frame = _raising_frame(exc)
    if frame is None:
        return True  # raised by hand without a traceback: the project's own
    filename = frame.tb_frame.f_code.co_filename
    if not _in_project(filename):
        return False  # from inside a library: the project called it wrongly
    line = linecache.getline(filename, frame.tb_lineno).strip()
    return line.startswith("raise") or str(exc).startswith(_CONVERSIONS)


def internal_error_line(command: str, exc: BaseException) -> str:
    """The one line said for an internal error: what failed, and what to send with a report."""
    detail = " ".join(str(exc).split())[:200]
    hint = "" if os.environ.get("DVA_DEBUG") else "; rerun with DVA_DEBUG=1 for the traceback"
    return (f"dva {command}: internal error ({type(exc).__name__}: {detail}): a fault of the "
            f"tools, not of your input{hint} and report it with the command line and the input "
            "files")
