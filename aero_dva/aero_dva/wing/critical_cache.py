"""The bare wing's critical airspeed, kept on disk between processes.

A scenario states its airspeeds relative to U_cr of the wing without DVA, as the study does, so
every process that flies one needs U_cr before its first sample. The flutter search imports
scipy (LAPACK's ``dgeev``, ``brentq``), which costs a node process more CPU than the rest of its
start (docs/performance.md), and its answer depends on nothing but the wing, the density, the
aerodynamics and the code. :func:`critical_airspeed` returns the number
:func:`~aero_dva.wing.flutter.bare_critical_airspeed` gives, kept in a small file named by a hash
of all of them: every input's exact bits, the source of the wing layer (the model and the
search) and the numpy and scipy releases. A changed input, model or search gets a new name, so a
kept number is never a stale one; a missing, unreadable or foreign file is computed again and
rewritten.

The directory is ``$DVA_CACHE_DIR``, else ``$XDG_CACHE_HOME/aero-dva``, else
``~/.cache/aero-dva``; where it cannot be written, every call searches (as without the cache).
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import math
import os
from pathlib import Path

import numpy as np

__all__ = ["cache_dir", "critical_airspeed", "entry_path"]

FORMAT = "aero_dva critical airspeed v1"
WING_LAYER = Path(__file__).resolve().parent


def cache_dir() -> Path:
    """Where the kept numbers are (module docstring)."""
    if os.environ.get("DVA_CACHE_DIR"):
        return Path(os.environ["DVA_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "aero-dva"


@functools.cache
def _code_fingerprint() -> str:
    """Hash of the wing layer's source and of the numpy and scipy releases."""
    digest = hashlib.sha256(np.__version__.encode())
    spec = importlib.util.find_spec("scipy")  # finds, does not import
    scipy_version = Path(spec.origin).parent / "version.py" if spec and spec.origin else None
    digest.update(scipy_version.read_bytes() if scipy_version and scipy_version.is_file()
                  else b"no scipy")
    for path in sorted(WING_LAYER.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _exact(value) -> object:
    """A value with every float written exactly (hex), for hashing."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [type(value).__name__, *((f.name, _exact(getattr(value, f.name)))
                                        for f in dataclasses.fields(value))]
    if isinstance(value, (float, np.floating)):
        return float(value).hex()
    if isinstance(value, (list, tuple)):
        return [_exact(v) for v in value]
    return repr(value)


def entry_path(wing, density: float, aero=None) -> Path:
    """The file that keeps U_cr of ``wing`` at ``density`` with ``aero`` (None: quasi-steady)."""
    key = repr([FORMAT, _code_fingerprint(), _exact(wing), _exact(float(density)),
                _exact(aero)])
    return cache_dir() / f"critical_airspeed_{hashlib.sha256(key.encode()).hexdigest()[:32]}"


def critical_airspeed(wing, density: float, aero=None) -> float:
    """U_cr [m/s] of ``wing`` without DVA at ``density`` (the flutter search's number, kept)."""
    path = entry_path(wing, density, aero)
    try:
        head, value = path.read_text().split("\n")[:2]
        if head == FORMAT:
            kept = float.fromhex(value)
            if math.isfinite(kept) and kept > 0:
                return kept
    except (OSError, ValueError):
        pass  # not kept yet, or unreadable: search again
    from aero_dva.wing.flutter import bare_critical_airspeed

    u_cr = bare_critical_airspeed(wing, density, aero)
    try:
        from aero_dva.atomic_io import atomic_output

        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_output(path) as stream:
            stream.write(f"{FORMAT}\n{float(u_cr).hex()}\n")
    except OSError:
        pass  # a read-only home: the next process searches too
    return u_cr
