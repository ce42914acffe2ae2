"""JSON file of the switching c2 law's gains, written by `dva control switching-design`.

What the damper's controller needs (law gain, observer gain, c2 levels, the wing it was
designed for) plus how the design was chosen. Checked on load: format, version, units, every
number finite, shapes consistent, 0 < c_lo < c_hi; the wing fingerprint lets a user refuse a
file made for another wing. c_lo and c_hi must lie inside the damper's range (by default
:data:`~aero_dva.flight.damper.DAMPER_RANGE`; a flight checks its own damper's): such a file
is neither written nor read. A law scheduled with the airspeed (the clipped-optimal law,
design ``clipped_optimal``) has ``airspeeds`` [m/s] and one row of ``gain`` (and of
``force_gain``) per airspeed; the others have neither and one row. Example (abridged)::

    {"format": "dva_switching_gains", "version": 1, "design": "lyapunov",
     "wing_fingerprint": "3f0c...", "design_airspeed": 115.0, "density": 1.2,
     "c_lo": 150.0, "c_hi": 2500.0, "time_constant": 0.01, "sample_rate": 1000.0,
     "effort": 100.0, "lead": 0.011, "state_names": [...], "gain": [...],
     "observer": [[...], ...], "force_gain": [...],
     "units": {...}, "selection": [...], "description": "..."}
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aero_dva import input_ranges as ranges
from aero_dva.atomic_io import atomic_output
from aero_dva.flight.damper import DAMPER_RANGE, SWITCHING_SOURCE, damping_problem
from aero_dva.flight.per_sample.switching_law import (
    DESIGNS,
    MEASURED_OUTPUTS,
    SCHEDULED_DESIGN,
    SwitchingLaw,
)
from aero_dva.safe_files import check_file_header, parse_json
from aero_dva.text_input import read_text_input

__all__ = ["FILE_FORMAT", "FILE_VERSION", "UNITS", "SwitchingGains", "SwitchingGainsError",
           "clipped_optimal_law", "gains_from_dict", "gains_to_dict", "gains_problem",
           "load_gains", "save_gains", "supervised_law", "with_per_sample", "with_switching"]

FILE_FORMAT = "dva_switching_gains"
FILE_VERSION = 1
UNITS = {"airspeed": "m/s", "density": "kg/m^3", "damping": "N s/m", "time_constant": "s",
         "sample_rate": "Hz", "measured": list(MEASURED_OUTPUTS)}
_NUMBERS = ("design_airspeed", "density", "c_lo", "c_hi", "time_constant", "sample_rate",
            "effort", "lead")


class SwitchingGainsError(ValueError):
    """A switching-gains file is missing, unreadable or invalid."""


@dataclass(frozen=True)
class SwitchingGains:
    """The contents of a gains file (see the module docstring)."""

    law: SwitchingLaw
    design: str
    wing_fingerprint: str
    design_airspeed: float
    density: float
    time_constant: float
    sample_rate: float
    effort: float
    state_names: tuple
    lead: float = 0.0
    selection: list = field(default_factory=list)
    description: str = ""


def gains_to_dict(g: SwitchingGains) -> dict:
    """The JSON object of ``g``; SwitchingGainsError when its c2 levels leave the damper's
    default range."""
    problem = damping_problem((g.law.c_lo, g.law.c_hi), "switching gains c_lo and c_hi")
    if problem is not None:
        raise SwitchingGainsError(problem)
    scheduled = {} if not g.law.scheduled else {"airspeeds": g.law.airspeeds.tolist()}
    return {
        "format": FILE_FORMAT, "version": FILE_VERSION, "design": g.design,
        "wing_fingerprint": g.wing_fingerprint, "design_airspeed": g.design_airspeed,
        "density": g.density, "c_lo": g.law.c_lo, "c_hi": g.law.c_hi,
        "time_constant": g.time_constant, "sample_rate": g.sample_rate, "effort": g.effort,
        "lead": g.lead, "state_names": list(g.state_names), "gain": g.law.gain.tolist(),
        "observer": None if g.law.observer is None else g.law.observer.tolist(),
        "force_gain": None if g.law.force_gain is None else g.law.force_gain.tolist(),
        "units": dict(UNITS), "selection": g.selection, "description": g.description,
        **scheduled,
    }


def gains_from_dict(data, source: str = "<dict>",
                    damping_range=DAMPER_RANGE) -> SwitchingGains:
    """Validate a JSON object; errors name ``source`` and the field. ``c_lo`` and ``c_hi``
    must lie inside ``damping_range`` [N s/m], the damper's."""

    def fail(what: str) -> SwitchingGainsError:
        return SwitchingGainsError(f"switching gains {source}: {what}")

    check_file_header(data, fail, FILE_FORMAT, FILE_VERSION, UNITS)
    if data.get("design") not in DESIGNS:
        raise fail(f"design {data.get('design')!r} is not one of {list(DESIGNS)}")
    values = {}
    for key in _NUMBERS:
        value = data.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise fail(f"field {key!r} must be a number, got {type(value).__name__}")
        if not math.isfinite(value):
            raise fail(f"field {key!r} must be finite, got {value}")
        values[key] = float(value)
    try:
        ranges.check_fields(values, ranges.GAINS)
        for key, rng in ranges.GAIN_ROWS.items():
            if data.get(key) is not None:
                ranges.check_numbers(data[key], key, rng)
    except ValueError as exc:
        raise fail(str(exc)) from None
    names = data.get("state_names")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise fail("field 'state_names' must be a list of strings")
    if "maxwell_deflection" not in names:
        raise fail("field 'state_names' has no 'maxwell_deflection' (not a Maxwell DVA)")
    if not isinstance(data.get("wing_fingerprint"), str):
        raise fail("field 'wing_fingerprint' must be a string")
    try:
        gain = np.array(data.get("gain"), dtype=float)
        observer = data.get("observer")
        observer = None if observer is None else np.array(observer, dtype=float)
        force_gain = data.get("force_gain")
        force_gain = None if force_gain is None else np.array(force_gain, dtype=float)
        airspeeds = data.get("airspeeds")
        airspeeds = None if airspeeds is None else np.array(airspeeds, dtype=float)
    except (TypeError, ValueError):
        raise fail("fields 'gain', 'observer', 'force_gain' and 'airspeeds' must be "
                   "numbers") from None
    scheduled = data["design"] == SCHEDULED_DESIGN
    if scheduled != (airspeeds is not None):
        raise fail(f"field 'airspeeds' is required with design {SCHEDULED_DESIGN!r} and only "
                   "with it")
    rows = () if airspeeds is None else airspeeds.shape
    if gain.shape != (*rows, len(names)):
        raise fail(f"field 'gain' must have {len(names)} entries (one per state"
                   f"{f', in each of {rows[0]} rows, one per airspeed' if rows else ''}), "
                   f"got shape {gain.shape}")
    problem = damping_problem((values["c_lo"], values["c_hi"]), "fields 'c_lo' and 'c_hi'",
                              damping_range)
    if problem is not None:
        raise fail(problem)
    try:
        law = SwitchingLaw(gain, values["c_lo"], values["c_hi"], observer, force_gain,
                           airspeeds)
    except ValueError as exc:
        raise fail(str(exc)) from None
    selection = data.get("selection", [])
    description = data.get("description", "")
    if not isinstance(selection, list) or not isinstance(description, str):
        raise fail("'selection' must be a list and 'description' a string")
    return SwitchingGains(law=law, design=data["design"],
                          wing_fingerprint=data["wing_fingerprint"],
                          design_airspeed=values["design_airspeed"], density=values["density"],
                          time_constant=values["time_constant"],
                          sample_rate=values["sample_rate"], effort=values["effort"],
                          lead=values["lead"],
                          state_names=tuple(names), selection=selection,
                          description=description)


