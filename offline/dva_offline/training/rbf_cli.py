"""``dva train rbf``: the RBF controller (Zhang (2006) eq. 7.4-7.5) trained from a recorded sweep.

Reads only the bag (and the training plan kept in it, if any): windows at the end of every
dwell (cut where the recorded airspeed, density or c2 changes), their eq. 7.3 spectra plus c2
as the 33 inputs, a label per window (``--labels``), OLS training for each candidate spread on
the training airspeeds, the spread chosen on the held-out airspeeds. A network whose neurons do
not respond to the held-out inputs (median peak activation below 0.1: it would command its
bias, a constant c2) is refused: one line, exit 2, no file written.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from aero_dva.bag import channels as ch
from dva_offline.cli_tools import json_safe

__all__ = ["register"]

TOPICS = {
    ch.ACCELERATION.absolute(): "the spectra's accelerations",
    ch.DISPLACEMENT.absolute(): "the measured leading-edge RMS of the windows; `dva train "
                                "sweep --no-displacement` leaves it out",
    ch.FLIGHT_CONDITION.absolute(): "the airspeed and density",
    ch.DAMPER_STATE.absolute(): "the applied c2",
}


def register(sub) -> None:
    """Add ``dva train rbf`` to the ``train`` subcommands."""
    from dva_offline.training.defaults import (
        DEFAULT_SPREADS,
        LABEL_METHODS,
        MAX_CANDIDATES,
        MIN_ACTIVATION,
    )

    r = sub.add_parser("rbf", help="train the RBF network from a recorded sweep",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("bag", metavar="BAG_DIR", help="recorded sweep (rosbag2 MCAP bag)")
    r.add_argument("--out", metavar="network.npz", required=True,
                   help="network file to write (the rbf_controller's network_file)")
    r.add_argument("--labels", choices=LABEL_METHODS, default="exact",
                   help="exact: c2*(U, rho) minimising the exact stationary leading-edge RMS "
                        "at each window's recorded condition (default); measured-argmin: the "
                        "c2 of the lowest measured RMS per condition (the study's procedure; "
                        "one 2 s window is too noisy for it, docs/training.md)")
    r.add_argument("--wing", metavar="FILE", help="wing of the exact labels (default: the "
                   "training plan's wing if the bag has one, else the chapter-6 wing); its "
                   "U_cr must match the bag's")
    r.add_argument("--plot", metavar="FILE.png", help="write fig. 7.11 (optimal vs network c2)")
    r.add_argument("--window", type=float, default=2.0,
                   help="[s] window at the end of each dwell (default 2)")
    r.add_argument("--spreads", metavar="S1,S2,...",
                   help="candidate spreads in scaled input space (default "
                        + ",".join(f"{s:g}" for s in DEFAULT_SPREADS) + ")")
    r.add_argument("--validation-every", type=int, default=5,
                   help="hold out every k-th airspeed for validation (default 5)")
    r.add_argument("--max-neurons", type=int, default=100, help="most hidden neurons (100)")
    r.add_argument("--max-candidates", type=int, default=MAX_CANDIDATES,
                   help=f"candidate centres of the OLS selection at most (default "
                        f"{MAX_CANDIDATES})")
    r.add_argument("--tolerance", type=float, default=1e-3,
                   help="OLS stops below this unexplained fraction (default 1e-3)")
    r.add_argument("--min-activation", type=float, default=MIN_ACTIVATION,
                   help=f"refuse a network whose median peak activation on the held-out "
                        f"windows is below this (default {MIN_ACTIVATION})")
    r.add_argument("--allow-partial", action="store_true",
                   help="train on a sweep that was interrupted (its bag says so), has no "
                        "end-of-flight report or lacks dwells of its plan, saying what is "
                        "missing (default: such a sweep is refused)")
    r.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    r.set_defaults(func=_rbf)


def _check_topics(bag) -> None:
    from aero_dva.bag.reader import TopicNotFoundError, bag_topics

    present = bag_topics(bag)
    for topic, what in TOPICS.items():
        if topic not in present:
            raise TopicNotFoundError(
                f"bag {str(bag)!r} has no topic {topic} ({what}); topics there: "
                f"{sorted(present)}")
        if present[topic].message_count == 0:
            raise ValueError(f"bag {str(bag)!r}: topic {topic} ({what}) holds no messages")


def _bag_value(log, key: str) -> str | None:
    """A value of the bag's /diagnostics (``log``: anything with ``diagnostics``)."""
    for status in log.diagnostics:
        value = status["values"].get(key)
        if value is not None:
            return value
    return None


