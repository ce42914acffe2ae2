"""The project's laws in the in-process loop, built from objects (not files) for the tests."""
from __future__ import annotations

from aero_dva.control import controllers as table
from aero_dva.control.airspeed_schedule import MAX_AIRSPEED
from aero_dva.control.command_laws import FixedLaw, RBFLaw, ScheduleLaw
from aero_dva.control.oracle import OracleLaw
from aero_dva.flight.damper import DAMPER_RANGE
from dva_offline.evaluation.closed_loop import LawControl

RATE = 1000.0  # [Hz] the flights' sample rate


def fixed_control(damping: float) -> LawControl:
    return LawControl(table.controller("fixed"), FixedLaw(damping, 20.0), RATE)


def schedule_control(schedule) -> LawControl:
    return LawControl(table.controller("schedule"),
                      ScheduleLaw(schedule, DAMPER_RANGE, True, MAX_AIRSPEED), RATE)


def oracle_control(optimal) -> LawControl:
    return LawControl(table.controller("oracle"), OracleLaw(optimal), RATE)


def rbf_control(network, damping_range=DAMPER_RANGE) -> LawControl:
    return LawControl(table.controller("rbf"), RBFLaw(network, damping_range), RATE)


def evaluation_laws(fixed: float, schedule=None, network=None, optimal=None) -> dict:
    """An evaluation's laws by controller (``EvaluationSetup.laws``); None: not flown."""
    laws = {"fixed": FixedLaw(fixed, 20.0)}
    if schedule is not None:
        laws["schedule"] = ScheduleLaw(schedule, DAMPER_RANGE, True, MAX_AIRSPEED)
    if network is not None:
        laws["rbf"] = RBFLaw(network, DAMPER_RANGE)
    if optimal is not None:
        laws["oracle"] = OracleLaw(optimal)
    return laws
