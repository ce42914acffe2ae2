"""Write files so that a reader never sees half of one: temporary file + rename."""
from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def atomic_output(path, mode: str = "w", *, fsync: bool = False) -> Iterator:
    """Open a temporary file beside ``path``; on success it replaces ``path`` (mode 0644),
    on failure it is removed and ``path`` is untouched. ``fsync`` puts the data on the disk
    before the rename (for a file that marks something else complete, like a bag's
    metadata.yaml)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as stream:
            yield stream
            if fsync:
                stream.flush()
                os.fsync(stream.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; these files are meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
