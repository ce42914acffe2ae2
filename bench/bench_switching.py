"""Speed of the flight with the switching c2 law armed, against the held-c2 flight timed in
the same run.

Run:  .venv/bin/python bench/bench_switching.py [--repeats 3] [--clock wall|cpu]
      [--gains FILE]

Prints (best of ``--repeats``), for the study's 30 s ramp 0.8 -> 1.2 U_cr at 1 kHz:
- one flight with c2 held (the batch simulator; the baseline);
- one flight with the law armed (10 ms damper lag, Kalman observer, sensor noise): repeated
  (its maps kept from the previous flight of the same conditions, as for the seeds of a case)
  and first (its maps built); the same without lag (two precomputed steps instead of the c2
  table) and without observer;
- 12 flights with the law armed in one batch (what `dva switching evaluate` flies);
each as wall time, x real time and the ratio to the baseline (target: >= 2 000x real time
for the armed flight with lag and observer).
First, the first armed flight of the process: it loads the compiled loop from numba's cache
(or compiles it, on a fresh install).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from aero_dva.control.switching_io import load_gains
from aero_dva.data_files import data_file
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.flight.divergence import ramp_airspeed
from aero_dva.flight.per_sample.flight import _kept, fly_switched
from aero_dva.flight.per_sample.switching_law import SwitchingLaw
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

CLOCK = {"wall": time.perf_counter, "cpu": time.process_time}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--clock", choices=sorted(CLOCK), default="wall")
    parser.add_argument("--gains", default=str(data_file("switching_gains.json")))
    args = parser.parse_args()
    clock = CLOCK[args.clock]

    def best(fn, setup=None):
        times = []
        for _ in range(args.repeats):
            if setup is not None:  # not timed
                setup()
            t = clock()
            fn()
            times.append(clock() - t)
        return min(times)

    cfg = load_wing()
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    gains = load_gains(args.gains)
    law = gains.law
    u = ramp_airspeed(100.0)
    duration = u.size / 1000.0
    rng = np.random.default_rng(0)
    force = 1000.0 * rng.standard_normal((12, u.size))
    noise = 1e-3 * rng.standard_normal((u.size, 4))
    no_observer = SwitchingLaw(law.gain, law.c_lo, law.c_hi)
    cases = [
        ("c2 held (baseline)", lambda: simulate_flights(
            cfg.wing, cfg.absorber, force=force[0], airspeed=u, density=1.2, damping=None)),
        ("law armed, 10 ms lag, observer", lambda: fly_switched(
            model, law, u, 1.2, force[0], time_constant=0.01, noise=noise)),
        ("law armed, no lag, observer", lambda: fly_switched(
            model, law, u, 1.2, force[0], time_constant=0.0, noise=noise)),
        ("law armed, 10 ms lag, true state", lambda: fly_switched(
            model, no_observer, u, 1.2, force[0], time_constant=0.01)),
    ]
    t = clock()
    cases[1][1]()
    print(f"first armed flight of this process (loads or compiles the loop) "
          f"{(clock() - t) * 1e3:7.1f} ms", flush=True)
    base = None
    for name, fn in cases[:2] + [("the same, its maps built (first)", cases[1][1])] + cases[2:]:
        t = best(fn, _kept.clear if name.endswith("(first)") else None)
        base = t if base is None else base
        print(f"one 30 s flight, {name:<34} {t * 1e3:7.1f} ms = {duration / t:6.0f}x real "
              f"time, {t / base:5.1f}x the baseline", flush=True)
    t = best(lambda: fly_switched(model, law, u, 1.2, force, time_constant=0.01))
    print(f"12 flights in one batch, law armed, 10 ms lag  {t * 1e3:7.1f} ms = "
          f"{12 * duration / t:6.0f}x real time per flight, {t / 12 / base:5.1f}x the "
          "baseline per flight")


if __name__ == "__main__":
    main()