def save_gains(gains: SwitchingGains, path) -> Path:
    """Write ``gains`` as JSON, atomically. Returns the path."""
    text = json.dumps(gains_to_dict(gains), indent=2, allow_nan=False)
    path = Path(path)
    with atomic_output(path) as stream:
        stream.write(text + "\n")
    return path


def load_gains(path, damping_range=DAMPER_RANGE) -> SwitchingGains:
    """Read and validate a gains file (:class:`SwitchingGainsError` naming what is wrong);
    its c2 levels must lie inside ``damping_range`` [N s/m]."""
    path = Path(path)
    text = read_text_input(path, "switching gains", error=SwitchingGainsError)
    data = parse_json(text, f"switching gains {str(path)!r}", SwitchingGainsError,
                      nonfinite=True)  # each field is checked by name
    return gains_from_dict(data, repr(str(path)), damping_range)


def supervised_law(values) -> SwitchingGains:
    """The ``switching`` controller's law (its table entry's loader): the gains of the
    parameter ``gains_file`` (empty: the package's file), read and checked
    (:class:`SwitchingGainsError`, a ValueError, naming what is wrong); a law at one airspeed
    (design lyapunov or clipped)."""
    return _law_of(values, "switching_gains.json", DESIGNS[:2], "switching")


def clipped_optimal_law(values) -> SwitchingGains:
    """The ``clipped_optimal`` controller's law (its table entry's loader): as
    :func:`supervised_law`, a law scheduled with the airspeed (design clipped_optimal; the
    package's file ``clipped_optimal_gains.json`` by default)."""
    return _law_of(values, "clipped_optimal_gains.json", (SCHEDULED_DESIGN,), "clipped_optimal")


