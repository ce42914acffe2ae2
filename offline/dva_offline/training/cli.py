"""``dva train``: plan and record the training sweep, train the RBF controller (Zhang (2006) 7.2).

Subcommands::

    dva train plan    the (U, rho, c2) dwells to record: 0.8 .. 1.14 U_cr, rho0 x 0.9/1.0/1.1,
                      c2 around the exact optimum c2*(U, rho) where the wing decays (JSON)
    dva train sweep   fly the plan (default: the default plan) with every dwell started from
                      its stationary state, and record it to a rosbag2 MCAP bag through the
                      batch path (the node graph's topics); --scenario flies a scenario sweep
    dva train rbf     read a recorded sweep (the bag alone), label every window with the exact
                      c2*(U, rho) of its condition (or --labels measured-argmin, the study's
                      procedure, which fails), train the RBF network by OLS with the spread
                      chosen on held-out airspeeds, save it for the rbf_controller node

Every dwell of a plan starts from its own stationary state (drawn from the exact stationary
covariance of its condition), so no dwell inherits a transient and no c2 needs a settling
time; only pairs that decay at ``--min-decay`` 1/s or faster are planned, so the recording
covers the airspeeds near and above U_cr where c2 matters. ``--scenario FILE`` flies a stepped
scenario sweep as one continuous flight instead (the graph's path), keeping the leading
airspeeds at which every c2 of its list decays at ``--min-decay`` (``--as-is``: unchanged).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from dva_offline.cli_tools import command_family, range3

__all__ = ["register"]

DEFAULT_RATIOS = "0.8:1.14:0.002"  # U/U_cr: the study's training airspeeds
DEFAULT_FACTORS = "0.9,1.0,1.1"  # rho / rho0
DEFAULT_N_DAMPING = 10  # c2 per (U, rho); the study used 20 (docs/training.md: no better)
SCENARIO_C2 = "200:770:20"  # [N s/m] c2 list of an adapted scenario sweep


def register(subparsers) -> None:
    """Add the ``train`` command and its subcommands."""
    from dva_offline.training import rbf_cli as train_rbf_cli

    p, sub = command_family(subparsers, "train",
                            "plan and record the training sweep, train the RBF network",
                            __doc__, "train_command")

    pl = sub.add_parser("plan", help="the (U, rho, c2) dwells of the training sweep (JSON)",
                        description="Plan the training dwells: airspeeds x densities, c2 "
                                    "around the exact optimum inside the interval where the "
                                    "wing decays at --min-decay.")
    _plan_options(pl)
    pl.add_argument("--out", metavar="plan.json", required=True, help="plan file to write")
    pl.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    pl.set_defaults(func=_plan)

    s = sub.add_parser("sweep", help="fly and record the training sweep (MCAP)",
                       description="Fly the training plan (default: the default plan; "
                                   "--plan FILE, or the plan options) with each dwell started "
                                   "from its stationary state, and record it; or fly a "
                                   "scenario sweep (--scenario).")
    s.add_argument("--plan", metavar="FILE", help="plan JSON (dva train plan); default: make "
                   "the plan from the options below")
    _plan_options(s)
    s.add_argument("--out", metavar="BAG_DIR",
                   help="bag directory to create (default runs/train_sweep_<UTC time>)")
    s.add_argument("--no-displacement", dest="displacement", action="store_false",
                   help="record only what a wing test measures (no /wing/displacement); "
                        "dva train rbf, run reports and replays need the displacement")
    g = s.add_argument_group("scenario sweep (one continuous flight instead of a plan)")
    g.add_argument("--scenario", metavar="FILE", help="stepped sweep scenario YAML (e.g. "
                   "the package's scenario_sweep.yaml); at most 20,000,000 samples "
                   "(duration x sample rate, 100..20000 Hz)")
    g.add_argument("--c2", metavar="MIN:MAX:N", default=None,
                   help=f"c2 values at each airspeed [N s/m] (default {SCENARIO_C2}; "
                        "'scenario' keeps the file's list)")
    g.add_argument("--settle", type=float, default=None,
                   help="[s] settling time at the start of each dwell (default 2)")
    g.add_argument("--as-is", action="store_true",
                   help="fly the scenario unchanged (no stability check, its own c2 and dwell)")
    g.add_argument("--jobs", type=_jobs, default=None, metavar="N",
                   help="processes, each recording a part of the sweep into its own file "
                        "of a split bag (default 0: one per core, at most 4; 1: one file)")
    s.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    s.set_defaults(func=_sweep)

    train_rbf_cli.register(sub)


#: The plan options, their defaults, and which of them a scenario sweep uses.
PLAN_DEFAULTS = {"ratios": DEFAULT_RATIOS, "factors": DEFAULT_FACTORS,
                 "n_damping": DEFAULT_N_DAMPING, "min_decay": 0.2, "max_offset": 300.0,
                 "window": 2.0, "seed": 7}
SCENARIO_PLAN_OPTIONS = ("--min-decay", "--window")  # the rest come from the scenario file


def _options(dests) -> list[str]:
    return ["--" + d.replace("_", "-") for d in dests]


def _resolve(args, defaults: dict) -> None:
    """Give the options of ``defaults`` that were not given their default value."""
    for dest, value in defaults.items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, value)


def _check_sweep_options(args) -> None:
    """Refuse the options the chosen sweep has no use for (one line, exit 2)."""
    from dva_offline.cli_tools import not_with

    plan_options = _options(PLAN_DEFAULTS)
    scenario_only = ("--c2", "--settle", "--as-is", "--jobs")
    if args.scenario:
        not_with(args, "is for a plan, not a --scenario sweep", "--plan", "--wing",
                 *(o for o in plan_options if o not in SCENARIO_PLAN_OPTIONS))
        if args.as_is:
            not_with(args, "adapts the scenario, which --as-is flies unchanged", "--c2",
                     "--settle", *SCENARIO_PLAN_OPTIONS)
        _resolve(args, {"c2": SCENARIO_C2, "settle": 2.0, "jobs": 0,
                        "min_decay": PLAN_DEFAULTS["min_decay"],
                        "window": PLAN_DEFAULTS["window"]})
        return
    not_with(args, "is for a scenario sweep: it needs --scenario FILE", *scenario_only)
    if args.plan:
        not_with(args, "makes a plan, but --plan gives one", *plan_options)
    _resolve(args, PLAN_DEFAULTS)


def _plan_options(p) -> None:
    p.add_argument("--wing", metavar="FILE", help="wing YAML with a Maxwell absorber "
                   "(default: the chapter-6 wing)")
    p.add_argument("--ratios", metavar="START:STOP:STEP", default=None,
                   help=f"airspeeds U/U_cr (default {DEFAULT_RATIOS}, the study's)")
    p.add_argument("--factors", metavar="F1,F2,...", default=None,
                   help=f"densities rho/rho0 (default {DEFAULT_FACTORS})")
    p.add_argument("--n-damping", type=int, default=None,
                   help=f"c2 values per (U, rho) (default {DEFAULT_N_DAMPING})")
    p.add_argument("--min-decay", type=float, default=None,
                   help="[1/s] decay rate every planned (U, rho, c2) has at least (default "
                        "0.2); a scenario sweep's: every c2 at a kept airspeed (default 0.2)")
    p.add_argument("--max-offset", type=float, default=None,
                   help="[N s/m] c2 within c2* +- this (default 300)")
    p.add_argument("--window", type=float, default=None,
                   help="[s] window = dwell of a plan (default 2, the study's); at most "
                        "600,000 samples (10 min at 1 kHz), and the whole plan at most "
                        "20,000,000 samples (dwells x window x sample rate)")
    p.add_argument("--seed", type=int, default=None, help="excitation seed (default 7)")


def _jobs(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expects an integer >= 0, got {text!r}")
    return value


def _range3(option: str, text: str):
    """``MIN:MAX:N`` -> N evenly spaced values, 0 <= MIN < MAX."""
    return np.linspace(*range3(option, text, "MIN:MAX:N", minimum=0.0))


# -- plan -------------------------------------------------------------------------------------

def _wing(path):
    from aero_dva.control.dva_design import bare_critical_airspeed
    from aero_dva.wing.absorbers import MaxwellAbsorber
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import default_wing_path, load_wing, wing_fingerprint

    path = Path(path) if path else default_wing_path()
    cfg = load_wing(path)
    if not isinstance(cfg.absorber, MaxwellAbsorber):
        raise ValueError(f"--wing {path}: the file needs a Maxwell absorber whose c2 is tuned")
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    u_cr = bare_critical_airspeed(cfg.wing, cfg.air_density, cfg.aero)
    return cfg, model, u_cr, (str(path.resolve()), wing_fingerprint(cfg))


def _make_plan(args):
    """(plan, model, (wing file, its fingerprint)) from --plan or the plan options."""
    from dva_offline.training.plan import PlanSettings, make_training_plan, ratio_grid
    from dva_offline.training.plan_io import load_plan, plan_wing_file

    if getattr(args, "plan", None):
        plan, wing = load_plan(args.plan)
        _, model, u_cr, wing = _wing(args.wing or plan_wing_file(args.plan, wing))
        if abs(u_cr / plan.critical_airspeed - 1) > 1e-6:
            raise ValueError(f"--plan {args.plan}: made for a wing with U_cr = "
                             f"{plan.critical_airspeed:.4f} m/s, the wing {wing[0]} has "
                             f"{u_cr:.4f} m/s (give the plan's wing with --wing)")
        return plan, model, wing
    parts = args.ratios.split(":")
    try:
        start, stop, step = (float(v) for v in parts)
    except ValueError:
        raise ValueError(f"--ratios expects START:STOP:STEP, got {args.ratios!r}") from None
    try:
        factors = tuple(float(v) for v in args.factors.split(",") if v.strip())
    except ValueError:
        raise ValueError(f"--factors expects numbers separated by commas, got "
                         f"{args.factors!r}") from None
    cfg, model, u_cr, wing = _wing(args.wing)
    try:
        settings = PlanSettings(ratios=ratio_grid(start, stop, step), factors=factors,
                                n_damping=args.n_damping, min_decay=args.min_decay,
                                max_offset=args.max_offset, window=args.window,
                                seed=args.seed)
    except ValueError as exc:
        raise ValueError(f"plan options: {exc}") from None
    return make_training_plan(model, u_cr, cfg.air_density, settings), model, wing


def _plan_summary(plan, wing) -> dict:
    s = plan.settings
    span = plan.stable_high - plan.stable_low
    return {
        "wing": wing[0], "wing_fingerprint": wing[1],
        "critical_airspeed_no_dva": plan.critical_airspeed,
        "base_density": plan.base_density, "dwells": plan.n_dwells,
        "duration_s": plan.duration, "airspeeds": len(s.ratios),
        "airspeed_ratio_range": [s.ratios[0], s.ratios[-1]], "factors": list(s.factors),
        "n_damping": s.n_damping, "min_decay_per_s": s.min_decay,
        "max_offset": s.max_offset, "window_s": s.window, "seed": s.seed,
        "optimal_c2_range": [float(np.nanmin(plan.optimal_damping)),
                             float(np.nanmax(plan.optimal_damping))],
        "planned_c2_range": [float(plan.damping.min()), float(plan.damping.max())],
        "stable_interval_width_range": [float(np.nanmin(span)), float(np.nanmax(span))],
        "skipped_conditions": [{"ratio": r, "factor": f} for r, f in plan.skipped],
    }


def _print_plan(summary: dict) -> None:
    print(f"wing                {summary['wing']} (U_cr {summary['critical_airspeed_no_dva']:.3f}"
          f" m/s without DVA, rho0 {summary['base_density']:g} kg/m^3)")
    lo, hi = summary["airspeed_ratio_range"]
    print(f"conditions          {summary['airspeeds']} airspeeds {lo:g} .. {hi:g} U_cr x "
          f"densities {summary['factors']} x rho0, {len(summary['skipped_conditions'])} "
          f"left out (no c2 decays at {summary['min_decay_per_s']:g} 1/s)")
    skipped = summary["skipped_conditions"]
    if skipped:
        print("left out            " + ", ".join(f"{c['ratio']:g} U_cr x {c['factor']:g}"
                                                 for c in skipped[:8])
              + (" ..." if len(skipped) > 8 else ""))
    a, b = summary["optimal_c2_range"]
    c, d = summary["planned_c2_range"]
    print(f"c2* (exact optimum) {a:.1f} .. {b:.1f} N s/m; planned c2 {c:.1f} .. {d:.1f} N s/m, "
          f"{summary['n_damping']} per condition within c2* +- {summary['max_offset']:g}")
    print(f"dwells              {summary['dwells']} x {summary['window_s']:g} s = "
          f"{summary['duration_s']:.0f} s of flight, each from its stationary state")


def _plan(args) -> int:
    from dva_offline.training.plan_io import save_plan

    _resolve(args, PLAN_DEFAULTS)
    plan, _, wing = _make_plan(args)
    out = save_plan(plan, args.out, wing[0])
    summary = {"plan": str(Path(out).resolve()), **_plan_summary(plan, wing)}
    if args.json:
        print(json.dumps(summary))
    else:
        _print_plan(summary)
        print(f"saved               {summary['plan']}")
    return 0


# -- sweep ------------------------------------------------------------------------------------

def _out_dir(args) -> Path:
    if not args.out:  # a default name another run took in the same second moves on
        from aero_dva.atomic_io import unique_directory

        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        return unique_directory(Path(f"runs/train_sweep_{stamp}").resolve(), "sweep bag")
    out = Path(args.out).resolve()  # held by this run alone (cli_tools.outputs_held)
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"--out {out} exists; choose a new bag directory")
    return out


@contextlib.contextmanager
def _recording_into(out: Path):
    """Around a sweep's recording into ``out`` (created by this run): an error removes the
    bag (nothing is left that looks like a sweep); an interrupt keeps what was recorded,
    closed and marked interrupted in its metadata.yaml (``dva train rbf --allow-partial``
    reads it and says what is missing), or removes it if it was never closed."""
    try:
        yield
    except KeyboardInterrupt:
        from aero_dva.bag.writer import interruption_reason, mark_interrupted

        if mark_interrupted(out, interruption_reason(KeyboardInterrupt, None)):
            print(f"dva train: the sweep recorded so far is kept in {out}, marked "
                  "interrupted (dva train rbf reads it only with --allow-partial)",
                  file=sys.stderr)
        else:
            shutil.rmtree(out, ignore_errors=True)
        raise
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)
        raise


def _sweep(args) -> int:
    _check_sweep_options(args)
    if args.scenario:
        from dva_offline.training.scenario_sweep import scenario_sweep

        out = _out_dir(args)
        with _recording_into(out):
            return scenario_sweep(args, out, _range3)
    from tqdm import tqdm

    from dva_offline.training.recording_io import record_plan

    out = _out_dir(args)
    plan, model, wing = _make_plan(args)
    bar = tqdm(total=plan.n_dwells * plan.settings.window_samples, desc="sweep",
               unit="sample", unit_scale=True, file=sys.stderr, leave=False)

    def progress(done, total):
        bar.update(done - bar.n)

    try:
        with _recording_into(out):
            recorded = record_plan(out, model, plan, wing=wing[0], wing_fingerprint=wing[1],
                                   displacement=args.displacement, progress=progress)
    finally:
        bar.close()
    summary = {"bag": str(out), "outcome": "completed", "sim_time_s": recorded.sim_time,
               "wall_time_s": recorded.wall_time,
               "real_time_factor": recorded.sim_time / recorded.wall_time,
               "samples": recorded.samples, "topics": list(recorded.topics),
               "bag_bytes": recorded.bag_bytes, "initial_state": "stationary",
               **_plan_summary(plan, wing)}
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"bag                 {out}")
    print(f"flown               {recorded.sim_time:.0f} s of sim time in "
          f"{recorded.wall_time:.1f} s wall ({summary['real_time_factor']:.0f}x real time), "
          f"{recorded.bag_bytes / 1e6:.0f} MB")
    _print_plan(summary)
    return 0
