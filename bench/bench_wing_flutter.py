"""Speed of the flutter solver, as a ratio against a baseline timed in the same run.

Run:  .venv/bin/python bench/bench_wing_flutter.py [--repeats 200] [--clock wall|cpu]

``--clock cpu`` times with the process's CPU time instead of the wall clock (on a shared, busy
machine the wall clock mostly measures the other processes). This revision and the previous
route are called alternately, so that both see the same load; each figure is the best call.

The default (chapter-6) wing with its Maxwell DVA (target: at most 0.5 ms per critical
airspeed). Two baselines in the same run: the previous route
(:func:`~aero_dva.wing.flutter.reference_flutter_speed`: 64-point grids, Brent's method), and
the straightforward way (the state space assembled anew at every airspeed, the growth rate
bisected to the same 1e-10 relative tolerance). The answers must agree to 1e-9 relative.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from aero_dva.wing.aerodynamics import TheodorsenAero
from aero_dva.wing.flutter import flutter_speed, reference_flutter_speed
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

CLOCK = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCK["wall"]


def best(fn, repeats=50):
    times = []
    for _ in range(repeats):
        t = clock()
        out = fn()
        times.append(clock() - t)
    return min(times), out


def best_alternating(fns, repeats):
    """Best time and last result of each function, the functions called in turn."""
    times = [[] for _ in fns]
    outs = [None] * len(fns)
    for _ in range(repeats):
        for k, fn in enumerate(fns):
            t = clock()
            outs[k] = fn()
            times[k].append(clock() - t)
    return [(min(t), out) for t, out in zip(times, outs)]


def baseline(model, rho, low, high, tol=1e-10):
    def g(u):
        lam = np.linalg.eigvals(model.state_space(u, rho).a)
        lam = lam[np.abs(lam) > 1e-7]
        return lam.real.max()

    u = np.linspace(low, high, 400)
    i = next(k for k in range(len(u)) if g(u[k]) > 0)
    a, b = u[i - 1], u[i]
    while b - a > tol * b:
        m = 0.5 * (a + b)
        a, b = (m, b) if g(m) < 0 else (a, m)
    return 0.5 * (a + b)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--clock", choices=sorted(CLOCK), default="wall")
    args = parser.parse_args()
    global clock
    clock = CLOCK[args.clock]
    cfg = load_wing()
    model = AeroelasticModel(cfg.wing, cfg.maxwell_design)
    (t_ours, res), (t_prev, prev) = best_alternating(
        [lambda: flutter_speed(model, cfg.air_density),
         lambda: reference_flutter_speed(model, cfg.air_density)], args.repeats)
    high = 2.0 * res.critical_airspeed
    t_base, u_base = best(lambda: baseline(model, cfg.air_density, 0.0, high), 3)
    print(f"{args.clock} clock, best of {args.repeats}")
    print(f"flutter speed with Maxwell DVA: {res.critical_airspeed:.6f} m/s, "
          f"{res.flutter_frequency:.4f} Hz")
    rel = abs(prev.critical_airspeed - res.critical_airspeed) / prev.critical_airspeed
    print(f"ours: {t_ours * 1e3:.3f} ms ({'within' if t_ours <= 5e-4 else 'OVER'} the 0.5 ms "
          f"target)   previous route: {t_prev * 1e3:.2f} ms  -> {t_prev / t_ours:.1f}x;  "
          f"|difference| = {rel:.1e} relative ({'within' if rel <= 1e-9 else 'OVER'} 1e-9)")
    print(f"ours: {t_ours * 1e3:.3f} ms   baseline (bisection, reassembly): {t_base * 1e3:.1f} ms"
          f"  -> {t_base / t_ours:.0f}x;  |difference| = "
          f"{abs(u_base - res.critical_airspeed) / res.critical_airspeed:.1e} relative")
    theo = AeroelasticModel(cfg.wing, cfg.maxwell_design, TheodorsenAero())
    t_pk, res_pk = best(lambda: flutter_speed(theo, cfg.air_density), 3)
    print(f"Theodorsen p-k: {res_pk.critical_airspeed:.4f} m/s ({res_pk.kind}) "
          f"in {t_pk * 1e3:.0f} ms")


if __name__ == "__main__":
    main()
