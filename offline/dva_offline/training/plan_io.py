"""JSON file of a training plan (:mod:`dva_offline.training.plan`), written atomically.

Layout (SI units; NaN is written as null)::

    {"format": "dva_training_plan", "version": 1,
     "wing": "<wing file the plan was made for>",
     "settings": {"ratios": [...], "factors": [...], "n_damping": 20, ...},
     "critical_airspeed": 100.0, "base_density": 1.2,
     "conditions": {"optimal_damping": [[...]], "stable_low": [[...]], "stable_high": [[...]]},
     "dwells": {"airspeed": [...], "density": [...], "damping": [...], "condition": [...]}}
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np

from aero_dva import input_ranges as ranges
from aero_dva.atomic_io import atomic_output
from aero_dva.flight.damper import damping_problem
from aero_dva.flight.flight_limits import MAX_FLIGHT_SAMPLES
from aero_dva.safe_files import read_json
from dva_offline.training.plan import PlanSettings, TrainingPlan

__all__ = ["FILE_FORMAT", "PLAN_FILE", "load_plan", "plan_damping_problem", "plan_from_dict",
           "plan_to_dict", "plan_wing_file", "save_plan"]

FILE_FORMAT = "dva_training_plan"
FILE_VERSION = 1
#: Name of the plan file a recorded sweep keeps inside its bag directory.
PLAN_FILE = "training_plan.json"


def _nulls(values) -> list:
    return [None if not math.isfinite(v) else float(v) for v in np.ravel(values)]


def plan_to_dict(plan: TrainingPlan, wing: str = "") -> dict:
    """The JSON object of ``plan``; ``wing`` names the wing file it was made for."""
    shape = plan.optimal_damping.shape
    settings = dataclasses.asdict(plan.settings)
    settings["ratios"] = list(settings["ratios"])
    settings["factors"] = list(settings["factors"])
    settings["damping_range"] = list(settings["damping_range"])
    return {
        "format": FILE_FORMAT, "version": FILE_VERSION, "wing": str(wing),
        "settings": settings, "critical_airspeed": plan.critical_airspeed,
        "base_density": plan.base_density,
        "conditions": {"shape": list(shape),
                       **{k: _nulls(getattr(plan, k))
                          for k in ("optimal_damping", "stable_low", "stable_high")}},
        "dwells": {"airspeed": plan.airspeed.tolist(), "density": plan.density.tolist(),
                   "damping": plan.damping.tolist(), "condition": plan.condition.tolist()},
    }


def plan_from_dict(data, where: str = "training plan") -> TrainingPlan:
    """Inverse of :func:`plan_to_dict`; ValueError naming what is wrong."""
    if not isinstance(data, dict) or data.get("format") != FILE_FORMAT:
        raise ValueError(f"{where}: not a {FILE_FORMAT} file")
    if data.get("version") != FILE_VERSION:
        raise ValueError(f"{where}: version {data.get('version')!r}, this reads "
                         f"{FILE_VERSION}")
    try:
        raw = dict(data["settings"])
        raw["ratios"] = tuple(raw["ratios"])
        raw["factors"] = tuple(raw["factors"])
        raw["damping_range"] = tuple(raw["damping_range"])
        settings = PlanSettings(**raw)
        shape = tuple(data["conditions"]["shape"])
        conditions = {k: np.array([math.nan if v is None else float(v)
                                   for v in data["conditions"][k]]).reshape(shape)
                      for k in ("optimal_damping", "stable_low", "stable_high")}
        dwells = data["dwells"]
        if not all(isinstance(c, int) and not isinstance(c, bool)
                   for c in dwells["condition"]):
            raise ValueError("dwells.condition must be whole numbers (condition indexes)")
        plan = TrainingPlan(
            settings=settings, critical_airspeed=float(data["critical_airspeed"]),
            base_density=float(data["base_density"]), **conditions,
            airspeed=np.asarray(dwells["airspeed"], dtype=float),
            density=np.asarray(dwells["density"], dtype=float),
            damping=np.asarray(dwells["damping"], dtype=float),
            condition=np.asarray(dwells["condition"], dtype=int))
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{where}: {type(exc).__name__}: {exc}") from None
    n = plan.airspeed.size
    arrays = (plan.airspeed, plan.density, plan.damping, plan.condition)
    if n == 0 or any(a.shape != (n,) for a in arrays):
        raise ValueError(f"{where}: the dwell arrays must be non-empty and of one length")
    try:
        ranges.check_fields(data, ranges.PLAN)
        ranges.check_numbers(plan.airspeed.tolist(), "dwells.airspeed", ranges.AIRSPEED)
        ranges.check_numbers(plan.density.tolist(), "dwells.density", ranges.AIR_DENSITY)
        ranges.check_numbers(plan.condition.tolist(), "dwells.condition",
                             ranges.Range(0, int(np.prod(shape)) - 1))
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    if not (np.all(np.isfinite(plan.airspeed)) and np.all(plan.airspeed > 0)
            and np.all(np.isfinite(plan.density)) and np.all(plan.density > 0)
            and np.all(np.isfinite(plan.damping)) and np.all(plan.damping >= 0)):
        raise ValueError(f"{where}: every dwell needs a finite airspeed > 0, density > 0 and "
                         "c2 >= 0")
    if shape != (len(settings.factors), len(settings.ratios)):
        raise ValueError(f"{where}: conditions shape {shape} does not match the settings")
    problem = plan_damping_problem(plan, where)
    if problem is not None:
        raise ValueError(problem)
    if n * settings.window_samples > MAX_FLIGHT_SAMPLES:
        raise ValueError(f"{where}: {n:,} dwells x {settings.window_samples:,} samples are "
                         f"more than the {MAX_FLIGHT_SAMPLES:,} samples a recording may have")
    return plan


def plan_damping_problem(plan: TrainingPlan, where: str = "training plan") -> str | None:
    """Why the plan's c2 values (its dwells', and its conditions' optimum and stable
    interval where they have one) cannot be flown by the plan's damper, or None."""
    conditions = np.concatenate([np.ravel(getattr(plan, k)) for k in
                                 ("optimal_damping", "stable_low", "stable_high")])
    for what, values in (("a dwell's", plan.damping),
                         ("a condition's", conditions[np.isfinite(conditions)])):
        problem = damping_problem(values, f"{where}: {what} c2", plan.settings.damping_range)
        if problem is not None:
            return problem
    return None


