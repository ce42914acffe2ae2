"""c2 proportional to the measured airspeed, c2 = gain U, clamped to the damper's range: a
block-rate law that answers each flight condition (an example of a law from outside the
project; docs/control.md, "Adding a control law")."""
from __future__ import annotations

import math

import numpy as np

from aero_dva.control.controllers import (
    BLOCK,
    CONDITION,
    DAMPER_RANGE_PARAMS,
    Controller,
    LawParam,
    LawStep,
)


class ProportionalLaw:
    """c2 = gain U for each flight condition, clamped to [damping_min, damping_max]."""

    counters = ()

    def __init__(self, gain: float, low: float, high: float):
        if not (math.isfinite(gain) and gain >= 0.0):
            raise ValueError(f"parameter 'gain' must be finite and >= 0, got {gain}")
        self.gain, self.low, self.high = gain, low, high

    def answer(self, kind: str, stamp_ns: int, value) -> LawStep:
        if not (math.isfinite(value.airspeed) and value.airspeed >= 0.0):
            return LawStep("rejected", reason=f"airspeed {value.airspeed} m/s")
        return LawStep.command(min(max(self.gain * value.airspeed, self.low), self.high))

    def condition_law(self):
        """c2(U, rho), for the evaluation's stability boundaries (arrays of conditions)."""
        return lambda airspeed, density: np.clip(self.gain * np.asarray(airspeed), self.low,
                                                 self.high)


def make(values) -> ProportionalLaw:
    return ProportionalLaw(float(values["gain"]), float(values["damping_min"]),
                           float(values["damping_max"]))


ENTRY = Controller(
    name="proportional", label="c2 proportional to U", source="proportional", runs=BLOCK,
    law="dva_law_example:make", inputs=(CONDITION,), command_lag=0.05,
    summary="Command c2 = gain U from each flight condition, clamped to the damper's range.",
    params=(LawParam("gain", 6.0, "c2 per airspeed", "N s^2/m^2", 0.0, 1.0e3),
            *DAMPER_RANGE_PARAMS))
