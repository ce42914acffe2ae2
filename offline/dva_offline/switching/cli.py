"""``dva switching``: the per-sample switching c2 law, designed and evaluated in process.

Subcommands::

    dva switching design    gains of the law and its Kalman observer from the wing model,
                            written to a checked JSON file
    dva switching plot      figure: a ramp flight with both dampers, the law at work
    dva switching mechanism per-sample laws against the ideal force they approximate
    dva switching evaluate  the law against the best constant c2 on paired seeds: bounded and
                            practical boundaries, RMS at 1.1 U_cr, switching rate, damper
                            power; sensitivity to damper lag, sensor noise, model mismatch
                            and unsteady aerodynamics

docs/switching.md describes the law and the numbers.
"""
from __future__ import annotations

import json
import math
import sys

__all__ = ["register"]


def _floats(option: str, text: str, allow_empty: bool = False) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{option} expects comma-separated numbers, got {text!r}") from None
    if allow_empty and not text.strip():
        return []
    if not values or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{option} expects finite numbers, got {text!r}")
    return values


EVALUATION_SEEDS = 100  # the evaluation's seeds start here, apart from the design's 0, 1, ...


def _seeds(n: int, first: int = 0) -> list[int]:
    if n < 2:
        raise ValueError(f"--seeds must be >= 2 (paired intervals), got {n}")
    return list(range(first, first + n))


def register(subparsers) -> None:
    from aero_dva.flight.damper import DAMPER_RANGE
    from aero_dva.flight.per_sample.switching_law import DESIGNS

    low, high = DAMPER_RANGE
    p = subparsers.add_parser("switching", help="per-sample switching c2 law: design, evaluate",
                              description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="switching_command", metavar="<subcommand>")
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])

    d = sub.add_parser("design", help="law and observer gains from the model, to a JSON file")
    d.add_argument("--out", required=True, metavar="FILE", help="gains file to write (JSON)")
    d.add_argument("--wing", metavar="FILE", help="wing YAML with a Maxwell absorber "
                   "(default: the chapter-6 wing)")
    d.add_argument("--design", choices=DESIGNS,
                   default="lyapunov",
                   help="h from the Riccati solution of the Maxwell-rate input (lyapunov), "
                        "Dyke's clipped-optimal force at the design airspeed (clipped), or "
                        "Dyke's law with the force's LQR scheduled with the airspeed, the "
                        "clipped_optimal controller's (clipped_optimal, "
                        "docs/clipped_optimal.md); default lyapunov")
    d.add_argument("--design-airspeed", type=float, default=1.15, metavar="RATIO",
                   help="design airspeed over U_cr (default 1.15): of the law and its "
                        "observer; with clipped_optimal of the observer only")
    d.add_argument("--c-lo", type=float, default=100.0,
                   help=f"low c2 [N s/m], > 0 and inside the damper's range {low:g}..{high:g} "
                        "(default 100)")
    d.add_argument("--c-hi", type=float, default=high,
                   help=f"high c2 [N s/m], inside the damper's range {low:g}..{high:g} "
                        f"(default {high:g}, its top)")
    d.add_argument("--lag", type=float, default=0.01,
                   help="damper time constant [s] the design is flown with (default 0.01)")
    d.add_argument("--efforts", default="100",
                   help="LQR control weights tried, relative (default 100)")
    d.add_argument("--leads", default="0,0.005,0.01,0.02",
                   help="leads [s] tried: F and h on the state predicted that far ahead, "
                        "against the damper lag (default 0,0.005,0.01,0.02)")
    d.add_argument("--seeds", type=int, default=4, help="ramp flights per effort (default 4)")
    d.add_argument("--noise", type=float, default=0.05,
                   help="sensor noise std / output RMS at U_cr (default 0.05)")
    d.add_argument("--aero", choices=("quasi-steady", "wagner"), default=None,
                   help="aerodynamics instead of the wing file's (wagner: Jones' finite-state "
                        "unsteady model)")
    d.set_defaults(func=_design)

    e = sub.add_parser("evaluate", help="fixed vs switching on paired seeds, sensitivities")
    e.add_argument("--gains", required=True, metavar="FILE", help="gains file of 'design'")
    e.add_argument("--wing", metavar="FILE", help="wing YAML (must match the gains file)")
    e.add_argument("--seeds", type=int, default=12, help="paired seeds (default 12)")
    e.add_argument("--lags", default="0,0.005,0.01,0.02",
                   help="damper time constants [s] of the lag table (default 0,0.005,0.01,0.02)")
    e.add_argument("--noises", default="0.2", help="sensor noise fractions besides the "
                   "design's (default 0.2)")
    e.add_argument("--mismatches", default="-0.05,0.05",
                   help="plant stiffness errors, fractions (default -0.05,0.05)")
    e.add_argument("--force-limits", default="400,250",
                   help="relief-valve force limits [N] of the switched damper: above it c2 "
                        "drops to c_lo (default 400,250)")
    e.add_argument("--yield-forces", default="",
                   help="Bingham yield forces [N] of both dampers: locked below it, c2 times "
                        "the velocity plus it above (default none)")
    e.add_argument("--blocks", default="20,50",
                   help="law decisions held over blocks of these many ms, as a slower loop "
                        "would (default 20,50)")
    e.add_argument("--no-wagner", action="store_true",
                   help="skip the flight on unsteady (Wagner) aerodynamics")
    e.add_argument("--noise", type=float, default=0.05,
                   help="sensor noise of the base setting (default 0.05)")
    e.add_argument("--cases", default="rho0",
                   help="density cases, comma-separated among rho0, x0.9, x1.1 "
                        "(docs/evaluation.md; default rho0); the sensitivities fly rho0")
    e.add_argument("--json", action="store_true", help="print one JSON object")
    e.add_argument("--aero", choices=("quasi-steady", "wagner"), default=None,
                   help="aerodynamics instead of the wing file's (wagner: Jones' finite-state "
                        "unsteady model)")
    e.set_defaults(func=_evaluate)

    m = sub.add_parser("mechanism", help="per-sample laws against the ideal force they "
                       "approximate, at one airspeed",
                       description="At --airspeed U_cr: the ideal actuator's closed loop "
                       "(eigenvalue, stationary RMS, share of time its force absorbs power) "
                       "and, flown on paired seeds, how closely each law's damper force "
                       "follows the desired force, its RMS, power and c2 "
                       "(docs/clipped_optimal.md).")
    m.add_argument("--gains", required=True, action="append", metavar="FILE",
                   help="gains file of 'design' (repeat for several laws)")
    m.add_argument("--effort", type=float, default=30.0,
                   help="LQR effort of the desired force (default 30, the shipped "
                        "clipped-optimal law's)")
    m.add_argument("--airspeed", type=float, default=1.1, metavar="RATIO",
                   help="airspeed over U_cr, below the constant c2's flutter (default 1.1)")
    m.add_argument("--seeds", type=int, default=30, help="paired seeds (default 30)")
    m.add_argument("--wing", metavar="FILE", help="wing YAML (must match the gains files)")
    m.add_argument("--json", action="store_true", help="print one JSON object")
    m.set_defaults(func=_mechanism)

    g = sub.add_parser("plot", help="figure: ramp flight fixed vs switching, the law at work")
    g.add_argument("--gains", required=True, metavar="FILE", help="gains file of 'design'")
    g.add_argument("--out", required=True, metavar="PNG", help="figure to write")
    g.add_argument("--wing", metavar="FILE", help="wing YAML (must match the gains file)")
    g.add_argument("--seed", type=int, default=0, help="aileron force seed (default 0)")
    g.add_argument("--aero", choices=("quasi-steady", "wagner"), default=None,
                   help="aerodynamics instead of the wing file's (wagner: Jones' finite-state "
                        "unsteady model)")
    g.set_defaults(func=_plot)


