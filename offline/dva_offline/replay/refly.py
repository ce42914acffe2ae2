"""``dva replay --offline`` of a per-sample law's flight: the wing flown again with the c2 the
bag recorded, and its accelerations compared with the recorded ones.

A per-sample law runs in closed loop with the wing, in the damper's own controller; re-running
it open loop on recorded data would answer nothing. Its decisions are in the bag instead
(``dva/damper_block``: the c2 acting over each sample of each block it flew; ``dva/damper_state``
the c2 held over the others), beside the aileron force (``wing/excitation``): flown again with
them (:func:`aero_dva.flight.per_sample.replay.fly_again`) on the scenario and wing the flight
flew, the wing must give the recorded accelerations, to rounding. A difference beyond
:data:`RTOL` of their peak is a failed check (exit 1): another scenario or wing, or a bag that
lost the law's blocks.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["RTOL", "refly"]

#: The re-flown accelerations agree with the recorded ones to this share of their peak.
RTOL = 1e-9


def refly(args) -> dict:
    """Fly ``args.bag``'s flight again (``args.scenario``, ``args.wing``: the flight's files,
    the package's by default), write its blocks to ``args.out``, and compare."""
    from aero_dva.bag.flight_log_io import load_flight_log
    from aero_dva.flight.flight_runtime import load_runtime_config
    from aero_dva.flight.per_sample.replay import fly_again
    from aero_dva.wing.model import ACCELERATION_NAMES
    from dva_offline.replay.bag_io import write_flight

    log = load_flight_log(args.bag)
    law = np.isfinite(log.law_damping)
    if not law.any():
        raise ValueError(f"bag {args.bag}: no dva/damper_block, so no block was flown by a "
                         "per-sample law (or the law's blocks were not recorded): nothing to "
                         "fly again with the law's c2")
    n = log.time.size
    lost = [name for name, values in (("wing/excitation", log.force),
                                      ("wing/acceleration", log.accelerations[0]),
                                      ("dva/damper_state", log.applied_damping))
            if not np.all(np.isfinite(values))]
    if lost or log.missing_samples:
        raise ValueError(f"bag {args.bag}: samples of {', '.join(lost) or 'wing/displacement'} "
                         "are missing (lost on the way to the recorder): the flight cannot be "
                         "flown again whole")
    config = load_runtime_config({"scenario": args.scenario or "", "wing": args.wing or ""})
    scenario = config.scenario
    if not math.isclose(scenario.sample_rate, log.sample_rate, rel_tol=1e-12):
        raise ValueError(f"--scenario: it samples at {scenario.sample_rate:g} Hz, the bag at "
                         f"{log.sample_rate:g} Hz")
    again = fly_again(config, log.force, log.damping, law, samples=n)
    starts = np.arange(0, n, scenario.block_size)
    if not np.allclose(again.airspeed[starts], log.airspeed[starts], rtol=1e-12, atol=0.0):
        worst = float(np.max(np.abs(again.airspeed[starts] - log.airspeed[starts])))
        raise ValueError(f"--scenario {args.scenario or '(the package ramp)'}: its airspeeds "
                         f"are not the recorded flight's (up to {worst:.3g} m/s apart): fly "
                         "again with the scenario the flight flew")
    write_flight(args.out, again, scenario.block_size)
    channels = {}
    for name, recorded, flown in zip(ACCELERATION_NAMES, log.accelerations,
                                     again.accelerations, strict=True):
        peak = float(np.max(np.abs(recorded)))
        difference = float(np.max(np.abs(flown - recorded)))
        channels[name] = {"peak": peak, "max_abs_difference": difference,
                          "relative_to_peak": difference / peak if peak > 0 else math.inf}
    worst = max(c["relative_to_peak"] for c in channels.values())
    return {"samples": n, "law_blocks": int(np.count_nonzero(law[starts])),
            "held_blocks": int(np.count_nonzero(~law[starts])), "accelerations": channels,
            "relative_to_peak": worst, "rtol": RTOL, "agrees": bool(worst <= RTOL)}
