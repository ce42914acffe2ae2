"""Fast DDS shared-memory port files that would hang every later participant.

A process that dies while creating its shared-memory port leaves ``/dev/shm/fastrtps_portN``
at size 0. Every later DDS participant that takes that port number hangs for ever while being
created, before its first log line (docs/reliability.md: two loaded integration runs and an
idle fresh clone failed so). Fast DDS's own ``fastdds shm clean`` removes ports whose lock file
nobody holds; such a port may have no lock file at all. A port being created is unsized for
microseconds, so one older than a minute is a dead process's. Every node removes such files
before it starts DDS (``node_tools.run_node``).

A process killed (SIGKILL, as tests and benchmarks do) also leaves its participant's segment
(``fastrtps_<16 hex>``, 0.5 MB of memory in /dev/shm) and the segment's ``_el`` lock file, which
a live owner holds locked (flock) for its life. Nothing removed them: on one machine 210 had
built up in a night (113 MB). :func:`remove_dead_segments` removes those whose lock nobody holds,
as ``fastdds shm clean`` does, and only those older than a minute (a segment being created is
unlocked for a moment).
"""
from __future__ import annotations

import fcntl
import os
import re
import sys
import time
from pathlib import Path

SHM = Path("/dev/shm")
MIN_AGE = 60.0  # [s] an unsized port older than this belongs to no live process
# The port segment itself; its lock files (``_el``, ``_sl``) are empty by design and must stay.
PORT_NAME = re.compile(r"fastrtps_port\d+")
SEGMENT_LOCK = re.compile(r"fastrtps_[0-9a-f]{16}_el")


def _old_files(shm: Path, pattern: str, name: re.Pattern, min_age: float):
    """(path, stat) of each file of ``shm`` matching ``pattern`` whose name is all ``name`` and
    that was last changed more than ``min_age`` seconds ago (one that vanishes is skipped)."""
    now = time.time()
    for path in sorted(shm.glob(pattern)):
        if not name.fullmatch(path.name):
            continue
        try:
            info = path.stat()
        except OSError:
            continue
        if now - info.st_mtime > min_age:
            yield path, info


def remove_unsized_ports(shm: Path = SHM, min_age: float = MIN_AGE) -> list[Path]:
    """Remove port segments (``fastrtps_portN``) of size 0 older than ``min_age`` seconds, with
    their mutex (``sem.fastrtps_portN_mutex``); return the ports removed. Lock files, files that
    vanish meanwhile and files of another user are left alone."""
    removed = []
    for port, info in _old_files(shm, "fastrtps_port*", PORT_NAME, min_age):
        if info.st_size != 0:
            continue
        try:
            port.unlink()
            (shm / f"sem.{port.name}_mutex").unlink(missing_ok=True)
        except OSError:
            continue
        removed.append(port)
    return removed


def remove_dead_segments(shm: Path = SHM, min_age: float = MIN_AGE) -> list[Path]:
    """Remove the segments (``fastrtps_<16 hex>``) whose ``_el`` lock file is older than
    ``min_age`` seconds and locked by nobody, with that lock file; return the segments removed.
    A lock held (a live participant's), a file that vanishes meanwhile or one of another user is
    left alone."""
    removed = []
    for lock, _ in _old_files(shm, "fastrtps_*_el", SEGMENT_LOCK, min_age):
        try:
            fd = os.open(lock, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # OSError: its owner lives
            segment = lock.with_name(lock.name[:-len("_el")])
            segment.unlink(missing_ok=True)
            lock.unlink()
        except OSError:
            continue
        finally:
            os.close(fd)
        removed.append(segment)
    return removed


def clear_dead_ports(prefix: str, shm: Path = SHM) -> list[Path]:
    """:func:`remove_unsized_ports`, each removal said on stderr after ``prefix`` (who removed
    it: a port that would have hung the node), and :func:`remove_dead_segments`, unsaid (memory
    of the dead, nothing a run's output should carry: its one-line errors stay one line);
    return what was removed (ports, then segments)."""
    removed = remove_unsized_ports(shm)
    for port in removed:
        print(f"{prefix} removed {port}: an unsized Fast DDS port file a dead process left",
              file=sys.stderr)
    return removed + remove_dead_segments(shm)