def _wing(path, aero=None):
    import dataclasses

    from aero_dva.wing.aerodynamics import AERO_MODELS
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import load_wing, wing_fingerprint

    cfg = load_wing(path)
    if aero is not None and aero != cfg.aero.name:
        cfg = dataclasses.replace(cfg, aero=AERO_MODELS[aero]())
    model = AeroelasticModel(cfg.wing, cfg.maxwell_design, cfg.aero)
    return cfg, model, wing_fingerprint(cfg)


def _reference(cfg, model):
    """U_cr of the bare wing, the best constant c2 and its flutter airspeed."""
    from aero_dva.control.dva_design import best_fixed_damping
    from aero_dva.wing.flutter import bare_critical_airspeed

    choice = best_fixed_damping(model, cfg.air_density)
    return (bare_critical_airspeed(cfg.wing, cfg.air_density, cfg.aero), choice.damping,
            choice.critical_airspeed)


def _design(args) -> int:
    from aero_dva.control.switching_io import load_gains, save_gains
    from aero_dva.flight.damper import check_damping
    from dva_offline.switching.study import design

    check_damping((args.c_lo, args.c_hi), "--c-lo and --c-hi")
    if not 0 < args.c_lo < args.c_hi:
        raise ValueError(f"need 0 < --c-lo < --c-hi, got {args.c_lo}, {args.c_hi}")
    if not (math.isfinite(args.lag) and args.lag >= 0):
        raise ValueError(f"--lag must be >= 0 s, got {args.lag}")
    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise ValueError(f"--noise must be >= 0, got {args.noise}")
    if not 0.5 <= args.design_airspeed <= 2.0:
        raise ValueError(f"--design-airspeed is a ratio of U_cr in [0.5, 2], "
                         f"got {args.design_airspeed}")
    efforts = _floats("--efforts", args.efforts)
    if any(v <= 0 for v in efforts):
        raise ValueError(f"--efforts must be > 0, got {args.efforts}")
    leads = _floats("--leads", args.leads)
    if any(v < 0 or v > 0.1 for v in leads):
        raise ValueError(f"--leads must be in [0, 0.1] s, got {args.leads}")
    cfg, model, fingerprint = _wing(args.wing, args.aero)
    u_cr, c2, u_fix = _reference(cfg, model)
    print(f"U_cr {u_cr:.3f} m/s; best constant c2 {c2:.1f} N s/m flutters at "
          f"{u_fix / u_cr:.4f} U_cr", file=sys.stderr)
    gains, _ = design(
        model, fingerprint, cfg.air_density, u_cr, c2, design_name=args.design,
        design_ratio=args.design_airspeed, c_lo=args.c_lo, c_hi=args.c_hi,
        time_constant=args.lag, efforts=efforts, leads=leads, seeds=_seeds(args.seeds),
        noise=args.noise,
        progress=lambda e: print(f"effort {e['effort']:g}, lead {e['lead']:g} s: practical "
                                 f"boundary "
                                 f"{e['practical_switching']:.4f} U_cr (fixed "
                                 f"{e['practical_fixed']:.4f}), bounded "
                                 f"{e['bounded_switching']:.4f}", file=sys.stderr))
    path = save_gains(gains, args.out)
    if load_gains(path).law.gain.tolist() != gains.law.gain.tolist():
        raise ValueError(f"{path}: the gains did not read back unchanged")
    print(f"wrote {path} (effort {gains.effort:g}, lead {gains.lead:g} s)")
    return 0