def _law_of(values, default_file: str, designs, controller: str) -> SwitchingGains:
    from aero_dva.data_files import data_file

    path = values.get("gains_file") or data_file(default_file)
    gains = load_gains(path)
    if gains.design not in designs:
        raise SwitchingGainsError(
            f"switching gains {str(path)!r} are of design {gains.design!r}; the {controller} "
            f"controller flies {' or '.join(designs)}")
    return gains


def with_per_sample(config, source: str, path: str, wing: str | None = None, load=None):
    """A flight's ``config`` (:class:`~aero_dva.flight.flight_runtime.RuntimeConfig`) with the
    gains from ``path`` of the per-sample law that commands from ``source`` arm, for the
    damper's own controller, or with the reason the law cannot run: no file, an invalid one
    (:class:`SwitchingGainsError`'s text, or ``load``'s: the controller's own loader, which
    checks the design), one made for another wing (its fingerprint; ``wing`` the flight's wing
    file, None the package's), or a flight whose absorber is not the wing file's. Not fatal:
    the damper then holds the commands' constant c2 and says why when the law is asked for."""
    import dataclasses

    from aero_dva.wing.wing_io import load_wing, wing_fingerprint

    def set_to(value):
        return dataclasses.replace(config, per_sample={**config.per_sample, source: value})

    if not path:
        return set_to(f"no gains file for the {source} law")
    gains, text = _read_gains(path, config.damper.damping_range, load)
    if gains is None:
        return set_to(text)
    wing_file = load_wing(wing or None)
    design, absorber = wing_file.maxwell_design, config.absorber
    if absorber is None or (absorber.mass, absorber.stiffness, absorber.series_stiffness,
                            absorber.position) != (design.mass, design.stiffness,
                                                   design.series_stiffness, design.position):
        return set_to("the switching gains are for the wing file's own Maxwell absorber")
    text = wing_problem(gains, path, wing_fingerprint(wing_file), _state_names(config))
    return set_to(gains if text is None else text)


def with_switching(config, path: str, wing: str | None = None):
    """:func:`with_per_sample` for the switching law (commands of the source
    ``"switching"``)."""
    return with_per_sample(config, SWITCHING_SOURCE, path, wing, supervised_law_file)


def supervised_law_file(path) -> SwitchingGains:
    """The switching controller's loader of one file (:func:`supervised_law`)."""
    return supervised_law({"gains_file": str(path)})


def gains_problem(path, wing: str | None = None, load=None) -> str | None:
    """Why the gains file ``path`` cannot serve the wing file ``wing`` (None: the package's),
    or None: the same texts as :func:`with_per_sample` (for a node that only supervises);
    ``load`` the controller's loader of a file (default :func:`load_gains`)."""
    from aero_dva.wing.wing_io import load_wing, wing_fingerprint

    gains, text = _read_gains(path, DAMPER_RANGE, load)
    if gains is None:
        return text
    return wing_problem(gains, path, wing_fingerprint(load_wing(wing or None)))


def wing_problem(gains: SwitchingGains, path, fingerprint: str,
                 state_names=None) -> str | None:
    """Why ``gains`` (read from ``path``) do not belong to the wing of ``fingerprint`` and,
    when given, these ``state_names``; None when they do."""
    if gains.wing_fingerprint != fingerprint:
        return (f"switching gains {str(path)!r} were designed for another wing (fingerprint "
                f"{gains.wing_fingerprint}, this wing's {fingerprint})")
    if state_names is not None and tuple(gains.state_names) != tuple(state_names):
        return (f"switching gains {str(path)!r}: states {list(gains.state_names)} are not the "
                "flown wing's")
    return None


def _read_gains(path, damping_range=DAMPER_RANGE, load=None
                ) -> tuple[SwitchingGains | None, str | None]:
    try:
        gains = load_gains(path, damping_range)
        if load is not None:  # the controller's own checks (its design)
            gains = load(path)
        return gains, None
    except SwitchingGainsError as exc:
        return None, f"invalid switching gains: {exc}"


def _state_names(config) -> tuple:
    from aero_dva.wing.model import AeroelasticModel

    return AeroelasticModel(config.wing, config.absorber, config.aero).state_names
