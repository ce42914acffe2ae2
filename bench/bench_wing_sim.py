"""Speed of the wing simulators, as ratios against baselines timed in the same run.

Run:  .venv/bin/python bench/bench_wing_sim.py [--flights 64]
      [--repeats 3] [--clock wall|cpu]

``--clock cpu`` times with the process's CPU time (all its threads) instead of the wall clock:
on a shared, busy machine the wall clock mostly measures the other processes.

Prints (best of ``--repeats``):
- the study's flight (30 s ramp 0.8 -> 1.2 U_cr at 1 kHz, Maxwell DVA) with c2 held (ch. 6) and
  with a c2 schedule (ch. 7) by four routes timed alternately in this run: this revision (the
  compiled loop over stacked (16, 8) maps), the previous revision's compiled loop (general
  matrix-vector products, ``held_kernel.step_periods``), the banded period carry
  (``BatchStepper`` without the compiled loop) and the reference
  (``reference_simulate_flights``); each as a first flight (no condition discretised yet; the
  kept conditions are dropped before the clock starts) and a repeated one (the conditions
  kept from the previous call, as for the seeds of an evaluation case); real-time factors
  (targets >= 10 000x held, >= 5 000x schedule), ratios and the largest difference relative
  to each channel's peak;
- a batch of flights vs a loop of single flights, both by the compiled loop: flights per
  second and their ratio (the per-call cost a batch pays once);
- a constant-airspeed flight vs scipy.signal.dlsim on the same discretised system;
- the StreamingSimulator in 20-sample blocks (the simulator node's use).
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.signal import cont2discrete, dlsim

from aero_dva.flight.batch_simulator import (
    BatchStepper,
    _DiscreteCache,
    _simulate_with,
    forget_conditions,
    reference_simulate_flights,
    simulate_flights,
)
from aero_dva.flight.discrete_model import DEFAULT_HOLD, DiscreteWing
from aero_dva.flight.divergence import ramp_airspeed
from aero_dva.flight.streaming_simulator import StreamingSimulator
from aero_dva.wing.flutter import flutter_speed
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

CLOCK = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCK["wall"]


def best(fn, repeats, setup=None):
    times = []
    for _ in range(repeats):
        if setup is not None:  # not timed
            setup()
        t = clock()
        fn()
        times.append(clock() - t)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--clock", choices=sorted(CLOCK), default="wall")
    args = parser.parse_args()
    global clock
    clock = CLOCK[args.clock]
    cfg = load_wing()
    wing, dva, rho = cfg.wing, cfg.maxwell_design, cfg.air_density
    u_cr = flutter_speed(AeroelasticModel(wing), rho).critical_airspeed
    u = ramp_airspeed(u_cr)
    c2 = np.interp(u, [0.8 * u_cr, 1.2 * u_cr], [1200.0, 300.0])  # a c2 schedule
    duration = u.size / 1000.0
    rng = np.random.default_rng(0)
    force = 1000.0 * rng.standard_normal((args.flights, u.size))

    def one(i=0, damping=c2, route=simulate_flights):
        return route(wing, dva, force=force[i], airspeed=u, density=rho, damping=damping)


    # Earlier routes for one flight, their conditions kept between calls: the banded period
    # carry and the period maps (BatchStepper without the compiled loop), and the previous
    # revision's compiled loop (general matrix-vector products, no stacked maps).
    dw = DiscreteWing(AeroelasticModel(wing, dva), 1000.0, hold=DEFAULT_HOLD, quantum=2e-3)
    kept = {}

    def earlier(route, damping, **kw):
        key = (route, damping is None)
        if key not in kept:
            kept[key] = (_DiscreteCache(dw) if route == "banded"
                         else _DiscreteCache(dw, compiled=True, stacked=False))
        stepper = BatchStepper(dw, kept[key], compiled=route == "general")
        return _simulate_with(stepper, kw["force"], kw["airspeed"], kw["density"], damping,
                              None, None)

    def banded(wing_, dva_, *, damping, **kw):
        return earlier("banded", damping, **kw)

    def general(wing_, dva_, *, damping, **kw):
        return earlier("general", damping, **kw)

    print("one 30 s flight: the routes timed alternately (first: nothing discretised yet;"
          " repeated: the conditions kept from the previous call)")
    routes = {"banded": (banded, "banded carry"),
              "previous": (general, "previous compiled loop")}
    for label, damping in (("c2 held", None), ("c2 schedule", c2)):
        ref = one(0, damping, reference_simulate_flights)
        new = one(0, damping)
        diff = max(float(np.max(np.abs(a - b) / np.max(np.abs(a), axis=-1, keepdims=True)))
                   for other in [ref] + [one(0, damping, fn) for fn, _ in routes.values()]
                   for a, b in ((other.displacements, new.displacements),
                                (other.accelerations, new.accelerations)))
        times = {"reference": []}
        for k in ("first", "repeated"):
            times.update({f"{r} {k}": [] for r in routes} | {k: []})
        for _ in range(args.repeats):
            times["reference"].append(
                best(lambda d=damping: one(0, d, reference_simulate_flights), 1))
            for r, (fn, _) in routes.items():
                times[f"{r} first"].append(best(lambda d=damping, f=fn: one(0, d, f), 1,
                                                setup=kept.clear))
                times[f"{r} repeated"].append(best(lambda d=damping, f=fn: one(0, d, f), 1))
            times["first"].append(best(lambda d=damping: one(0, d), 1,
                                       setup=forget_conditions))
            times["repeated"].append(best(lambda d=damping: one(0, d), 1))
        t = {k: min(v) for k, v in times.items()}
        print(f"  {label:12s} {'reference':17s} {t['reference'] * 1e3:6.2f} ms = "
              f"{duration / t['reference']:6.0f}x real time  (reference_simulate_flights)")
        for k in ("first", "repeated"):
            for r, (_, name) in routes.items():
                print(f"  {label:12s} {r + ' ' + k:17s} {t[f'{r} {k}'] * 1e3:6.2f} ms = "
                      f"{duration / t[f'{r} {k}']:6.0f}x real time  ({name})")
            print(f"  {label:12s} {'this ' + k:17s} {t[k] * 1e3:6.2f} ms = "
                  f"{duration / t[k]:6.0f}x real time  -> "
                  f"{t[f'previous {k}'] / t[k]:4.1f}x the previous compiled loop, "
                  f"{t[f'banded {k}'] / t[k]:4.1f}x the banded carry, "
                  f"{t['reference'] / t[k]:4.1f}x the reference")
        print(f"  {label:12s} largest difference / channel peak: {diff:.1e}")

    def loop():
        for i in range(args.flights):
            one(i)

    def batch():
        simulate_flights(wing, dva, force=force, airspeed=u, density=rho, damping=c2)

    t_loop = best(loop, args.repeats)
    t_batch = best(batch, args.repeats)
    rate_loop, rate_batch = args.flights / t_loop, args.flights / t_batch
    print(f"c2 schedule, loop of {args.flights} single flights: {rate_loop:6.1f} flights/s")
    print(f"c2 schedule, batch of {args.flights} flights:       {rate_batch:6.1f} flights/s"
          f"  -> batch / loop = {rate_batch / rate_loop:.1f}x")

    # Constant airspeed: the same LTI system through scipy.signal.dlsim.
    ss = AeroelasticModel(wing, dva).state_space(0.9 * u_cr, rho, damping=600.0)
    c = np.vstack([ss.c_displacement, ss.c_acceleration])
    d = np.r_[np.zeros(4), ss.d_acceleration][:, None]
    sysd = cont2discrete((ss.a, ss.b[:, None], c, d), 1e-3, "zoh")
    t_dlsim = best(lambda: dlsim(sysd, force[0]), args.repeats)
    t_ours = best(lambda: simulate_flights(wing, dva, force=force[0], airspeed=0.9 * u_cr,
                                           density=rho, damping=600.0), args.repeats)
    print(f"constant airspeed:      dlsim {t_dlsim * 1e3:.1f} ms, ours {t_ours * 1e3:.1f} ms"
          f"  -> {t_dlsim / t_ours:.1f}x faster than dlsim")

    def stream():
        sim = StreamingSimulator(wing, dva, quantum=2e-3)
        for i in range(0, u.size, 20):
            sim.advance(force[0, i:i + 20], u[i:i + 20], rho, c2[i:i + 20])

    t_stream = best(stream, 1)
    print(f"streaming, 20-sample blocks: {t_stream * 1e3:.0f} ms = "
          f"{duration / t_stream:.0f}x real time")


if __name__ == "__main__":
    main()
