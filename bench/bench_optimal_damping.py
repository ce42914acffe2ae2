"""Benchmark: optimal c2 versus airspeed, exact stationary RMS against simulated RMS (sec. 7.1).

In the same run:

- exact route: :func:`aero_dva.control.optimal_damping.optimal_damping` on 200 airspeeds
  (0.8 .. 1.2 U_cr) x 100 values of c2 (over the damper's range), leading-edge objective, sampled
  system at 1 kHz with 1 kN per sample; wall time (median of repeats) with and without the
  ``minimize_scalar`` refinement (target: under 2 s);
- the exact continuous-limit c2 map (Lyapunov) on the same grid by
  :func:`aero_dva.control.damping_map.continuous_rms_map` (one solve per airspeed, c2 entering
  through one entry; target: at most 0.1 s) against the previous route, the batched modal
  solution of :func:`~aero_dva.control.stationary_rms.stationary_rms` for every pair, timed in
  the same run; their largest relative difference and whether they agree on stability;
- simulated route (the study's): :func:`aero_dva.control.optimal_damping.simulated_rms` on a small
  subset of (airspeed, c2) pairs, each flown at constant condition, settled, then ``--duration``
  seconds kept; wall time per pair, the speed-up of the exact route per pair, the agreement
  in standard errors, and the simulated time a 1 % standard error would need.

Run: .venv/bin/python bench/bench_optimal_damping.py [--repeats 3] [--duration 10]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from aero_dva.control.damping_map import continuous_rms_map
from aero_dva.control.dva_design import bare_critical_airspeed
from aero_dva.control.optimal_damping import optimal_damping, simulated_rms
from aero_dva.control.stationary_rms import stationary_rms
from aero_dva.flight.damper import DAMPER_RANGE
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing


def timed(fn, repeats, *args, **kwargs):
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn(*args, **kwargs)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), result


def reference_continuous_map(model, speeds, grid, rho):
    """The previous route: the batched modal solution for every (airspeed, c2) pair."""
    res = stationary_rms(model, speeds[:, None], rho, grid[None, :], method="continuous")
    return res.displacement, res.stable


def continuous_map(model, speeds, grid, rho, repeats):
    """Time this revision's c2 map against the previous route (alternating); print both."""
    continuous_rms_map(model, speeds[:4], grid, rho)  # warm-up
    t_new, t_old, c_new, c_old = [], [], [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        new, st_new = continuous_rms_map(model, speeds, grid, rho)
        t_new.append(time.perf_counter() - t0)
        c_new.append(time.process_time() - c0)
        t0, c0 = time.perf_counter(), time.process_time()
        old, st_old = reference_continuous_map(model, speeds, grid, rho)
        t_old.append(time.perf_counter() - t0)
        c_old.append(time.process_time() - c0)
    fin = np.isfinite(old)
    rel = float(np.max(np.abs(new[fin] - old[fin]) / old[fin])) if fin.any() else 0.0
    t_n, t_o = float(np.median(t_new)), float(np.median(t_old))
    print(f"exact continuous-limit c2 map (Lyapunov), {speeds.size} x {grid.size} "
          f"(wall clock median / min of {repeats}, the two routes alternating):")
    print(f"  this revision    {t_n:7.3f} s / {min(t_new):.3f} s   "
          f"({'within' if t_n <= 0.1 else 'OVER'} the 0.1 s target)")
    print(f"  previous route   {t_o:7.3f} s / {min(t_old):.3f} s   -> {t_o / t_n:.1f}x "
          f"(min / min {min(t_old) / min(t_new):.1f}x)")
    cn, co = float(np.median(c_new)), float(np.median(c_old))
    print(f"  CPU time         {cn:7.3f} s this revision "
          f"({'within' if cn <= 0.1 else 'OVER'} the 0.1 s target), {co:.3f} s previous route "
          f"-> {co / cn:.1f}x")
    print(f"  largest relative difference {rel:.1e} (tolerance 1e-9); stability flags "
          f"{'identical' if np.array_equal(st_new, st_old) else 'DIFFER'} "
          f"({int(st_new.sum())} of {st_new.size} pairs stable)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--airspeeds", type=int, default=200)
    parser.add_argument("--c2", type=int, default=100)
    parser.add_argument("--duration", type=float, default=10.0,
                        help="[s] kept per simulated pair after settling (0: skip the "
                        "simulated route)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    cfg = load_wing()
    rho = cfg.air_density
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    u_cr = bare_critical_airspeed(cfg.wing, rho, cfg.aero)
    speeds = np.linspace(0.8, 1.2, args.airspeeds) * u_cr
    grid = np.linspace(*DAMPER_RANGE, args.c2)
    pairs = speeds.size * grid.size
    print(f"default (chapter-6) wing, U_cr = {u_cr:.3f} m/s, {model.n_states} states; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")

    optimal_damping(model, speeds[:4], grid, rho)  # warm-up (imports, caches)
    t_full, t_full_min, res = timed(optimal_damping, args.repeats, model, speeds, grid, rho)
    t_grid, t_grid_min, _ = timed(optimal_damping, args.repeats, model, speeds, grid, rho,
                                  refine=False)
    ok = res.has_optimum
    print(f"exact RMS, {speeds.size} airspeeds x {grid.size} c2 = {pairs} pairs "
          f"(median / min of {args.repeats}):")
    print(f"  grid only        {t_grid:7.3f} s / {t_grid_min:.3f} s")
    print(f"  grid + refine    {t_full:7.3f} s / {t_full_min:.3f} s   "
          f"({'under' if t_full < 2.0 else 'OVER'} the 2 s target)")
    print(f"  per pair         {1e6 * t_full / pairs:7.1f} us")
    print(f"  stable with the best c2 up to {res.stable_airspeed_limit() / u_cr:.4f} U_cr; "
          f"optimal c2 {np.nanmin(res.optimal_damping):.1f} .. "
          f"{np.nanmax(res.optimal_damping):.1f} N s/m over {ok.sum()} stable airspeeds")

    continuous_map(model, speeds, grid, rho, max(args.repeats, 3))
    if args.duration <= 0:
        return

    sub_u = np.array([0.85, 0.95, 1.05]) * u_cr
    sub_c = np.linspace(150.0, 1050.0, 10)
    n_sub = sub_u.size * sub_c.size
    t0 = time.perf_counter()
    sim = simulated_rms(model, sub_u, sub_c, rho, rng=np.random.default_rng(args.seed),
                        duration=args.duration)
    t_sim = time.perf_counter() - t0
    simulated_seconds = float(np.sum(sim.settle_time) + n_sub * sim.duration)
    per_sim, per_exact = t_sim / n_sub, t_full / pairs
    z = sim.z_score[2]
    print(f"simulated RMS, {sub_u.size} airspeeds x {sub_c.size} c2 = {n_sub} pairs, "
          f"{args.duration:g} s kept each after settling ({simulated_seconds:.0f} s simulated):")
    print(f"  wall time        {t_sim:7.3f} s  ({1e3 * per_sim:.1f} ms per pair, "
          f"{simulated_seconds / t_sim:.0f}x real time)")
    print(f"  speed-up of the exact route per pair: {per_sim / per_exact:.0f}x")
    stable = np.isfinite(sim.exact[2])
    rse = sim.relative_standard_error[2][stable]
    z = sim.z_score[2][stable]
    print(f"  leading-edge RMS on the {stable.sum()} stable pairs: relative standard error "
          f"{100 * rse.min():.1f} .. {100 * rse.max():.1f} %, |simulated - exact| / SE max "
          f"{np.max(np.abs(z)):.2f}, rms {np.sqrt(np.mean(z**2)):.2f}")
    exact_sub = optimal_damping(model, sub_u, grid, rho)
    for i, speed in enumerate(sub_u):
        print(f"  U = {speed / u_cr:.2f} U_cr: optimal c2 simulated (grid of {sub_c.size}) "
              f"{sim.optimal_damping[i]:7.1f}, exact {exact_sub.optimal_damping[i]:7.1f} N s/m")
    corr = stationary_rms(model, sub_u[:, None], rho, sub_c[None, :],
                          correlation=True).correlation_samples[..., 2][stable]
    need = corr / (2 * 0.01**2) / sim.sample_rate  # [s] kept for a 1 % standard error
    per_second = t_sim / simulated_seconds  # wall time per simulated second
    equal = (np.mean(need) + np.mean(sim.settle_time[stable])) * per_second
    print(f"  a 1 % standard error needs {need.min():.0f} .. {need.max():.0f} s of simulated "
          f"response per pair (+ settling), about {equal:.2f} s of wall time per pair: "
          f"at equal accuracy the exact route is {equal / per_exact:.0f}x faster")


if __name__ == "__main__":
    main()
