"""``dva wing``: modal analysis, flutter, DVA design and ramp flights of the wing (study ch. 6).

Subcommands::

    dva wing modal     frequencies and damping ratios versus airspeed (fig. 6.2)
    dva wing flutter   critical airspeed and flutter frequency
    dva wing design    the chapter-6 DVA studies (tables 6.1-6.3, Maxwell designs)
    dva wing simulate  ramp flight 0.8 -> 1.2 U_cr with random aileron force (fig. 6.4)

The wing comes from ``--wing FILE`` (default: the packaged chapter-6 wing) or, for ``modal``
and ``flutter``, from a textbook typical section ``--section FILE``. Absorbers are given in SI
units; ``--tune`` gives the tunable parameters their damping-optimal value at every airspeed.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from dva_offline.cli_tools import command_family, emit, finite

__all__ = ["register"]


def _absorber_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("absorber (SI units)")
    g.add_argument("--absorber", choices=("file", "none", "passive", "maxwell"), default="file",
                   help="absorber to attach (default: the one in the wing file, if any; the "
                        "options below then change that absorber's fields)")
    g.add_argument("--m1", type=float, help="absorber mass [kg] (default 0.04 x wing mass)")
    g.add_argument("--k1", type=float, help="parallel spring k1 [N/m]")
    g.add_argument("--c1", type=float, help="passive damper c1 [N s/m]")
    g.add_argument("--k2", type=float, help="Maxwell spring k2 [N/m]")
    g.add_argument("--c2", type=float, help="Maxwell damper c2 [N s/m]")
    g.add_argument("--position", type=float,
                   help="from the gravity centre, positive toward the leading edge [m] "
                        "(default: the leading edge)")
    g.add_argument("--tune", action="store_true",
                   help="tune k1, c1 (passive) or c2 (maxwell) for the largest minimum damping "
                        "ratio at every airspeed")
    g.add_argument("--c-max", type=float, default=None,
                   help="upper bound of the tuned damper [N s/m] (default 1e5)")


def _common(p: argparse.ArgumentParser, section: bool = True) -> None:
    src = p.add_mutually_exclusive_group()
    src.add_argument("--wing", metavar="FILE", help="wing YAML (default: the chapter-6 wing)")
    if section:
        src.add_argument("--section", metavar="FILE",
                         help="textbook typical section YAML (semichord, mass_ratio, ...)")
    p.add_argument("--aero", choices=("quasi-steady", "theodorsen", "wagner"), default=None,
                   help="aerodynamic model (default: the wing file's, else quasi-steady)")
    p.add_argument("--pitch-damping", choices=("thin_airfoil", "printed_6_2"), default=None,
                   help="reading of the study's pitch-rate couple (quasi-steady)")
    p.add_argument("--density", type=float, default=None, help="air density [kg/m^3]")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    _absorber_options(p)


def register(subparsers) -> None:
    """Add the ``wing`` command and its subcommands."""
    p, sub = command_family(subparsers, "wing",
                            "wing with DVA: modal, flutter, design, simulate", __doc__,
                            "wing_command")

    m = sub.add_parser("modal", help="frequencies and damping ratios vs airspeed (fig. 6.2)")
    _common(m)
    m.add_argument("--u-max", type=float, help="largest airspeed [m/s] (default 1.3 U_cr)")
    m.add_argument("--points", type=int, default=261, help="airspeeds (default 261)")
    m.add_argument("--plot", metavar="PNG", help="write the figure")
    m.set_defaults(func=_modal)

    f = sub.add_parser("flutter", help="critical airspeed and flutter frequency")
    _common(f)
    f.add_argument("--range", nargs=2, type=float, metavar=("LOW", "HIGH"),
                   help="airspeed range to search [m/s] (default: automatic)")
    f.set_defaults(func=_flutter)

    d = sub.add_parser("design", help="the chapter-6 DVA studies (tables 6.1-6.3, 6.3.2)")
    d.add_argument("--wing", metavar="FILE", help="wing YAML (default: the chapter-6 wing)")
    d.add_argument("--density", type=float, default=None, help="air density [kg/m^3]")
    d.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    d.add_argument("--plot", metavar="PNG", help="write the tuned-DVA figure (fig. 6.12/6.20)")
    d.set_defaults(func=_design)

    s = sub.add_parser("simulate", help="ramp flight with random aileron force (fig. 6.4)")
    _common(s, section=False)
    s.add_argument("--start", type=float, default=0.8, help="first airspeed / U_cr (0.8)")
    s.add_argument("--stop", type=float, default=1.2, help="last airspeed / U_cr (1.2)")
    s.add_argument("--duration", type=float, default=30.0, help="[s] (30)")
    s.add_argument("--sample-rate", type=float, default=1000.0, help="[Hz] (1000)")
    s.add_argument("--force-std", type=float, default=1000.0, help="aileron force std [N]")
    s.add_argument("--flights", type=int, default=1, help="flights with different noise")
    s.add_argument("--seed", type=int, default=0, help="random seed (0)")
    s.add_argument("--plot", metavar="PNG", help="write the time traces of the first flight")
    s.set_defaults(func=_simulate)


# -- building the model from the arguments ------------------------------------------------------

def _setup(args, allow_section=True):
    """(wing, absorber, aero, density, source) from the arguments."""
    from aero_dva.wing.aerodynamics import QuasiSteadyAero, aero_from_name
    from aero_dva.wing.typical_section import section_to_wing
    from aero_dva.wing.wing_io import load_section, load_wing

    section = getattr(args, "section", None) if allow_section else None
    if section:
        sec = load_section(section)
        wing, aero, rho, file_absorber = section_to_wing(sec), None, sec.air_density, None
        source = {"section": section}
    else:
        cfg = load_wing(args.wing)
        wing, aero, rho, file_absorber = cfg.wing, cfg.aero, cfg.air_density, cfg.absorber
        source = {"wing": args.wing or "chapter6"}
    if args.aero is not None:
        aero = aero_from_name(args.aero)
    if aero is None:
        aero = QuasiSteadyAero()
    if getattr(args, "pitch_damping", None):
        if not isinstance(aero, QuasiSteadyAero):
            raise ValueError("--pitch-damping applies to --aero quasi-steady only")
        aero = QuasiSteadyAero(pitch_damping=args.pitch_damping)
    if args.density is not None:
        rho = args.density
    if not (math.isfinite(rho) and rho > 0):
        raise ValueError(f"--density must be > 0, got {rho}")
    absorber = _absorber(args, wing, file_absorber)
    return wing, absorber, aero, rho, source


# Each absorber option and the absorber fields it sets; an option the chosen absorber has no
# field for is refused, never ignored.
_FIELDS = {"m1": "mass", "k1": "stiffness", "c1": "damping", "k2": "series_stiffness",
           "c2": "damping", "position": "position"}
_KIND_OPTIONS = {"passive": ("m1", "k1", "c1", "position"),
                 "maxwell": ("m1", "k1", "k2", "c2", "position")}
_TUNED = {"passive": ("k1", "c1"), "maxwell": ("c2",)}  # what --tune chooses


def _absorber(args, wing, file_absorber):
    """The absorber the arguments ask for; refuses an option it would not use."""
    from aero_dva.wing.absorbers import MaxwellAbsorber, PassiveAbsorber

    given = [o for o in _FIELDS if getattr(args, o) is not None]
    kind = args.absorber
    if args.c_max is not None and not args.tune:
        raise ValueError("--c-max bounds the tuned damper: it needs --tune")
    if kind == "none" or (kind == "file" and file_absorber is None):
        if args.tune:
            raise ValueError("--tune needs an absorber (--absorber passive|maxwell)")
        if given:
            why = "--absorber none" if kind == "none" else "the wing file has no absorber"
            raise ValueError(f"--{given[0]} sets an absorber, but {why}: give "
                             "--absorber passive|maxwell with its parameters")
        return None
    if kind == "file":
        kind = "maxwell" if isinstance(file_absorber, MaxwellAbsorber) else "passive"
        source = f"the wing file's {kind} absorber"
    else:
        source = f"--absorber {kind}"
    for o in given:
        if o not in _KIND_OPTIONS[kind]:
            raise ValueError(f"--{o} does not apply to {source} (its options: "
                             + ", ".join(f"--{k}" for k in _KIND_OPTIONS[kind]) + ")")
        if args.tune and o in _TUNED[kind]:
            raise ValueError(f"--{o} and --tune: --tune chooses "
                             + " and ".join(_TUNED[kind]) + " itself; drop one of them")
    changes = {_FIELDS[o]: getattr(args, o) for o in given}
    if args.absorber == "file":
        return file_absorber.replace(**changes)

    m1 = 0.04 * wing.mass if args.m1 is None else args.m1
    pos = wing.leading_edge if args.position is None else args.position

    def need(name, unless_tuned=False):
        value = getattr(args, name)
        if value is None:
            if unless_tuned and args.tune:
                return 1.0  # placeholder, replaced by the tuned value
            raise ValueError(f"--{name} is required for --absorber {kind}")
        return value

    if kind == "passive":
        return PassiveAbsorber(m1, need("k1", True), need("c1", True), pos)
    return MaxwellAbsorber(m1, need("k1"), need("k2"), need("c2", True), pos)


def _absorber_json(absorber):
    from aero_dva.wing.wing_io import absorber_to_dict

    return absorber_to_dict(absorber)


def _tune_kwargs(args):
    return {} if args.c_max is None else {"damping_bounds": (1e-3 * args.c_max, args.c_max)}


# -- subcommands ----------------------------------------------------------------------------------

def _flutter(args) -> int:
    from aero_dva.control.dva_design import critical_frequency, tuned_critical_airspeed
    from aero_dva.wing.aerodynamics import TheodorsenAero
    from aero_dva.wing.flutter import bare_critical_airspeed, flutter_speed
    from aero_dva.wing.model import AeroelasticModel

    wing, absorber, aero, rho, source = _setup(args)
    model = AeroelasticModel(wing, absorber, aero)
    payload = {**source, "aero": aero.name, "density": rho, "absorber": _absorber_json(absorber),
               "tuned": bool(args.tune)}
    if args.tune:
        if isinstance(aero, TheodorsenAero):
            raise ValueError("--tune needs --aero quasi-steady or wagner")
        bare = bare_critical_airspeed(wing, rho, aero)
        rng = args.range or (0.5 * bare, 3.0 * bare)
        tc = tuned_critical_airspeed(model, rho, rng, **_tune_kwargs(args))
        payload.update(critical_airspeed=tc.airspeed,
                       flutter_frequency=critical_frequency(model, tc, rho),
                       kind="flutter", bare_critical_airspeed=bare,
                       ratio=tc.airspeed / bare,
                       tuned_setting={"stiffness": tc.stiffness, "damping": tc.damping})
    else:
        res = flutter_speed(model, rho, args.range)
        payload.update(critical_airspeed=res.critical_airspeed,
                       flutter_frequency=res.flutter_frequency, kind=res.kind)
    lines = [f"critical airspeed: {payload['critical_airspeed']:.6g} m/s ({payload['kind']})",
             f"flutter frequency: {payload['flutter_frequency']:.6g} Hz"]
    if args.tune:
        lines.append(f"ratio to the bare wing: {payload['ratio']:.4f}")
    emit(args, payload, lines)
    return 0


def _modal(args) -> int:
    from aero_dva.control.dva_design import best_damping_curve
    from aero_dva.wing.flutter import NoFlutterError, bare_critical_airspeed
    from aero_dva.wing.modal import modal_analysis
    from aero_dva.wing.model import AeroelasticModel

    wing, absorber, aero, rho, source = _setup(args)
    if aero.name == "theodorsen":
        raise ValueError("modal needs --aero quasi-steady or wagner")
    if args.points < 3:
        raise ValueError("--points must be >= 3")
    model = AeroelasticModel(wing, absorber, aero)
    try:
        u_cr = bare_critical_airspeed(wing, rho, aero)
    except NoFlutterError:
        u_cr = None
    u_max = args.u_max or (1.3 * u_cr if u_cr else 200.0)
    u = np.linspace(0.0, u_max, args.points)
    damping = None
    if args.tune:
        from tqdm import tqdm

        from aero_dva.wing.absorbers import MaxwellAbsorber

        if not isinstance(absorber, MaxwellAbsorber):
            raise ValueError("modal --tune supports --absorber maxwell (c2 only)")
        curve = best_damping_curve(model, tqdm(u, desc="tuning", file=sys.stderr), rho,
                                   **_tune_kwargs(args))
        damping = np.array([c.damping for c in curve])
    res = modal_analysis(model, u, rho, damping)
    payload = {**source, "aero": aero.name, "density": rho, "absorber": _absorber_json(absorber),
               "bare_critical_airspeed": u_cr, "airspeed": u,
               "modes": [{"label": lab, "frequency": res.frequency[i],
                          "damping_ratio": res.damping_ratio[i]}
                         for i, lab in enumerate(res.labels)],
               "min_damping_ratio": res.min_damping_ratio}
    if args.plot:
        from dva_offline.wing.plots import plot_modal

        plot_modal(res, args.plot, u_cr)
    lines = [f"{len(res.labels)} modes over 0 .. {u_max:.4g} m/s ({aero.name})"]
    for i, lab in enumerate(res.labels):
        lines.append(f"  {lab:13s} f = {res.frequency[i, 0]:.4g} -> {res.frequency[i, -1]:.4g}"
                     f" Hz, zeta = {res.damping_ratio[i, 0]:.4g} -> "
                     f"{res.damping_ratio[i, -1]:.4g}")
    emit(args, payload, lines)
    return 0


def _design(args) -> int:
    from tqdm import tqdm

    from aero_dva.control import dva_design as dd
    from aero_dva.wing.wing_io import load_wing

    cfg = load_wing(args.wing)
    wing, aero = cfg.wing, cfg.aero
    rho = cfg.air_density if args.density is None else args.density
    steps = tqdm(total=4, desc="design studies", file=sys.stderr)
    u_cr = dd.bare_critical_airspeed(wing, rho, aero)
    tables = {}
    tables["table_6_1"] = _rows(dd.position_study(wing, rho, aero=aero), dd.STUDY_TABLE_6_1)
    steps.update()
    tables["table_6_2"] = _rows(dd.mass_study(wing, rho, aero=aero),
                                {f"{k:g}": v for k, v in dd.STUDY_TABLE_6_2.items()})
    steps.update()
    study63 = {f"constant DVA({i + 1})": row[2] for i, row in enumerate(dd.STUDY_TABLE_6_3)}
    study63["tunable DVA"] = dd.STUDY_TUNED_RATIO
    tables["table_6_3"] = _rows(dd.constant_absorber_study(wing, rho, aero=aero), study63)
    steps.update()
    studymx = {f"Maxwell DVA({i + 1})": row[3] for i, row in enumerate(dd.STUDY_MAXWELL_DESIGNS)}
    tables["maxwell"] = _rows(dd.maxwell_study(wing, rho, aero=aero), studymx)
    steps.update()
    steps.close()
    if args.plot:
        from aero_dva.wing.absorbers import PassiveAbsorber
        from aero_dva.wing.model import AeroelasticModel
        from dva_offline.wing.plots import plot_tuned

        model = AeroelasticModel(
            wing, PassiveAbsorber(0.04 * wing.mass, 1e5, 1e3, dd.STUDY_POSITIONS["front_tip"]),
            aero)
        u = np.linspace(0.5, 1.25, 31) * u_cr
        plot_tuned(dd.best_damping_curve(model, u, rho), u_cr, args.plot)
    payload = {"wing": args.wing or "chapter6", "density": rho, "aero": aero.name,
               "bare_critical_airspeed": u_cr, **tables}
    lines = [f"bare wing critical airspeed: {u_cr:.4f} m/s"]
    for name, rows in tables.items():
        lines.append(f"{name}:  label  project  study")
        lines += [f"  {r['label']:22s} {r['ratio']:.4f}  {r['study']}" for r in rows]
    emit(args, payload, lines)
    return 0


def _rows(results, study: dict) -> list[dict]:
    return [{"label": r.label, "critical_airspeed": finite(r.critical_airspeed),
             "ratio": finite(r.ratio), "study": study.get(r.label),
             "setting": None if r.setting is None else
             {"stiffness": r.setting.stiffness, "damping": r.setting.damping}}
            for r in results]


def _simulate(args) -> int:
    from aero_dva.control.dva_design import best_damping_curve
    from aero_dva.flight.batch_simulator import simulate_flights
    from aero_dva.flight.divergence import divergence_airspeed, ramp_airspeed
    from aero_dva.wing.absorbers import PassiveAbsorber
    from aero_dva.wing.flutter import bare_critical_airspeed
    from aero_dva.wing.model import AeroelasticModel

    wing, absorber, aero, rho, source = _setup(args, allow_section=False)
    if aero.name == "theodorsen":
        raise ValueError("simulate needs --aero quasi-steady or wagner")
    if args.flights < 1:
        raise ValueError("--flights must be >= 1")
    if not 0 < args.start < args.stop:
        raise ValueError("--start and --stop must satisfy 0 < start < stop")
    if args.force_std < 0:
        raise ValueError("--force-std must be >= 0")
    u_cr = bare_critical_airspeed(wing, rho, aero)
    u = ramp_airspeed(u_cr, args.start, args.stop, args.duration, args.sample_rate)
    damping = None
    if args.tune:
        if isinstance(absorber, PassiveAbsorber):
            raise ValueError("simulate --tune varies the damper only: use --absorber maxwell")
        model = AeroelasticModel(wing, absorber, aero)
        grid = np.linspace(u[0], u[-1], 41)
        curve = best_damping_curve(model, grid, rho, **_tune_kwargs(args))
        damping = np.interp(u, grid, [c.damping for c in curve])
    rng = np.random.default_rng(args.seed)
    force = args.force_std * rng.standard_normal((args.flights, u.size))
    traces = simulate_flights(wing, absorber, force=force, airspeed=u, density=rho,
                              damping=damping, sample_rate=args.sample_rate, aero=aero)
    u_div = divergence_airspeed(traces.airspeed, traces.displacements[:, 2],
                                args.sample_rate)
    if args.plot:
        from dva_offline.wing.plots import plot_flight

        plot_flight(traces, u_cr, args.plot, u_div[0])
    payload = {**source, "aero": aero.name, "density": rho, "absorber": _absorber_json(absorber),
               "tuned": bool(args.tune), "critical_airspeed": u_cr, "seed": args.seed,
               "flights": args.flights, "duration": args.duration,
               "sample_rate": args.sample_rate, "force_std": args.force_std,
               "divergence_airspeed": [finite(x) for x in u_div],
               "divergence_ratio": [finite(x / u_cr) for x in u_div],
               "max_abs_leading_edge": np.abs(traces.displacements[:, 2]).max(axis=1)}
    lines = [f"bare wing critical airspeed: {u_cr:.4f} m/s"]
    for i, x in enumerate(u_div):
        lines.append(f"flight {i}: " + ("no divergence" if not math.isfinite(x) else
                                         f"diverged at {x:.2f} m/s = {x / u_cr:.3f} U_cr"))
    emit(args, payload, lines)
    return 0