def _labelling_wing(args, bag: Path, log):
    """(model, wing file) for exact labels, checked against the bag's U_cr."""
    from aero_dva.control.dva_design import bare_critical_airspeed
    from aero_dva.wing.absorbers import MaxwellAbsorber
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import default_wing_path, load_wing, wing_fingerprint
    from dva_offline.training.plan_io import PLAN_FILE, load_plan, plan_wing_file

    density = None
    planned = None
    if (bag / PLAN_FILE).is_file():
        plan, planned = load_plan(bag / PLAN_FILE)
        density = plan.base_density
    if args.wing:
        path = Path(args.wing)
    elif planned is not None:  # the plan's own wing, never a default in its place
        path = plan_wing_file(bag / PLAN_FILE, planned)
    else:  # a scenario sweep: the bag's wing fingerprint is checked below
        path = default_wing_path()
    cfg = load_wing(path)
    if not isinstance(cfg.absorber, MaxwellAbsorber):
        raise ValueError(f"--wing {path}: the file needs a Maxwell absorber whose c2 is tuned")
    recorded = _bag_value(log, "critical_airspeed_no_dva")
    flown = _bag_value(log, "wing_fingerprint")
    if flown and flown != wing_fingerprint(cfg):
        raise ValueError(f"bag {bag}: flown with another wing (fingerprint {flown}) than "
                         f"{path} ({wing_fingerprint(cfg)}); give the bag's wing with --wing")
    u_cr = bare_critical_airspeed(cfg.wing, density or cfg.air_density, cfg.aero)
    if recorded is not None and abs(float(recorded) / u_cr - 1) > 1e-6:
        raise ValueError(f"bag {bag}: flown with a wing whose U_cr is {float(recorded):.4f} "
                         f"m/s, the wing {path} has {u_cr:.4f} m/s (give the bag's wing with "
                         "--wing)")
    return AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero), str(path.resolve()), u_cr


def partial_sweep(bag: Path, log, data) -> list[str]:
    """What a recorded sweep lacks (empty for a whole one): the interruption its bag is marked
    with, a missing end-of-flight report, the dwells of its plan that have no window."""
    from aero_dva.bag.reader import bag_interruption
    from aero_dva.flight.divergence import STOP_PREFIX
    from dva_offline.training.plan_io import PLAN_FILE, load_plan

    missing = []
    interrupted = bag_interruption(bag) if bag.is_dir() else None
    if interrupted is not None:
        missing.append(f"the recording was {interrupted}")
    ended = any(d.get("name") == ch.FLIGHT_DIAGNOSTIC_NAME and (
        d.get("message") == "flight completed"
        or str(d.get("message", "")).startswith(STOP_PREFIX)) for d in log.diagnostics)
    if not ended:
        missing.append("it has no end-of-flight report (the flight was cut short)")
    if bag.is_dir() and (bag / PLAN_FILE).is_file():
        plan, _ = load_plan(bag / PLAN_FILE)
        flown = {(round(float(u), 6), round(float(r), 9), round(float(c), 6))
                 for u, r, c in zip(data.airspeed, data.density, data.damping, strict=True)}
        absent = [k for k in range(plan.n_dwells)
                  if (round(float(plan.airspeed[k]), 6), round(float(plan.density[k]), 9),
                      round(float(plan.damping[k]), 6)) not in flown]
        if absent:
            speeds = plan.airspeed[absent] / plan.critical_airspeed
            missing.append(f"{len(absent)} of the plan's {plan.n_dwells} dwells have no "
                           f"window (airspeeds {speeds.min():.3f} .. {speeds.max():.3f} U_cr)")
    return missing


class _Diagnostics:
    def __init__(self, diagnostics):
        self.diagnostics = diagnostics


def _read_windows(bag: Path, window: float):
    """(something with the bag's ``diagnostics``, the data set): from the rows the data set
    uses alone when the bag has chunk indexes (a closed bag), else from the whole log."""
    from aero_dva.bag.flight_log_io import (
        flight_diagnostics,
        flight_topics,
        load_flight_log,
        read_flight_rows,
    )
    from aero_dva.wing.model import DISPLACEMENT_NAMES, LEADING_EDGE
    from dva_offline.training.rbf import CHANNELS, build_dataset, build_dataset_from_rows

    present, wanted = flight_topics(bag, "", False)
    rows = read_flight_rows(bag, wanted, {ch.ACCELERATION: CHANNELS,
                                          ch.DISPLACEMENT: (DISPLACEMENT_NAMES[LEADING_EDGE],)})
    if rows is None:
        log = load_flight_log(bag)
        return log, build_dataset(log, window=window)
    data = build_dataset_from_rows(rows, window=window)
    return _Diagnostics(flight_diagnostics(bag, present)), data


