"""Speed of the flutter solver, as a ratio against baselines timed in the same run.

Run:  .venv/bin/python bench/bench_wing_flutter.py [--repeats 200] [--clock wall|cpu]

``--clock cpu`` times with the process's CPU time instead of the wall clock (on a shared, busy
machine the wall clock mostly measures the other processes). This revision and the previous
routes are called alternately, so that all see the same load; each figure is the best call.

The default (chapter-6) wing with its Maxwell DVA (target: at most 0.5 ms per critical
airspeed). Baselines in the same run: the straightforward way (the state space assembled anew
at every airspeed, the growth rate bisected to the same 1e-10 relative tolerance), the
previous route (:func:`~aero_dva.wing.flutter.grid_flutter_speed`: 16-point grids per range,
Newton's method) and the one before it (:func:`~aero_dva.wing.flutter.reference_flutter_speed`:
64-point grids, Brent's method). The answers must agree with the previous route to 1e-9
relative, on this wing and on the other cases printed (other damper settings and densities).
Where the time goes: the assembly of ``A(U)``, the samples (one eigenvalue problem each) and
the rest (the search's Python).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from aero_dva.flight.damper import DAMPER_RANGE
from aero_dva.wing import flutter_march
from aero_dva.wing.aerodynamics import TheodorsenAero, WagnerAero
from aero_dva.wing.flutter import flutter_speed, grid_flutter_speed, reference_flutter_speed
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing

CLOCK = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCK["wall"]
TARGET = 5e-4  # [s] per critical airspeed


def best(fn, repeats=50):
    times = []
    for _ in range(repeats):
        t = clock()
        out = fn()
        times.append(clock() - t)
    return min(times), out


def best_alternating(fns, repeats, block=1):
    """Best time and last result of each function, the functions called in turn, ``block``
    calls of one before the next (``block=1``: each call follows the other routes' calls, its
    code and data cold in the caches; a block leaves them warm, as in a loop of searches)."""
    times = [[] for _ in fns]
    outs = [None] * len(fns)
    for _ in range(max(repeats // block, 1)):
        for k, fn in enumerate(fns):
            for _ in range(block):
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


def samples_per_search(model, rho):
    """Eigenvalue problems one search solves (counted, not timed)."""
    count = [0]
    sample = flutter_march.TangentGrowth.sample

    def counted(self, u):
        count[0] += 1
        return sample(self, u)

    flutter_march.TangentGrowth.sample = counted
    try:
        flutter_speed(model, rho)
    finally:
        flutter_march.TangentGrowth.sample = sample
    return count[0]


def where_the_time_goes(model, rho, t_ours, repeats):
    t_poly, poly = best(lambda: model.polynomial_unchecked(rho, None), repeats)
    growth = flutter_march.TangentGrowth(*poly)
    u = flutter_speed(model, rho).critical_airspeed
    t_sample, _ = best(lambda: growth.sample(u), repeats)
    n = samples_per_search(model, rho)
    rest = t_ours - t_poly - n * t_sample
    print(f"where the time goes: assembly of A(U) {t_poly * 1e6:.0f} us; {n} samples x "
          f"{t_sample * 1e6:.0f} us = {n * t_sample * 1e6:.0f} us (one dgeev with both "
          f"eigenvector sets and the slopes); the rest {rest * 1e6:.0f} us")


def other_cases(cfg):
    """Largest relative difference to the previous route over damper settings, densities
    and aerodynamic models of the default wing (untimed)."""
    worst, n = 0.0, 0
    for aero in (None, WagnerAero()):
        for c2 in (0.0, 50.0, 500.0, DAMPER_RANGE[1], np.inf):
            model = AeroelasticModel(cfg.wing, cfg.maxwell_design.replace(damping=c2), aero)
            for rho in (0.6, 0.9, 1.2, 1.5):
                new, old = flutter_speed(model, rho), grid_flutter_speed(model, rho)
                worst = max(worst, abs(new.critical_airspeed / old.critical_airspeed - 1))
                n += 1
    return worst, n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--clock", choices=sorted(CLOCK), default="wall")
    parser.add_argument("--block", type=int, default=20,
                        help="calls of one route in a row before the next (1: strictly "
                             "alternating, each call with cold caches)")
    args = parser.parse_args()
    global clock
    clock = CLOCK[args.clock]
    cfg = load_wing()
    rho = cfg.air_density
    model = AeroelasticModel(cfg.wing, cfg.maxwell_design)
    (t_ours, res), (t_grid, grid), (t_brent, brent) = best_alternating(
        [lambda: flutter_speed(model, rho), lambda: grid_flutter_speed(model, rho),
         lambda: reference_flutter_speed(model, rho)], args.repeats, args.block)
    high = 2.0 * res.critical_airspeed
    t_base, u_base = best(lambda: baseline(model, rho, 0.0, high), 3)
    u = res.critical_airspeed
    print(f"{args.clock} clock, best of {args.repeats}, in turns of {args.block} calls per route")
    print(f"flutter speed with Maxwell DVA: {u:.6f} m/s, {res.flutter_frequency:.4f} Hz")
    verdict = "within" if t_ours <= TARGET else "OVER"
    print(f"ours: {t_ours * 1e3:.3f} ms ({verdict} the 0.5 ms target)   baseline (bisection, "
          f"reassembly): {t_base * 1e3:.1f} ms  -> {t_base / t_ours:.0f}x;  |difference| = "
          f"{abs(u_base - u) / u:.1e} relative")
    rel = abs(grid.critical_airspeed - u) / grid.critical_airspeed
    print(f"ours: {t_ours * 1e3:.3f} ms   previous route (grids, Newton): {t_grid * 1e3:.2f} ms"
          f"  -> {t_grid / t_ours:.1f}x;  |difference| = {rel:.1e} relative "
          f"({'within' if rel <= 1e-9 else 'OVER'} 1e-9)")
    rel = abs(brent.critical_airspeed - u) / brent.critical_airspeed
    print(f"ours: {t_ours * 1e3:.3f} ms   route before (grids, Brent): {t_brent * 1e3:.2f} ms"
          f"  -> {t_brent / t_ours:.1f}x;  |difference| = {rel:.1e} relative")
    worst, n = other_cases(cfg)
    print(f"other cases ({n}: c2 x density x quasi-steady/Wagner): largest |difference| to the "
          f"previous route {worst:.1e} relative ({'within' if worst <= 1e-9 else 'OVER'} 1e-9)")
    where_the_time_goes(model, rho, t_ours, args.repeats)
    theo = AeroelasticModel(cfg.wing, cfg.maxwell_design, TheodorsenAero())
    t_pk, res_pk = best(lambda: flutter_speed(theo, rho), 3)
    print(f"Theodorsen p-k: {res_pk.critical_airspeed:.4f} m/s ({res_pk.kind}) "
          f"in {t_pk * 1e3:.0f} ms")


if __name__ == "__main__":
    main()
