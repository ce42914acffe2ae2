"""Fast DDS shared-memory port files that would hang every later participant.

A process that dies while creating its shared-memory port leaves ``/dev/shm/fastrtps_portN``
at size 0. Every later DDS participant that takes that port number hangs for ever while being
created, before its first log line (docs/reliability.md: two loaded integration runs and an
idle fresh clone failed so). Fast DDS's own ``fastdds shm clean`` removes ports whose lock file
nobody holds; such a port may have no lock file at all. A port being created is unsized for
microseconds, so one older than a minute is a dead process's. Every node removes such files
before it starts DDS (``node_tools.run_node``).
"""
from __future__ import annotations

import re
import sys
import time
from pathlib import Path

SHM = Path("/dev/shm")
MIN_AGE = 60.0  # [s] an unsized port older than this belongs to no live process
# The port segment itself; its lock files (``_el``, ``_sl``) are empty by design and must stay.
PORT_NAME = re.compile(r"fastrtps_port\d+")


def remove_unsized_ports(shm: Path = SHM, min_age: float = MIN_AGE) -> list[Path]:
    """Remove port segments (``fastrtps_portN``) of size 0 older than ``min_age`` seconds, with
    their mutex (``sem.fastrtps_portN_mutex``); return the ports removed. Lock files, files that
    vanish meanwhile and files of another user are left alone."""
    removed = []
    now = time.time()
    for port in sorted(shm.glob("fastrtps_port*")):
        if not PORT_NAME.fullmatch(port.name):
            continue
        try:
            info = port.stat()
            if info.st_size != 0 or now - info.st_mtime <= min_age:
                continue
            port.unlink()
            (shm / f"sem.{port.name}_mutex").unlink(missing_ok=True)
        except OSError:
            continue
        removed.append(port)
    return removed


def clear_dead_ports(prefix: str, shm: Path = SHM) -> list[Path]:
    """:func:`remove_unsized_ports`, each removal said on stderr after ``prefix`` (who removed
    it); return the ports removed."""
    removed = remove_unsized_ports(shm)
    for port in removed:
        print(f"{prefix} removed {port}: an unsized Fast DDS port file a dead process left",
              file=sys.stderr)
    return removed