def _rbf(args) -> int:
    from aero_dva.control.rbf_io import save_rbf_network
    from dva_offline.training.labels import label_exact, label_min_rms
    from dva_offline.training.rbf import DEFAULT_SPREADS, train_network

    if args.labels != "exact":
        from dva_offline.cli_tools import not_with

        not_with(args, f"is the wing of the exact labels; --labels {args.labels} uses none",
                 "--wing")
    if args.spreads:
        try:
            spreads = tuple(float(s) for s in args.spreads.split(","))
        except ValueError:
            raise ValueError(f"--spreads expects numbers separated by commas, got "
                             f"{args.spreads!r}") from None
        from aero_dva.control.rbf_io import MAX_SPREAD, MIN_SPREAD

        if not all(MIN_SPREAD <= s <= MAX_SPREAD for s in spreads):
            raise ValueError(f"--spreads must lie within [{MIN_SPREAD:g}, {MAX_SPREAD:g}] "
                             f"(a network file holds no other), got {args.spreads!r}")
    else:
        spreads = DEFAULT_SPREADS
    if not (math.isfinite(args.min_activation) and 0 <= args.min_activation < 1):
        raise ValueError(f"--min-activation must be in [0, 1), got {args.min_activation}")
    started = time.monotonic()
    bag = Path(args.bag)
    _check_topics(bag)
    log, data = _read_windows(bag, args.window)
    partial = partial_sweep(bag, log, data)
    if partial and not args.allow_partial:
        raise ValueError(f"bag {str(bag)!r} is not a whole sweep: {'; '.join(partial)} "
                         "(--allow-partial trains on it anyway)")
    for text in partial:
        print(f"dva train rbf: warning: a partial sweep: {text}", file=sys.stderr)
    wing, u_cr = None, _bag_value(log, "critical_airspeed_no_dva")
    dropped = 0
    u_cr = float(u_cr) if u_cr is not None else None
    if args.labels == "exact":
        model, wing, u_cr = _labelling_wing(args, bag, log)
        labels = label_exact(data, model)
    else:
        # A condition recorded with one c2 offers no choice: its windows are left out.
        from dva_offline.training.labels import conditions_of
        from dva_offline.training.rbf import select_windows

        _, _, index = conditions_of(data.airspeed, data.density)
        counts = np.array([np.unique(data.damping[index == k]).size
                           for k in range(index.max() + 1)])
        single = counts[index] < 2
        if single.any() and not single.all():
            data = select_windows(data, ~single)
        dropped = int(single.sum()) if not single.all() else 0
        labels = label_min_rms(data)
    outcome = train_network(data, labels, spreads=spreads,
                            validation_every=args.validation_every,
                            tolerance=args.tolerance, max_neurons=args.max_neurons,
                            max_candidates=args.max_candidates)
    val, trn = outcome.validation_metrics, outcome.training_metrics
    summary = _summary(args, bag, data, labels, outcome, wing, u_cr)
    summary["windows_left_out_single_c2"] = dropped
    summary["partial"] = partial
    if val.median_peak_activation < args.min_activation:
        held = summary["windows"] - summary["training_windows"]
        raise ValueError(
            f"refused: the trained network's median peak activation on its {held} held-out "
            f"windows is "
            f"{val.median_peak_activation:.3g} < {args.min_activation:g} (its neurons do not "
            f"respond to unseen inputs: it would command about its bias, "
            f"{outcome.network.output_bias:.1f} N s/m); no network written")
    description = (
        f"trained by dva train rbf from {bag.resolve()}: {data.n_windows} windows "
        f"({data.window:g} s, last of each dwell), {labels.n_conditions} conditions (U, rho), "
        f"labels {labels.method}; spread {outcome.spread:g} chosen on "
        f"{summary['validation_airspeeds']} held-out airspeeds; validation R^2 {val.r2:.4f}, "
        f"RMS error {val.rmse:.4g} N s/m (training {trn.rmse:.4g}), median peak activation "
        f"{val.median_peak_activation:.3f}")
    out = save_rbf_network(outcome.network, args.out, description=description)
    summary["network"] = str(out)
    if args.plot:
        from dva_offline.training.plots import plot_network_c2
        from dva_offline.training.rbf import network_c2_per_condition

        per_condition = network_c2_per_condition(outcome.network, data, labels)
        held = ~np.isin(labels.airspeed, data.airspeed[outcome.train_mask])
        scale = u_cr if u_cr else 1.0
        plot_network_c2(args.plot, labels.airspeed / scale, labels.density, labels.damping,
                        per_condition, held, labels.method)
        summary["plot"] = str(Path(args.plot).resolve())
    summary["wall_time_s"] = time.monotonic() - started
    if args.json:
        print(json.dumps(json_safe(summary), allow_nan=False))
    else:
        _print(summary, outcome)
    return 0