def save_plan(plan: TrainingPlan, path, wing: str = "") -> Path:
    """Write ``plan`` to ``path`` (atomically); a plan with a c2 outside its damper's range is
    refused (ValueError), never written."""
    problem = plan_damping_problem(plan)
    if problem is not None:
        raise ValueError(problem)
    with atomic_output(path) as handle:
        json.dump(plan_to_dict(plan, wing), handle, allow_nan=False)
    return Path(path)


def plan_wing_file(plan_path, wing: str) -> Path:
    """The wing file the plan ``plan_path`` names (``wing``, as :func:`load_plan` gives it): a
    relative path is taken from the plan's folder; it must exist and be readable, else
    ValueError in one line (a default wing never takes its place)."""
    from aero_dva.text_input import loggable

    where = f"training plan {str(plan_path)!r}"
    if not wing:
        raise ValueError(f"{where} names no wing file; give its wing with --wing")
    path = Path(wing)
    if not path.is_absolute():
        path = Path(plan_path).parent / path
    if not path.is_file():
        raise ValueError(f"{where}: its wing file '{loggable(path)}' does not exist (a "
                         "relative path is taken from the plan's folder); give the wing "
                         "with --wing")
    if not os.access(path, os.R_OK):
        raise ValueError(f"{where}: its wing file '{loggable(path)}' is not readable")
    return path.resolve()


def load_plan(path) -> tuple[TrainingPlan, str]:
    """(plan, wing file name it was made for) from ``path``."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no training plan file {path}")
    data = read_json(path, "training plan")  # refuses binary, oversized and deep files
    return plan_from_dict(data, f"training plan {path}"), str(data.get("wing", ""))
