"""Records of the in-process evaluation saved job by job, so an interrupted ``dva evaluate``
resumes where it stopped (``DIR/flights``).

One JSON file per (case, seed) job holds its records; ``settings.json`` holds what the records
depend on (scenario, controllers, cases, RMS range, fixed c2, schedule and network files). A
directory written with other settings is refused rather than mixed.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from aero_dva.atomic_io import atomic_output
from dva_offline.evaluation.paired import FlightRecord

__all__ = ["FlightStore"]


class FlightStore:
    def __init__(self, directory: Path, settings: dict):
        self.directory = Path(directory)
        self.settings = json.loads(json.dumps(settings))  # as it reads back

    def _path(self, case: str, seed: int) -> Path:
        return self.directory / f"{case}_seed{seed}.json"

    def load(self, seeds) -> dict[tuple[str, int], list[FlightRecord]]:
        """The jobs already flown with these settings (creates the directory)."""
        settings_file = self.directory / "settings.json"
        if settings_file.is_file():
            saved = json.loads(settings_file.read_text())
            if saved != self.settings:
                changed = sorted(k for k in set(saved) | set(self.settings)
                                 if saved.get(k) != self.settings.get(k))
                raise ValueError(f"{self.directory} holds flights flown with other settings "
                                 f"({', '.join(changed)}); use another --out")
        else:
            self.directory.mkdir(parents=True, exist_ok=True)
            with atomic_output(settings_file) as f:
                json.dump(self.settings, f, indent=1)
        done = {}
        for case in self.settings["cases"]:
            for seed in seeds:
                path = self._path(case["case"], seed)
                if path.is_file():
                    done[(case["case"], seed)] = [_record(r)
                                                  for r in json.loads(path.read_text())]
        return done

    def save(self, key: tuple[str, int], records: list[FlightRecord]) -> None:
        with atomic_output(self._path(*key)) as f:
            json.dump([r.to_dict() for r in records], f, allow_nan=False)


def _record(row: dict) -> FlightRecord:
    """A saved record (its NaN numbers saved as null)."""
    floats = {f.name for f in dataclasses.fields(FlightRecord) if f.type == "float"}
    return FlightRecord(**{k: (math.nan if k in floats and v is None else v)
                           for k, v in row.items()})
