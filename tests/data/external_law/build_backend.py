"""A PEP 517 build backend that needs nothing but the standard library: it zips the package
and its metadata into a wheel, so ``pip install --no-build-isolation --no-index`` installs this
example offline (the project's venv has no ``wheel`` for setuptools' backend)."""
from __future__ import annotations

import base64
import hashlib
import zipfile
from pathlib import Path

import tomllib

HERE = Path(__file__).parent


def _project() -> dict:
    return tomllib.loads((HERE / "pyproject.toml").read_text())["project"]


def _metadata() -> dict[str, str]:
    """dist-info file name -> text."""
    project = _project()
    groups = project.get("entry-points", {})
    entry_points = "".join(f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items())
                           for group, eps in groups.items())
    return {"METADATA": f"Metadata-Version: 2.1\nName: {project['name']}\n"
                        f"Version: {project['version']}\nSummary: {project['description']}\n",
            "WHEEL": "Wheel-Version: 1.0\nGenerator: build_backend.py\nRoot-Is-Purelib: true\n"
                     "Tag: py3-none-any\n",
            "entry_points.txt": entry_points}


def get_requires_for_build_wheel(config_settings=None) -> list[str]:
    return []


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None) -> str:
    project = _project()
    name = project["name"].replace("-", "_")
    info = f"{name}-{project['version']}.dist-info"
    files = {str(p.relative_to(HERE)): p.read_bytes()
             for p in sorted((HERE / "dva_law_example").rglob("*.py"))}
    files.update({f"{info}/{k}": v.encode() for k, v in _metadata().items()})
    record = []
    for path, data in files.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        record.append(f"{path},sha256={digest},{len(data)}")
    record.append(f"{info}/RECORD,,")
    wheel = f"{name}-{project['version']}-py3-none-any.whl"
    with zipfile.ZipFile(Path(wheel_directory) / wheel, "w") as archive:
        for path, data in files.items():
            archive.writestr(path, data)
        archive.writestr(f"{info}/RECORD", "\n".join(record) + "\n")
    return wheel
