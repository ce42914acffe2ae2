"""Scenario files (YAML) <-> :class:`aero_dva.flight.scenario.Scenario`.

Format (every key optional except ``duration`` and ``airspeed``; SI units)::

    name: ramp_flight
    duration: 30.0               # [s]
    sample_rate: 1000.0          # [Hz]
    block_size: 20               # samples per published block
    airspeed:                    # m/s keys (start, end, value, values) or ratio keys of U_ref
      kind: ramp                 # constant | ramp | steps
      start_ratio: 0.8           # (ramp) or start: 80.0 [m/s]
      end_ratio: 1.2
      # constant: value: 90.0 | value_ratio: 1.0
      # steps: values: [...] | ratios: [...] | start_ratio/end_ratio/step_ratio
    density: {base: 1.2, variation: 0.05, frequency: 1.0}   # eq. 7.2: mu = variation, f [Hz]
    excitation: {force_std: 1000.0, seed: 1}                # [N], seed of default_rng
    # optional: levels: [1.0, 3.0], level_dwell: 8.0  (force_std multipliers held in turn)
    sweep: {dwell: 2.0, damping: [0.0, 100.0, ...]}         # steps only: c2 values [N s/m]
    plant:                       # optional hidden plant effects (aero_dva.flight.hidden_plant)
      actuator_lag: {time_constant: 0.8}                 # [s] first-order lag of c2
      sensor_delay: {delay: 0.004}                       # [s] accelerometers delayed
      cubic_stiffness: {kappa: 1.0e5}                    # [1/rad^2] k_alpha (a + kappa a^3)
      unsteady_aero: {scale: 1.0}                        # Wagner/Jones lag, amplitudes x scale
      drift: {parameter: pitch_stiffness, rate: -0.003}  # [1/s] p(t) = p0 (1 + rate t)
      sensor_noise: {plunge: 0.5, pitch: 0.2, leading_edge: 0.5}  # accelerometer noise std
      sensor_gain: {plunge: 1.0, pitch: 1.05, leading_edge: 1.0}  # calibration factors

For ``steps``, ``duration: auto`` takes the sweep length. Nothing recorded names the plant
options: they are what a model-discrepancy analysis has to find.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aero_dva.flight.hidden_plant import CHANNELS, PlantOptions
from aero_dva.flight.scenario import (
    AirspeedProfile,
    Scenario,
    ScenarioError,
    sweep_duration,
)
from aero_dva.safe_files import read_yaml

_TOP_KEYS = {"name", "duration", "sample_rate", "block_size", "airspeed", "density", "excitation",
             "sweep", "plant"}
# plant section: effect -> (its keys, the PlantOptions field each key sets)
_PLANT_KEYS = {
    "actuator_lag": {"time_constant": "actuator_lag"},
    "sensor_delay": {"delay": "sensor_delay"},
    "cubic_stiffness": {"kappa": "cubic_stiffness"},
    "unsteady_aero": {"scale": "unsteady_aero"},
    "drift": {"parameter": "drift_parameter", "rate": "drift_rate"},
    "sensor_noise": {ch: None for ch in CHANNELS},
    "sensor_gain": {ch: None for ch in CHANNELS},
}


def _number(section: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"{section}.{key} must be a number, got {value!r}")
    return float(value)


#: Most airspeed steps of one scenario (a sweep has tens; more is a typo in the step).
MAX_STEPS = 10_000


def _airspeed(raw: Any) -> AirspeedProfile:
    if not isinstance(raw, dict) or "kind" not in raw:
        raise ScenarioError("airspeed must be a mapping with a 'kind' (constant, ramp or steps)")
    kind = raw["kind"]
    relative = any(str(key).endswith("ratio") or key == "ratios" for key in raw)
    absolute = any(key in raw for key in ("value", "start", "end", "values"))
    if relative and absolute:
        raise ScenarioError("airspeed mixes m/s keys and *_ratio keys; use one kind of unit")
    suffix = "_ratio" if relative else ""
    if kind == "constant":
        values = (_number("airspeed", "value" + suffix, raw.get("value" + suffix)),)
    elif kind == "ramp":
        values = tuple(
            _number("airspeed", k + suffix, raw.get(k + suffix)) for k in ("start", "end")
        )
    elif kind == "steps":
        listed = raw.get("ratios" if relative else "values")
        if listed is not None:
            if not isinstance(listed, list):
                raise ScenarioError(f"airspeed steps must be a list of numbers, got {listed!r}"
                                    [:160])
            values = tuple(_number("airspeed", "values", v) for v in listed)
        else:
            start, end, step = (_number("airspeed", k + suffix, raw.get(k + suffix))
                                for k in ("start", "end", "step"))
            if step <= 0 or end < start:
                raise ScenarioError("airspeed steps need step > 0 and end >= start")
            count = (end - start) / step + 1
            if not count <= MAX_STEPS:
                raise ScenarioError(f"airspeed steps from {start:g} to {end:g} by {step:g} make "
                                    f"{count:.3g} steps; at most {MAX_STEPS} are flown")
            count = int(np.floor((end - start) / step + 1e-9)) + 1
            values = tuple(float(v) for v in start + step * np.arange(count))
    else:
        raise ScenarioError(f"airspeed.kind must be constant, ramp or steps, got {kind!r}")
    return AirspeedProfile(kind, values, relative=relative)


def _plant(raw: Any) -> PlantOptions | None:
    """The ``plant`` section -> :class:`PlantOptions` (None when absent or empty)."""
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise ScenarioError("plant must be a mapping of effects, e.g. "
                            "{actuator_lag: {time_constant: 0.5}}")
    unknown = set(raw) - set(_PLANT_KEYS)
    if unknown:
        raise ScenarioError(f"unknown plant effects {sorted(unknown)}; known: "
                            f"{sorted(_PLANT_KEYS)}")
    fields: dict[str, Any] = {}
    for effect, section in raw.items():
        keys = _PLANT_KEYS[effect]
        if not isinstance(section, dict):
            raise ScenarioError(f"plant.{effect} must be a mapping with keys {sorted(keys)}")
        bad = set(section) - set(keys)
        if bad:
            raise ScenarioError(f"unknown keys {sorted(bad)} in plant.{effect}; known: "
                                f"{sorted(keys)}")
        if effect in ("sensor_noise", "sensor_gain"):
            default = 0.0 if effect == "sensor_noise" else 1.0
            fields[effect] = tuple(
                _number(f"plant.{effect}", ch, section.get(ch, default)) for ch in CHANNELS)
            continue
        for key, target in keys.items():
            if key not in section:
                raise ScenarioError(f"plant.{effect} needs '{key}'")
            value = section[key]
            fields[target] = (str(value) if key == "parameter"
                              else _number(f"plant.{effect}", key, value))
    try:
        return PlantOptions(**fields)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None


def _section(raw: dict, key: str) -> dict:
    """The optional mapping ``raw[key]`` (empty when absent)."""
    section = raw.get(key) or {}
    if not isinstance(section, dict):
        raise ScenarioError(f"{key} must be a mapping, got {section!r}"[:160])
    return section


def _list(section: dict, name: str, key: str) -> list:
    """The optional list ``section[key]`` (empty when absent)."""
    values = section.get(key) or []
    if not isinstance(values, list):
        raise ScenarioError(f"{name}.{key} must be a list of numbers, got {values!r}"[:160])
    return values


def scenario_from_dict(raw: Any, default_name: str = "scenario") -> Scenario:
    """Build and validate a :class:`Scenario` from parsed YAML; errors name the bad key."""
    if not isinstance(raw, dict):
        raise ScenarioError("a scenario file must contain a mapping at the top level")
    unknown = set(raw) - _TOP_KEYS
    if unknown:
        raise ScenarioError(f"unknown scenario keys {sorted(unknown)}; known: {sorted(_TOP_KEYS)}")
    if "airspeed" not in raw:
        raise ScenarioError("scenario needs an 'airspeed' section")
    airspeed = _airspeed(raw["airspeed"])
    density = _section(raw, "density")
    excitation = _section(raw, "excitation")
    sweep = _section(raw, "sweep")
    dwell = _number("sweep", "dwell", sweep.get("dwell", 2.0))
    damping = tuple(_number("sweep", "damping", c) for c in _list(sweep, "sweep", "damping"))
    duration = raw.get("duration")
    if duration == "auto" and airspeed.kind == "steps":
        duration = sweep_duration(len(airspeed.values), len(damping), dwell)
    unknown = set(excitation) - {"force_std", "seed", "levels", "level_dwell"}
    if unknown:
        raise ScenarioError(f"unknown keys {sorted(unknown)} in excitation; known: "
                            "force_std, seed, levels, level_dwell")
    levels = tuple(_number("excitation", "levels", v)
                   for v in _list(excitation, "excitation", "levels"))
    seed = excitation.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"excitation.seed must be a non-negative integer, got {seed!r}")
    block_size = raw.get("block_size", 20)
    if isinstance(block_size, bool) or not isinstance(block_size, int):
        raise ScenarioError(f"block_size must be an integer, got {block_size!r}")
    return Scenario(
        name=str(raw.get("name", default_name)),
        duration=_number("scenario", "duration", duration),
        sample_rate=_number("scenario", "sample_rate", raw.get("sample_rate", 1000.0)),
        block_size=block_size,
        airspeed=airspeed,
        density=_number("density", "base", density.get("base", 1.2)),
        density_variation=_number("density", "variation", density.get("variation", 0.0)),
        density_frequency=_number("density", "frequency", density.get("frequency", 1.0)),
        force_std=_number("excitation", "force_std", excitation.get("force_std", 1000.0)),
        seed=seed,
        dwell=dwell,
        sweep_damping=damping,
        force_levels=levels,
        level_dwell=_number("excitation", "level_dwell", excitation.get("level_dwell", 1.0)),
        plant=_plant(raw.get("plant")),
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario YAML file; :class:`ScenarioError` names the file and the problem."""
    path = Path(path)
    raw = read_yaml(path, "scenario", ScenarioError)
    try:
        return scenario_from_dict(raw, default_name=path.stem)
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
