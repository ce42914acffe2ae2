"""YAML files of wings, absorbers and typical sections (load, validate, save).

A wing file holds::

    wing:            # WingParameters fields, SI units
      mass: 1000.0
      ...
    air_density: 1.2            # [kg/m^3] default flight condition
    aero: quasi-steady          # or wagner / theodorsen
    pitch_damping: thin_airfoil # quasi-steady only (see aerodynamics.py)
    absorber:                   # optional default absorber
      type: maxwell             # or passive
      mass: 40.0
      ...

A typical-section file holds the keys of
:class:`~aero_dva.wing.typical_section.TypicalSection` at the top level.
Unknown keys are errors (they are usually typos).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from aero_dva import input_ranges as ranges
from aero_dva.data_files import data_file
from aero_dva.safe_files import read_yaml
from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber
from aero_dva.wing.aerodynamics import QuasiSteadyAero, aero_from_name
from aero_dva.wing.model import WingParameters
from aero_dva.wing.typical_section import TypicalSection

__all__ = [
    "DEFAULT_WING",
    "WingConfig",
    "absorber_from_dict",
    "absorber_to_dict",
    "default_wing_path",
    "load_section",
    "load_wing",
    "reference_wing_path",
    "save_wing",
    "wing_fingerprint",
]

_ABSORBERS = {"passive": PassiveAbsorber, "maxwell": MaxwellAbsorber}
#: The wing every tool and node flies unless told otherwise: the chapter-6 wing, which
#: reproduces every critical-airspeed ratio of the study's tables 6.1-6.3 and section 6.3.2
#: within 0.013 with every ordering right (docs/wing.md). The earlier reference wing stays as
#: a file for comparison (:func:`reference_wing_path`).
DEFAULT_WING = "chapter6_wing.yaml"


@dataclass(frozen=True)
class WingConfig:
    """Contents of a wing file."""

    wing: WingParameters
    air_density: float = 1.2
    aero: object = field(default_factory=QuasiSteadyAero)
    absorber: PassiveAbsorber | MaxwellAbsorber | None = None

    @property
    def maxwell_design(self) -> MaxwellAbsorber:
        """The file's absorber, which must be a Maxwell DVA (the simulator's default)."""
        if not isinstance(self.absorber, MaxwellAbsorber):
            raise ValueError("the wing file has no Maxwell absorber (absorber: type: maxwell)")
        return self.absorber


def default_wing_path() -> Path:
    """Path of the packaged default wing, the chapter-6 wing (:data:`DEFAULT_WING`)."""
    return data_file(DEFAULT_WING)


def reference_wing_path() -> Path:
    """Path of the packaged reference wing, the first calibration (kept for comparison)."""
    return data_file("reference_wing.yaml")


def _fields(cls, data: dict, where: str) -> dict:
    if not isinstance(data, dict):
        raise ValueError(f"{where} must be a mapping")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; expected some of {sorted(names)}")
    missing = sorted(
        f.name for f in dataclasses.fields(cls)
        if f.name not in data and f.default is dataclasses.MISSING
    )
    if missing:
        raise ValueError(f"{where}: missing key(s) {missing}")
    return data


def _build(cls, data: dict, where: str):
    try:
        return cls(**_fields(cls, data, where))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None


def absorber_from_dict(data: dict | None):
    """An absorber from ``{"type": "passive"|"maxwell", ...fields}`` (None -> None)."""
    if data is None:
        return None
    if not isinstance(data, dict) or "type" not in data:
        raise ValueError("absorber must be a mapping with a 'type' (passive or maxwell)")
    kind = data["type"]
    if kind not in _ABSORBERS:
        raise ValueError(f"absorber type must be one of {sorted(_ABSORBERS)}, got {kind!r}")
    rest = {k: v for k, v in data.items() if k != "type"}
    if kind == "maxwell" and isinstance(rest.get("damping"), str):
        try:
            rest["damping"] = float(rest["damping"])  # allow "inf"
        except ValueError:
            raise ValueError(f"absorber ({kind}): damping must be a number or inf, got "
                             f"{rest['damping']!r}") from None
    ranges.check_fields(rest, ranges.ABSORBER, f"absorber ({kind})")
    return _build(_ABSORBERS[kind], rest, f"absorber ({kind})")


def absorber_to_dict(absorber) -> dict | None:
    """Inverse of :func:`absorber_from_dict`."""
    if absorber is None:
        return None
    kind = "maxwell" if isinstance(absorber, MaxwellAbsorber) else "passive"
    return {"type": kind, **dataclasses.asdict(absorber)}


def config_from_dict(data: dict, where: str = "wing file") -> WingConfig:
    """Validate a parsed wing file."""
    if not isinstance(data, dict) or "wing" not in data:
        raise ValueError(f"{where} must be a mapping with a 'wing' section")
    allowed = {"wing", "air_density", "aero", "pitch_damping", "absorber"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; expected some of {sorted(allowed)}")
    if isinstance(data["wing"], dict):
        ranges.check_fields(data["wing"], ranges.WING, f"{where}: wing")
    wing = _build(WingParameters, data["wing"], f"{where}: wing")
    rho = ranges.check_number(data.get("air_density", 1.2), "air_density", ranges.AIR_DENSITY)
    aero = aero_from_name(data.get("aero", "quasi-steady"))
    if "pitch_damping" in data:
        if not isinstance(aero, QuasiSteadyAero):
            raise ValueError(f"{where}: pitch_damping applies to quasi-steady aero only")
        aero = QuasiSteadyAero(pitch_damping=data["pitch_damping"])
    absorber = absorber_from_dict(data.get("absorber"))
    if absorber is not None:
        wing.check_on_chord(absorber.position, "absorber position")
    return WingConfig(wing, rho, aero, absorber)


def load_wing(path=None) -> WingConfig:
    """Read a wing file (default: the chapter-6 wing, :func:`default_wing_path`)."""
    path = Path(default_wing_path() if path is None else path)
    data = _read_yaml(path, "wing file")
    try:
        return config_from_dict(data, str(path))
    except (TypeError, ValueError) as exc:
        if str(path) in str(exc):
            raise
        raise ValueError(f"wing file {str(path)!r}: {exc}") from None


def _read_yaml(path: Path, what: str):
    return read_yaml(path, what)



def save_wing(path, config: WingConfig) -> None:
    """Write ``config`` as a wing file."""
    data = {"wing": dataclasses.asdict(config.wing), "air_density": config.air_density,
            "aero": config.aero.name}
    if isinstance(config.aero, QuasiSteadyAero):
        data["pitch_damping"] = config.aero.pitch_damping
    if config.absorber is not None:
        data["absorber"] = absorber_to_dict(config.absorber)
    with open(path, "w", encoding="utf-8") as fh:
        yaml.safe_dump(data, fh, sort_keys=False)


def wing_fingerprint(config: WingConfig) -> str:
    """A short hash of everything in a wing file that the flight depends on (wing, density,
    aerodynamics, absorber): two files with the same fingerprint fly the same wing."""
    data = {"wing": dataclasses.asdict(config.wing), "air_density": config.air_density,
            "aero": config.aero.name, "absorber": absorber_to_dict(config.absorber)}
    if isinstance(config.aero, QuasiSteadyAero):
        data["pitch_damping"] = config.aero.pitch_damping
    text = json.dumps(data, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def load_section(path) -> TypicalSection:
    """Read a typical-section file (keys of :class:`TypicalSection`)."""
    data = _read_yaml(Path(path), "section file")
    if isinstance(data, dict):
        ranges.check_fields(data, ranges.SECTION, str(path))
    return _build(TypicalSection, data, str(path))