def _gains_for_wing(args):
    from aero_dva.control.switching_io import load_gains, wing_problem

    gains = load_gains(args.gains)
    cfg, model, fingerprint = _wing(args.wing, args.aero)
    problem = wing_problem(gains, args.gains, fingerprint, model.state_names)
    if problem is not None:
        raise ValueError(problem)
    return gains, cfg, model


def _plot(args) -> int:
    from dva_offline.switching.plots import plot_switching

    gains, cfg, model = _gains_for_wing(args)
    u_cr, c2, _ = _reference(cfg, model)
    plot_switching(model, gains, u_cr, c2, args.out, seed=args.seed)
    print(f"wrote {args.out}")
    return 0


def _evaluate(args) -> int:
    from aero_dva.control.switching_design import measured_rms
    from dva_offline.switching.study import (
        DENSITY_CASES,
        FORCE_STD,
        SAMPLE_RATE,
        Setting,
        evaluate_setting,
    )

    gains, cfg, model = _gains_for_wing(args)
    seeds = _seeds(args.seeds, EVALUATION_SEEDS)
    u_cr, c2, u_fix = _reference(cfg, model)
    sensor_rms = measured_rms(model, u_cr, cfg.air_density, c2, SAMPLE_RATE, FORCE_STD)
    lag = gains.time_constant
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in DENSITY_CASES]
    if not cases or unknown:
        raise ValueError(f"--cases must be among {list(DENSITY_CASES)}, got {args.cases!r}")
    settings = [Setting("base" if c == "rho0" else f"case {c}", lag, args.noise, case=c)
                for c in cases]
    settings += [Setting(f"lag {t * 1e3:g} ms", t, args.noise)
                 for t in _floats("--lags", args.lags, True) if t != lag]
    settings += [Setting(f"noise {v:g}", lag, v) for v in _floats("--noises", args.noises, True)]
    settings += [Setting(f"stiffness {m:+g}", lag, args.noise, mismatch=m)
                 for m in _floats("--mismatches", args.mismatches, True)]
    settings += [Setting(f"force limit {v:g} N", lag, args.noise, force_limit=v)
                 for v in _floats("--force-limits", args.force_limits, True)]
    settings += [Setting(f"yield force {v:g} N", lag, args.noise, yield_force=v)
                 for v in _floats("--yield-forces", args.yield_forces, True)]
    for ms in _floats("--blocks", args.blocks, True):
        if ms < 1 or ms != int(ms):
            raise ValueError(f"--blocks must be whole numbers of ms >= 1, got {args.blocks}")
        settings.append(Setting(f"decisions every {ms:g} ms", lag, args.noise,
                                update_every=int(ms)))
    if not args.no_wagner:
        settings.append(Setting("wagner plant", lag, args.noise, aero="wagner"))
    if any(s.time_constant < 0 or s.noise < 0 or not s.force_limit > 0 or s.yield_force < 0
           for s in settings):
        raise ValueError("lags, noises and yield forces must be >= 0, force limits > 0")
    rows = []
    for s in settings:
        row = evaluate_setting(model, gains, s, seeds, u_cr, c2, sensor_rms)
        rows.append(row)
        if not args.json:
            _print_row(row)
    if args.json:
        print(json.dumps({"gains": str(args.gains), "u_cr": u_cr, "fixed_c2": c2,
                          "fixed_flutter_ratio": u_fix / u_cr, "seeds": len(seeds),
                          "rows": rows}, indent=1))
    return 0


