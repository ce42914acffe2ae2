"""Files shipped with the package: the wing files and the scenarios (``aero_dva/data/``)."""
from __future__ import annotations

from pathlib import Path

DATA_DIR = Path(__file__).resolve().parent / "data"


def data_file(name: str) -> Path:
    """A file of ``aero_dva/data/`` by name; FileNotFoundError names where it looked."""
    path = DATA_DIR / name
    if not path.is_file():
        raise FileNotFoundError(f"no {name} in {DATA_DIR}")
    return path