def _summary(args, bag, data, labels, outcome, wing, u_cr) -> dict:
    from dva_offline.training.rbf import condition_predictability

    val, trn = outcome.validation_metrics, outcome.training_metrics
    held = ~outcome.train_mask
    readout = condition_predictability(data, outcome.train_mask)
    return {
        "bag": str(bag.resolve()), "network": None, "labels": labels.method, "wing": wing,
        "windows": data.n_windows, "training_windows": int(outcome.train_mask.sum()),
        "window_s": data.window, "skipped_dwells": data.skipped,
        "conditions": labels.n_conditions,
        "densities": sorted({round(float(r), 9) for r in labels.density}),
        "airspeeds": int(np.unique(data.airspeed).size),
        "validation_airspeeds": int(np.unique(data.airspeed[held]).size),
        "critical_airspeed_no_dva": u_cr,
        "spread": outcome.spread, "neurons": outcome.network.n_neurons,
        "candidates": outcome.n_candidates, "stop_reason": outcome.result.stop_reason,
        "validation_r2": val.r2, "validation_rmse": val.rmse,
        "output_min": val.output_min, "output_max": val.output_max,
        "median_peak_activation": val.median_peak_activation,
        "training_r2": trn.r2, "training_rmse": trn.rmse,
        "label_range": [float(labels.damping.min()), float(labels.damping.max())],
        "label_std": float(np.std(labels.targets)),
        "spectra_airspeed_r2": readout["airspeed"], "spectra_density_r2": readout["density"],
        "per_spread": [{"spread": float(s), "training_rmse": t.rmse, "validation_rmse": v.rmse,
                        "validation_r2": v.r2,
                        "median_peak_activation": v.median_peak_activation}
                       for s, t, v in zip(outcome.spreads, outcome.training,
                                          outcome.validation)],
        "plot": None,
    }


def _r2(value) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.3f}"


def _print(summary: dict, outcome) -> None:
    print(f"bag                 {summary['bag']}")
    print(f"data set            {summary['windows']} windows of {summary['window_s']:g} s x 33 "
          f"inputs, {summary['conditions']} conditions: {summary['airspeeds']} airspeeds x "
          f"densities {summary['densities']} kg/m^3")
    if summary.get("windows_left_out_single_c2"):
        print(f"left out            {summary['windows_left_out_single_c2']} windows of "
              "conditions recorded with one c2 (no argmin to take)")
    a, b = summary["label_range"]
    print(f"labels              {summary['labels']}: c2 {a:.1f} .. {b:.1f} N s/m (std over "
          f"windows {summary['label_std']:.1f})")
    for row in summary["per_spread"]:
        mark = "  <- chosen" if row["spread"] == summary["spread"] else ""
        print(f"spread {row['spread']:<6g}       training {row['training_rmse']:7.2f}  "
              f"validation {row['validation_rmse']:7.2f} N s/m  R^2 "
              f"{row['validation_r2']:6.3f}  activation {row['median_peak_activation']:.3f}"
              f"{mark}")
    print(f"network             {summary['neurons']} neurons of {summary['candidates']} "
          f"candidates, spread {summary['spread']:g} ({summary['stop_reason']}), validated on "
          f"{summary['validation_airspeeds']} held-out airspeeds")
    print(f"validation          R^2 {summary['validation_r2']:.4f}, RMS error "
          f"{summary['validation_rmse']:.2f} N s/m, output {summary['output_min']:.1f} .. "
          f"{summary['output_max']:.1f} N s/m, median peak activation "
          f"{summary['median_peak_activation']:.3f}")
    print(f"one window's spectra: linear read-out R^2 on the held-out windows, airspeed "
          f"{_r2(summary['spectra_airspeed_r2'])}, density {_r2(summary['spectra_density_r2'])}")
    print(f"saved               {summary['network']}")
    if summary["plot"]:
        print(f"plot                {summary['plot']}")
    print(f"wall time           {summary['wall_time_s']:.1f} s")