def _mechanism(args) -> int:
    from aero_dva.control.switching_design import measured_rms
    from dva_offline.switching.study import FORCE_STD, SAMPLE_RATE, mechanism

    if not (math.isfinite(args.effort) and args.effort > 0):
        raise ValueError(f"--effort must be > 0, got {args.effort}")
    if not 0.5 <= args.airspeed <= 2.0:
        raise ValueError(f"--airspeed is a ratio of U_cr in [0.5, 2], got {args.airspeed}")
    laws, model, cfg = {}, None, None
    for path in args.gains:
        class _One:  # what _gains_for_wing reads
            gains, wing, aero = path, args.wing, None
        gains, cfg, model = _gains_for_wing(_One)
        laws[path] = gains
    u_cr, c2, _ = _reference(cfg, model)
    sensor_rms = measured_rms(model, u_cr, cfg.air_density, c2, SAMPLE_RATE, FORCE_STD)
    out = mechanism(model, laws, u_cr, c2, _seeds(args.seeds, EVALUATION_SEEDS), sensor_rms,
                    args.effort, args.airspeed)
    if args.json:
        from dva_offline.cli_tools import json_safe

        print(json.dumps(json_safe(out), indent=1))
        return 0
    i, fx = out["ideal"], out["fixed"]
    print(f"at {args.airspeed:g} U_cr, {out['seeds']} seeds")
    print(f"ideal force (effort {args.effort:g}): least stable Re "
          f"{i['least_stable_real_part']:+.2f} 1/s, stationary leading-edge RMS "
          f"{i['leading_edge_rms_m'] * 1e3:.3f} mm, force RMS "
          f"{i['force_rms_n']:.0f} N, absorbs power {i['absorbing_share'] * 100:.0f} % of the "
          f"time (correlation with the stroke rate {i['force_stroke_rate_correlation']:+.2f})")
    print(f"constant c2 {fx['c2']:.1f} N s/m: least stable Re "
          f"{fx['least_stable_real_part']:+.2f} 1/s, stationary leading-edge RMS "
          f"{fx['leading_edge_rms_m'] * 1e3:.3f} mm")
    for name, row in out["flown"].items():
        extra = "" if name == "fixed" else (
            f", corr(F, f_c) {row['force_correlation']:+.2f}, c_hi "
            f"{row['share_at_c_hi'] * 100:.0f} % of the time, "
            f"{row['share_of_ideal_gain'] * 100:.0f} % of the ideal gain")
        print(f"flown {name}: leading-edge RMS {row['leading_edge_rms_m'] * 1e3:.3f} mm, F RMS "
              f"{row['damper_force_rms_n']:.0f} N, f_c RMS {row['desired_force_rms_n']:.0f} N, "
              f"damper power {row['damper_power_w']:.1f} W, mean c2 {row['mean_c2']:.0f} N s/m"
              + extra)
    return 0


def _interval(stat, scale=1.0, fmt="+.4f") -> str:
    return (f"{stat['mean'] * scale:{fmt}} [{stat['low'] * scale:{fmt}}, "
            f"{stat['high'] * scale:{fmt}}]")


def _print_row(row) -> None:
    print(f"{row['setting']['name']:<16} practical {row['practical']['switching']:.4f} vs "
          f"{row['practical']['fixed']:.4f} U_cr: {_interval(row['practical']['difference'])}"
          f" | bounded {row['bounded']['switching']:.4f} vs {row['bounded']['fixed']:.4f}: "
          f"{_interval(row['bounded']['difference'])} | RMS at 1.1 "
          f"{_interval(row['rms_at_1.1']['change'], 100, '+.1f')} % | "
          f"{row['switches_per_second']['mean']:.0f} switches/s | damper power x"
          f"{row['damper_power_w']['ratio']['mean']:.2f}", flush=True)
