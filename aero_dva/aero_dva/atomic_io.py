"""Outputs written safely: a reader never sees half a file (temporary file + rename), and two
runs never write into one output (atomic directory creation, unique default names, locks)."""
from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def atomic_output(path, mode: str = "w", *, fsync: bool = False) -> Iterator:
    """Open a temporary file beside ``path`` (its folder made if missing); on success it
    replaces ``path`` (mode 0644), on failure it is removed and ``path`` is untouched.
    ``fsync`` puts the data on the disk before the rename (for a file that marks something
    else complete, like a bag's metadata.yaml)."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)  # (an output's folder is made for it)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:  # (read-only, no permission, no such folder): name the output
        exc.filename = str(path)
        raise
    try:
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as stream:
            yield stream
            if fsync:
                stream.flush()
                os.fsync(stream.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; these files are meant to be shared
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.filename in (None, tmp):
            exc.filename = str(path)  # (a full disk names the output, not the temporary file)
        raise


# -- outputs that cannot collide -------------------------------------------------------------
#
# Two runs never write into one output: a directory is created with one mkdir (atomic: of two
# runs asking for one name, exactly one gets it), a default name that is taken moves on to the
# next free one (``name_2``, ``name_3``, ...), and an output a run writes for a while (a file
# replaced at the end, an evaluation directory it resumes) is held under an exclusive lock that
# a second run is refused by.

class OutputBusyError(FileExistsError):
    """Another running process holds the output (a second run into one output)."""


def said(exc: OSError, text: str) -> OSError:
    """An OSError of ``exc``'s type and errno whose message is ``text`` alone (no "[Errno N]"
    prefix: it is printed as the one-line error)."""
    new = type(exc)(text)
    new.errno = exc.errno  # (strerror stays unset: str() would print it instead of text)
    return new


def _created(path: Path, what: str) -> bool:
    """mkdir ``path`` (parents too); False when it exists; one-line OSError when it cannot."""
    try:
        if not path.parent.is_dir():
            path.parent.mkdir(parents=True)
        path.mkdir()
    except FileExistsError:
        if not path.parent.is_dir():  # a parent is a file
            raise NotADirectoryError(f"{what} {str(path)!r} cannot be created: "
                                     f"{str(path.parent)!r} is not a directory") from None
        return False
    except OSError as exc:
        raise said(exc, f"{what} {str(path)!r} cannot be created: {exc.strerror}") from None
    return True


def new_directory(path, what: str = "output", *, siblings: tuple[str, ...] = ()) -> Path:
    """Create the directory ``path`` (and ``path`` + each suffix of ``siblings``, e.g.
    ``"_logs"``) for this run alone; FileExistsError naming the one that exists otherwise
    (nothing created is left behind)."""
    path = Path(path)
    made: list[Path] = []
    try:
        for target in (path, *(path.with_name(path.name + s) for s in siblings)):
            if not _created(target, what):
                named = f"{what} {str(path)!r}" + ("" if target == path else
                                                   f": {str(target)!r}")
                raise FileExistsError(f"{named} exists; choose another name (an output is "
                                      "never reused)")
            made.append(target)
    except BaseException:
        for target in reversed(made):
            target.rmdir()
        raise
    return path


def unique_directory(stem, what: str = "output", *, siblings: tuple[str, ...] = ()) -> Path:
    """Create the first free directory of ``stem``, ``stem_2``, ``stem_3``, ... (with its
    ``siblings``, see :func:`new_directory`) for this run alone: a default name (one with a
    UTC time in it, say) that another run took in the same second is never shared."""
    stem = Path(stem)
    for n in range(1, 10_000):
        path = stem if n == 1 else stem.with_name(f"{stem.name}_{n}")
        try:
            return new_directory(path, what, siblings=siblings)
        except OutputBusyError:
            raise
        except FileExistsError:
            continue
    raise FileExistsError(f"{what}: 10000 directories named {str(stem)!r}_N exist already")


def check_writable(path, what: str = "output") -> None:
    """Refuse, before any work, an output ``path`` that could not be written at the end: the
    folder it goes into (its nearest existing one, for a path still to be made) is a file, or
    is not writable (no permission, a read-only file system). One-line OSError naming it."""
    import errno

    path = Path(path).absolute()
    folder = path if path.is_dir() else path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise NotADirectoryError(f"{what} {str(path)!r} cannot be made: {str(folder)!r} is "
                                 "not a directory")
    if not os.access(folder, os.W_OK | os.X_OK):
        error = PermissionError(f"{what} {str(path)!r} cannot be written: {str(folder)!r} is "
                                "read-only" if _read_only(folder) else
                                f"{what} {str(path)!r} cannot be written: no permission to "
                                f"write in {str(folder)!r}")
        error.errno = errno.EROFS if _read_only(folder) else errno.EACCES
        raise error


def _read_only(folder: Path) -> bool:
    try:
        return bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def _lock_directory() -> Path:
    """Where the output locks live: one folder per user in the temporary directory (a lock
    beside the output would litter the user's folders and need their parents made first)."""
    folder = Path(tempfile.gettempdir()) / f"dva-output-locks-{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    return folder


@contextlib.contextmanager
def output_lock(path, what: str = "output") -> Iterator[Path]:
    """Hold ``path`` (a file or directory this run writes, existing or not) for the block:
    a second run asking for the same path meanwhile gets :class:`OutputBusyError` at once.
    The lock is a ``flock`` on a file named for the resolved path in :func:`_lock_directory`
    (released by the kernel even when the process is killed), removed at the end."""
    import fcntl
    import hashlib

    path = Path(path).resolve()
    key = hashlib.sha256(str(path).encode()).hexdigest()[:32]
    lock = _lock_directory() / f"{key}.lock"
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputBusyError(f"{what} {str(path)!r} is being written by another run "
                                  "right now; wait for it to end or choose another") from None
        try:  # the holder before may have removed the file we locked: lock the one in place
            if os.fstat(fd).st_ino == os.stat(lock).st_ino:
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:
        os.write(fd, f"{os.getpid()} {path}\n".encode())
        yield path
    finally:
        lock.unlink(missing_ok=True)  # while still held: a later run locks a new file
        os.close(fd)
