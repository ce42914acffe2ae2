"""Read a small text input file (YAML, JSON) or refuse it in one sentence that names it.

Configuration files of this project (wings, sections, scenarios, schedules) are a few hundred
bytes. A wrong file given by accident (a recording, a binary, a log of millions of lines) must
be refused at once with the reason, not parsed for minutes or reported as a decoding error
that does not say which file.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["MAX_LOGGED_CHARS", "MAX_TEXT_BYTES", "InputFileError", "loggable",
           "read_text_input"]

#: [bytes] largest configuration file read; the largest shipped one is about 2 kB.
MAX_TEXT_BYTES = 4 * 2**20
#: Most characters of one piece of outside text (a command's source, a name) put in a log line.
MAX_LOGGED_CHARS = 120


def loggable(text, limit: int = MAX_LOGGED_CHARS) -> str:
    """Text from outside (a command's source, a scenario, topic or file name) fit for one log
    line: control characters (newlines, escape codes) written as escapes, cut to ``limit``
    characters with the length of the rest said."""
    text = str(text)
    shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text[:limit])
    return shown if len(text) <= limit else f"{shown}... ({len(text) - limit:,} more characters)"


class InputFileError(ValueError):
    """An input file that is missing, too large, binary or not UTF-8."""


def read_text_input(path, what: str = "file", *, max_bytes: int = MAX_TEXT_BYTES,
                    error: type[ValueError] = InputFileError) -> str:
    """The UTF-8 text of ``path``; ``error`` (a ValueError) naming ``what`` and the path.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file is, for the message ("wing file", "scenario").
    max_bytes : int
        Larger files are refused before they are read.
    error : type
        Exception class raised (a ValueError subclass, so callers keep their own types).
    """
    path = Path(path)
    where = f"{what} {str(path)!r}"
    if not path.exists():
        raise error(f"{where}: cannot read (file not found)")
    if not path.is_file():
        raise error(f"{where}: cannot read (not a regular file)")
    size = path.stat().st_size
    if size > max_bytes:
        raise error(f"{where}: {size / 2**20:.1f} MiB is far larger than any {what} "
                    f"(at most {max_bytes / 2**20:g} MiB read); is it the right file?")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"{where}: cannot read ({exc.strerror or exc})") from None
    nul = data.find(b"\x00")
    if nul >= 0:
        raise error(f"{where}: binary data (a NUL byte at offset {nul}), not a text file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{where}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                    f"{exc.start})") from None
