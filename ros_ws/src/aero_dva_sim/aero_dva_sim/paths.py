"""Where the package's data files are: the source tree (also what a symlink install points at),
else the installed share directory."""
from __future__ import annotations

from pathlib import Path

PACKAGE = "aero_dva_sim"


def config_dir() -> Path:
    """The package's ``config/`` directory (scenarios, reference wing)."""
    source = Path(__file__).resolve().parent.parent / "config"
    if source.is_dir():
        return source
    try:  # a regular (copying) install: share/aero_dva_sim/config; ament_index is pure Python
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(PACKAGE)) / "config"
    except (ImportError, LookupError, OSError):
        return source


def config_file(name: str) -> Path:
    """A file of the package's ``config/`` directory; FileNotFoundError names where it looked."""
    path = config_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"no {name} in {path.parent}")
    return path
