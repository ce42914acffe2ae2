"""``dva control``: optimal damper c2 versus airspeed; the airspeed schedule (Zhang (2006) 7.1).

Subcommands::

    dva control optimal-c2   optimal c2 and minimum RMS versus airspeed (fig. 7.1-7.4)
    dva control schedule     fit c2 = a0 + a1 U (eq. 7.1) and write the airspeed controller's
                             schedule file

The objective is the exact stationary RMS of the wing's response (leading edge by default, the
the study's choice; or plunge, or rotation = pitch) to a white aileron force of ``--force-std`` N
per sample at ``--sample-rate`` Hz, held over each sample as in the simulator. Airspeeds are
in m/s, or ratios of the bare wing's critical airspeed U_cr with ``--relative``; c2 in N s/m.

Default fit range of ``schedule``: the study fits eq. 7.1 on U = 115 to 120 m/s, the near-linear
top end of its optimal-c2 curve where the wing is about to become unstable. The exact
stationary RMS exists only where the wing is stable, so the default here is the top
0.05 U_cr (the width of the study's 5 m/s at U_cr ~ 100 m/s) of the contiguous range of
airspeeds at which some c2 of the grid keeps the wing stable: [U_s - 0.05 U_cr, U_s].
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from aero_dva.flight.damper import DAMPER_RANGE
from dva_offline.cli_tools import command_family, emit, finite, not_with, range2, range3

__all__ = ["register"]

DEFAULT_AIRSPEEDS = "0.8:1.2:201"  # ratios of U_cr (the study's fig. 7.4 range, 0.002 U_cr step)
DEFAULT_C2 = "{:g}:{:g}:101".format(*DAMPER_RANGE)  # [N s/m] the simulator's damper range
DEFAULT_CURVES = "0.5,1.0,1.06,1.12"  # U / U_cr of the study's fig. 7.1-7.3
FIT_WIDTH = 0.05  # [U_cr] width of the default fit range
SCHEDULE_DESCRIPTION = (
    "Fit eq. 7.1, c2 = a0 + a1 U, by least squares to the optimal c2 and write it as the "
    "airspeed_controller's schedule file. Default fit range: the study fits U = 115 to 120 m/s, "
    "the near-linear top end of its optimal-c2 curve, just below and beyond its stability "
    "limit. The exact stationary RMS exists only where the wing is stable, so the default is "
    f"the top {FIT_WIDTH} U_cr (the study's 5 m/s at U_cr ~ 100 m/s) of the contiguous range of "
    "airspeeds at which some c2 of the grid keeps the wing stable: [U_s - 0.05 U_cr, U_s]."
)


# -- argument parsing ---------------------------------------------------------------------------

def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--wing", metavar="FILE", help="wing YAML with a Maxwell absorber "
                   "(default: the chapter-6 wing)")
    p.add_argument("--density", type=float, default=None,
                   help="air density [kg/m^3] (default: the wing file's)")
    p.add_argument("--objective", choices=("leading_edge", "plunge", "rotation"),
                   default="leading_edge",
                   help="RMS to minimise (default leading_edge, the study's choice)")
    p.add_argument("--airspeeds", metavar="START:STOP:N", default=None,
                   help="airspeed grid [m/s], or ratios U/U_cr with --relative "
                        f"(default: ratios {DEFAULT_AIRSPEEDS})")
    p.add_argument("--relative", action="store_true",
                   help="airspeeds (and --fit-range) are ratios of the bare wing's U_cr")
    p.add_argument("--c2-range", metavar="MIN:MAX:N", default=DEFAULT_C2,
                   help=f"c2 grid [N s/m], evenly spaced (default {DEFAULT_C2})")
    p.add_argument("--force-std", type=float, default=1000.0,
                   help="aileron force standard deviation per sample [N] (default 1000)")
    p.add_argument("--sample-rate", type=float, default=1000.0,
                   help="sample rate [Hz] (default 1000)")
    p.add_argument("--method", choices=("discrete", "continuous"), default="discrete",
                   help="exact RMS of the sampled system as simulated (default) or of its "
                        "continuous limit")
    p.add_argument("--plot", metavar="FILE.png", help="write a PNG figure")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def register(subparsers) -> None:
    """Add the ``control`` command and its subcommands."""
    p, sub = command_family(subparsers, "control",
                            "optimal c2 versus airspeed, airspeed schedule", __doc__,
                            "control_command")

    o = sub.add_parser("optimal-c2", help="optimal c2 and minimum RMS vs airspeed (fig. 7.4)",
                       description="Optimal c2 minimising the exact stationary RMS of the "
                                   "objective at each airspeed of the grid (Zhang (2006) "
                                   "fig. 7.1-7.4).")
    _common(o)
    o.add_argument("--curves", metavar="R1,R2,...", default=None,
                   help="U/U_cr of the RMS-versus-c2 curves of --plot "
                        f"(default {DEFAULT_CURVES}, as fig. 7.1-7.3)")
    o.add_argument("--surface", action="store_true",
                   help="include the RMS surfaces (all outputs, every grid point) in --json")
    o.add_argument("--check-simulation", type=int, default=0, metavar="K",
                   help="also simulate the optimum at K airspeeds across the stable range and "
                        "compare with the exact RMS (default 0: no)")
    o.add_argument("--sim-duration", type=float, default=None,
                   help="[s] kept per simulated flight after settling, with --check-simulation "
                        "(default 20)")
    o.add_argument("--flights", type=int, default=None,
                   help="simulated flights per airspeed, with --check-simulation (default 4)")
    o.add_argument("--seed", type=int, default=None,
                   help="random seed of the simulations, with --check-simulation (default 0)")
    o.set_defaults(func=_optimal_c2)

    s = sub.add_parser("schedule", help="fit c2 = a0 + a1 U (eq. 7.1) and write the file the "
                                        "airspeed_controller reads",
                       description=SCHEDULE_DESCRIPTION)
    _common(s)
    s.add_argument("--fit-range", metavar="U_MIN:U_MAX", default=None,
                   help="airspeeds of the fit [m/s], or ratios with --relative (default: the "
                        f"top {FIT_WIDTH} U_cr of the stable range, see above)")
    s.add_argument("--damping-range", metavar="MIN:MAX", default=None,
                   help="damper range the schedule clamps to [N s/m] (default: the c2 grid's)")
    s.add_argument("--out", metavar="schedule.json", required=True,
                   help="schedule file to write (the airspeed_controller's schedule_file)")
    s.set_defaults(func=_schedule)


# -- shared work --------------------------------------------------------------------------------

def _finite_list(values):
    return [finite(v) for v in np.asarray(values, dtype=float).ravel()]


def _setup(args):
    """Model, density, critical airspeed, airspeed grid and c2 grid from the arguments."""
    from aero_dva.control.dva_design import bare_critical_airspeed
    from aero_dva.wing.absorbers import MaxwellAbsorber
    from aero_dva.wing.aerodynamics import TheodorsenAero
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import load_wing

    cfg = load_wing(args.wing)
    if not isinstance(cfg.absorber, MaxwellAbsorber):
        raise ValueError(f"--wing {args.wing or 'chapter6'}: the file needs a Maxwell absorber "
                         "(absorber: type: maxwell) whose c2 is tuned")
    if isinstance(cfg.aero, TheodorsenAero):
        raise ValueError("the wing file's aero must be quasi-steady or wagner (time domain)")
    rho = cfg.air_density if args.density is None else args.density
    if not (math.isfinite(rho) and rho > 0):
        raise ValueError(f"--density must be > 0, got {rho}")
    if not (math.isfinite(args.force_std) and args.force_std > 0):
        raise ValueError(f"--force-std must be > 0, got {args.force_std}")
    if not (math.isfinite(args.sample_rate) and args.sample_rate > 0):
        raise ValueError(f"--sample-rate must be > 0, got {args.sample_rate}")
    u_cr = bare_critical_airspeed(cfg.wing, rho, cfg.aero)
    relative = args.relative or args.airspeeds is None
    start, stop, n = range3("--airspeeds", args.airspeeds or DEFAULT_AIRSPEEDS)
    if start < 0:
        raise ValueError("--airspeeds must be >= 0")
    speeds = np.linspace(start, stop, n) * (u_cr if relative else 1.0)
    c_lo, c_hi, n_c = range3("--c2-range", args.c2_range)
    if c_lo < 0 or n_c < 3:
        raise ValueError("--c2-range needs MIN >= 0 and N >= 3")
    grid = np.linspace(c_lo, c_hi, n_c)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    return model, rho, u_cr, speeds, grid


def _solve(args, model, rho, speeds, grid):
    from tqdm import tqdm

    from aero_dva.control.optimal_damping import optimal_damping

    bar = tqdm(total=speeds.size, desc="exact RMS", unit="airspeed", file=sys.stderr,
               leave=False)
    done = [0]

    def progress(k):
        bar.update(k - done[0])
        done[0] = k

    t0 = time.perf_counter()
    try:
        res = optimal_damping(model, speeds, grid, rho, objective=args.objective,
                              force_std=args.force_std, sample_rate=args.sample_rate,
                              method=args.method, progress=progress)
    finally:
        bar.close()
    return res, time.perf_counter() - t0


def _rms_unit(objective: str) -> str:
    return "rad" if objective == "rotation" else "m"


def _base_payload(args, res, u_cr, elapsed) -> dict:
    limit = res.stable_airspeed_limit()
    return {
        "wing": args.wing or "chapter6",
        "density": res.density,
        "objective": res.objective,
        "method": res.method,
        "force_std": res.force_std,
        "sample_rate": res.sample_rate,
        "critical_airspeed": u_cr,
        "c2_grid": {"min": float(res.damping_grid[0]), "max": float(res.damping_grid[-1]),
                    "n": int(res.damping_grid.size)},
        "n_airspeeds": int(res.airspeeds.size),
        "stable_limit": {"airspeed": finite(limit),
                         "ratio": finite(limit / u_cr) if math.isfinite(limit) else None},
        "rms_unit": _rms_unit(res.objective),
        "elapsed_s": elapsed,
    }


# -- optimal-c2 ---------------------------------------------------------------------------------

def _curve_ratios(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--curves expects comma-separated ratios, got {text!r}") from None
    if not values or any(not math.isfinite(v) or v < 0 for v in values):
        raise ValueError(f"--curves needs ratios >= 0, got {text!r}")
    return values


def _simulation_check(args, model, rho, res, u_cr) -> dict:
    from tqdm import tqdm

    from aero_dva.control.optimal_damping import simulated_rms

    flights = 4 if args.flights is None else args.flights
    duration = 20.0 if args.sim_duration is None else args.sim_duration
    seed = 0 if args.seed is None else args.seed
    if flights < 1 or not duration > 0:
        raise ValueError("--flights must be >= 1 and --sim-duration > 0")
    # Spread over the stable range, short of its last 0.02 U_cr: right at the stability limit
    # the response is so slowly correlated that a simulation of reasonable length says little.
    limit = res.stable_airspeed_limit()
    ok = np.flatnonzero(res.has_optimum & (res.airspeeds <= limit - 0.02 * u_cr))
    if ok.size == 0:
        ok = np.flatnonzero(res.has_optimum)
    if ok.size == 0:
        raise ValueError("no airspeed has a stable c2: nothing to simulate")
    pick = ok[np.unique(np.linspace(0, ok.size - 1, args.check_simulation).round().astype(int))]
    rng = np.random.default_rng(seed)
    rows = []
    t0 = time.perf_counter()
    k = ("plunge", "pitch", "leading_edge").index(
        {"rotation": "pitch"}.get(res.objective, res.objective))
    for i in tqdm(pick, desc="simulating", unit="airspeed", file=sys.stderr, leave=False):
        sim = simulated_rms(model, [res.airspeeds[i]], [res.optimal_damping[i]], rho, rng=rng,
                            duration=duration, flights=flights,
                            objective=res.objective, force_std=args.force_std,
                            sample_rate=args.sample_rate)
        rows.append({"airspeed": float(res.airspeeds[i]),
                     "ratio": float(res.airspeeds[i] / u_cr),
                     "c2": float(res.optimal_damping[i]),
                     "exact_rms": float(sim.exact[k, 0, 0]),
                     "simulated_rms": float(sim.rms[k, 0, 0]),
                     "relative_standard_error": float(sim.relative_standard_error[k, 0, 0]),
                     "z": float(sim.z_score[k, 0, 0]),
                     "settle_time": float(sim.settle_time[0, 0])})
    return {"duration": duration, "flights": flights, "seed": seed,
            "elapsed_s": time.perf_counter() - t0, "points": rows,
            "max_abs_z": max(abs(r["z"]) for r in rows)}


def _optimal_c2(args) -> int:
    from aero_dva.control.optimal_damping import RMS_OUTPUTS, optimal_damping

    not_with(args, "sets the curves of the figure: it needs --plot FILE.png", "--curves")
    if args.check_simulation < 0:
        raise ValueError(f"--check-simulation must be >= 0, got {args.check_simulation}")
    if not args.check_simulation:
        not_with(args, "sets the simulated check: it needs --check-simulation K",
                 "--sim-duration", "--flights", "--seed")
    model, rho, u_cr, speeds, grid = _setup(args)
    curves = _curve_ratios(DEFAULT_CURVES if args.curves is None else args.curves)
    res, elapsed = _solve(args, model, rho, speeds, grid)
    payload = _base_payload(args, res, u_cr, elapsed)
    payload.update({
        "airspeed": res.airspeeds.tolist(),
        "airspeed_ratio": (res.airspeeds / u_cr).tolist(),
        "optimal_c2": _finite_list(res.optimal_damping),
        "min_rms": _finite_list(res.min_rms),
        "at_bound": res.at_bound.tolist(),
    })
    if args.surface:
        payload["surface"] = {"outputs": list(RMS_OUTPUTS), "units": ["m", "rad", "m"],
                              "c2": res.damping_grid.tolist(),
                              "rms": [[_finite_list(row) for row in out] for out in res.rms]}
    if args.check_simulation:
        payload["simulation_check"] = _simulation_check(args, model, rho, res, u_cr)
    if args.plot:
        curve_res = optimal_damping(model, np.array(curves) * u_cr, grid, rho,
                                    objective=args.objective, force_std=args.force_std,
                                    sample_rate=args.sample_rate, method=args.method)
        _plot_optimal(res, curve_res, u_cr, args.plot)
        payload["plot"] = args.plot
    lines = _summary_lines(res, u_cr, elapsed)
    if args.check_simulation:
        chk = payload["simulation_check"]
        lines.append(f"simulated check ({chk['flights']} x {chk['duration']:g} s per airspeed):")
        lines += [f"  U/U_cr {r['ratio']:.3f}: exact {r['exact_rms']:.4g}, simulated "
                  f"{r['simulated_rms']:.4g} (z = {r['z']:+.2f}, "
                  f"SE {100 * r['relative_standard_error']:.1f} %)"
                  for r in chk["points"]]
    emit(args, payload, lines)
    return 0


def _summary_lines(res, u_cr, elapsed) -> list[str]:
    unit = _rms_unit(res.objective)
    limit = res.stable_airspeed_limit()
    lines = [f"objective: {res.objective} RMS ({res.method}), {res.airspeeds.size} airspeeds x "
             f"{res.damping_grid.size} c2 values in {elapsed:.2f} s; U_cr = {u_cr:.4g} m/s",
             ("no stable c2 at the first airspeed" if not math.isfinite(limit) else
              f"stable with the best c2 up to {limit:.4g} m/s = {limit / u_cr:.4f} U_cr"),
             f"{'U [m/s]':>9} {'U/U_cr':>7} {'c2 [N s/m]':>11} {'min RMS [' + unit + ']':>14}"]
    step = max(1, res.airspeeds.size // 20)
    for i in range(0, res.airspeeds.size, step):
        c2 = res.optimal_damping[i]
        lines.append(f"{res.airspeeds[i]:9.3f} {res.airspeeds[i] / u_cr:7.4f} "
                     + (f"{c2:11.2f} {res.min_rms[i]:14.5g}" if math.isfinite(c2) else
                        f"{'-':>11} {'unstable':>14}")
                     + ("  (grid end)" if res.at_bound[i] else ""))
    return lines


def _plain_log_labels(axis) -> None:
    """Tick labels of a log axis as plain numbers (0.2, 0.5, 1), not 2 x 10^-1."""
    import matplotlib.ticker as ticker

    plain = ticker.FuncFormatter(lambda v, _: f"{v:g}")
    axis.set_major_formatter(plain)
    axis.set_minor_formatter(ticker.FuncFormatter(
        lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""))


def _plot_optimal(res, curves, u_cr, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5))
    titles = ("plunge RMS [mm] (fig. 7.1)", "pitch RMS [mrad] (fig. 7.2)",
              "leading-edge RMS [mm] (fig. 7.3)")
    for k, ax in enumerate(axes.ravel()[:3]):
        ax.set_ylabel(titles[k].split(" (")[0])
        for i, speed in enumerate(curves.airspeeds):
            note = "" if curves.has_optimum[i] else " (unstable at every c2)"
            ax.plot(curves.damping_grid, curves.rms[k, i] * 1e3,
                    label=f"U = {speed / u_cr:.2f} U_cr{note}")
        ax.set_xlabel("c2 [N s/m]")
        ax.set_title(titles[k], fontsize=10)
        ax.set_yscale("log")
        _plain_log_labels(ax.yaxis)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    ax = axes[1, 1]
    ratio = res.airspeeds / u_cr
    ax.plot(ratio, res.optimal_damping, "b-")
    ax.set_xlabel("U / U_cr [-]")
    ax.set_ylabel("optimal c2 [N s/m]", color="b")
    ax.grid(True, alpha=0.3)
    twin = ax.twinx()
    scale, unit = (1e3, "mrad") if res.objective == "rotation" else (1e3, "mm")
    twin.semilogy(ratio, np.where(np.isfinite(res.min_rms), res.min_rms * scale, np.nan), "r-")
    twin.set_ylabel(f"min {res.objective} RMS [{unit}]", color="r")
    _plain_log_labels(twin.yaxis)
    ax.set_title(f"optimal c2 and minimum RMS (fig. 7.4, {res.objective})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# -- schedule -----------------------------------------------------------------------------------

def _fit_range(args, res, u_cr):
    """(low, high) [m/s] of the fit and a sentence saying where it came from."""
    if args.fit_range is not None:
        low, high = range2("--fit-range", args.fit_range)
        scale = u_cr if args.relative else 1.0
        return low * scale, high * scale, "--fit-range"
    limit = res.stable_airspeed_limit()
    if not math.isfinite(limit):
        raise ValueError("no c2 of the grid keeps the wing stable at the first airspeed, so "
                         "there is no default fit range: give --fit-range")
    low = limit - FIT_WIDTH * u_cr
    return low, limit, (f"default: top {FIT_WIDTH} U_cr of the stable range "
                        f"(stable up to {limit / u_cr:.4f} U_cr)")


def _schedule(args) -> int:
    from aero_dva.control.airspeed_schedule import fit_airspeed_schedule
    from aero_dva.control.schedule_io import load_schedule, save_schedule
    from aero_dva.flight.damper import check_damping

    model, rho, u_cr, speeds, grid = _setup(args)
    if args.damping_range is not None:
        damping_range = range2("--damping-range", args.damping_range)
        if damping_range[0] < 0:
            raise ValueError("--damping-range MIN must be >= 0")
    else:
        damping_range = (float(grid[0]), float(grid[-1]))
    check_damping(damping_range, "--damping-range" if args.damping_range is not None
                  else "--c2-range (the schedule's damping range without --damping-range)")
    res, elapsed = _solve(args, model, rho, speeds, grid)
    low, high, source = _fit_range(args, res, u_cr)
    inside = (res.airspeeds >= low - 1e-9 * high) & (res.airspeeds <= high + 1e-9 * high)
    usable = inside & res.has_optimum
    if np.count_nonzero(usable) < 2:
        raise ValueError(f"fit range {low:.4g} .. {high:.4g} m/s holds "
                         f"{np.count_nonzero(usable)} airspeeds with a stable optimum; "
                         "need at least 2 (widen --fit-range or refine --airspeeds)")
    if np.count_nonzero(inside) > np.count_nonzero(usable):
        print(f"dva control schedule: warning: {np.count_nonzero(inside & ~usable)} airspeeds "
              "in the fit range have no stable c2 and are left out", file=sys.stderr)
    u_fit = res.airspeeds[usable]
    # the grid may miss a range end by rounding: never let that drop an end point
    low, high = min(low, float(u_fit.min())), max(high, float(u_fit.max()))
    fit = fit_airspeed_schedule(u_fit, res.optimal_damping[usable], damping_range, (low, high))
    sch = fit.schedule
    description = (
        f"least-squares fit of eq. 7.1 to the optimal c2 minimising the exact stationary "
        f"{res.objective} RMS ({res.method}, {res.force_std:g} N per sample at "
        f"{res.sample_rate:g} Hz) of wing {args.wing or 'chapter6'} at rho = {rho:g} kg/m^3; "
        f"U = {low:.4g} .. {high:.4g} m/s ({low / u_cr:.4f} .. {high / u_cr:.4f} U_cr, "
        f"{source}); {fit.n_points} points, RMSE {fit.rmse:.4g} N s/m, R^2 {fit.r_squared:.5f}"
    )
    path = save_schedule(sch, args.out, description)
    check = load_schedule(path)  # the file reads back as the controller will read it
    if (check.a0, check.a1) != (sch.a0, sch.a1):
        raise ValueError(f"{path}: the schedule did not read back unchanged")
    payload = _base_payload(args, res, u_cr, elapsed)
    payload.update({
        "schedule_file": str(path),
        "a0": sch.a0,
        "a1": sch.a1,
        "fit_range": {"airspeed": [low, high], "ratio": [low / u_cr, high / u_cr],
                      "source": source},
        "damping_range": list(sch.damping_range),
        "n_points": fit.n_points,
        "rmse": fit.rmse,
        "max_abs_error": fit.max_abs_error,
        "r_squared": finite(fit.r_squared),
        "description": description,
    })
    if args.plot:
        _plot_schedule(res, sch, (low, high), u_cr, args.plot)
        payload["plot"] = args.plot
    lines = [f"c2 = {sch.a0:.6g} + {sch.a1:.6g} U   [N s/m, U in m/s]  (eq. 7.1)",
             f"fit on U = {low:.4g} .. {high:.4g} m/s = {low / u_cr:.4f} .. {high / u_cr:.4f} "
             f"U_cr ({source}), {fit.n_points} points",
             f"RMSE {fit.rmse:.4g} N s/m, max error {fit.max_abs_error:.4g} N s/m, "
             f"R^2 {fit.r_squared:.5f}",
             f"clamped to {sch.damping_range[0]:g} .. {sch.damping_range[1]:g} N s/m; "
             f"written to {path}"]
    emit(args, payload, lines)
    return 0


def _plot_schedule(res, schedule, fit_range, u_cr, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5))
    ax.axvspan(fit_range[0] / u_cr, fit_range[1] / u_cr, color="0.85", label="fit range")
    ratio = res.airspeeds / u_cr
    ax.plot(ratio, res.optimal_damping, "b.", ms=3, label=f"optimal c2 ({res.objective})")
    ax.plot(ratio, schedule.a0 + schedule.a1 * res.airspeeds, "k--", lw=0.8,
            label="eq. 7.1 line")
    ax.plot(ratio, schedule.evaluate(res.airspeeds), "r-", lw=1.2,
            label="schedule (clamped)")
    ax.set_xlabel("U / U_cr [-]")
    ax.set_ylabel("c2 [N s/m]")
    ax.set_title(f"airspeed schedule c2 = {schedule.a0:.4g} + {schedule.a1:.4g} U", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
