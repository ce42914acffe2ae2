"""Files of the evaluation flights: scenario files, per-flight records, results, plots.

Layout of an evaluation directory::

    scenarios/<name>_mu<mu>_seed<seed>.yaml   the flown scenario of each (mu, seed)
    inputs/                                   schedule, fixed c2, network (made if not given)
    flights/<controller>_mu<mu>_seed<seed>/   the bag of each flight (run_flight --output)
    flights/<controller>_mu<mu>_seed<seed>.json   its record, written as soon as it ends
    reports/<controller>_mu<mu>/              per-run report of one representative flight
    results.md, results.json                  the table
    traces_mu<mu>.png, divergence_vs_mu.png   fig. 7.13-7.16 style traces, summary plot
"""
from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import yaml

from aero_dva.atomic_io import atomic_output
from aero_dva.control.controllers import NONE
from aero_dva.flight.scenario_io import scenario_from_dict
from aero_dva.safe_files import read_yaml
from aero_dva.wing.model import LEADING_EDGE
from dva_offline.evaluation.graph_cases import (
    CaseStats,
    FlightCase,
    graph_controllers,
    label,
)

__all__ = ["flight_bag", "flight_record_path", "load_base_scenario", "load_records",
           "plot_summary", "plot_traces", "save_json", "write_scenario"]


def save_json(path, payload) -> Path:
    """Write JSON atomically (a crash never leaves half a record)."""
    with atomic_output(path) as handle:
        json.dump(payload, handle, indent=1, allow_nan=False)
    return Path(path)


def load_base_scenario(path) -> dict:
    """The base scenario YAML as a mapping, checked as the simulator will check it."""
    path = Path(path)
    raw = read_yaml(path, "--scenario")
    try:
        scenario = scenario_from_dict(raw, default_name=path.stem)  # names the bad key
    except ValueError as exc:
        raise ValueError(f"--scenario {path}: {exc}") from None
    if scenario.airspeed.kind != "ramp":
        raise ValueError(f"--scenario {path}: the evaluation flies a ramp, got airspeed kind "
                         f"{scenario.airspeed.kind!r}")
    return raw


def write_scenario(directory, mapping: Mapping) -> Path:
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{mapping['name']}.yaml"
    path.write_text("# written by dva evaluate\n" + yaml.safe_dump(dict(mapping),
                                                                    sort_keys=False))
    return path


def flight_bag(out_dir, case: FlightCase) -> Path:
    return Path(out_dir) / "flights" / case.key


def flight_record_path(out_dir, case: FlightCase) -> Path:
    return Path(out_dir) / "flights" / f"{case.key}.json"


def load_records(out_dir, cases: Sequence[FlightCase]) -> dict[FlightCase, dict]:
    """Records already saved for ``cases`` (unreadable ones, and those whose divergence was
    read by another detector than today's, are treated as missing: flown again)."""
    from aero_dva.flight.divergence import DETECTOR

    found = {}
    for case in cases:
        path = flight_record_path(out_dir, case)
        if path.is_file():
            try:
                record = json.loads(path.read_text())
            except json.JSONDecodeError:
                continue
            if isinstance(record, dict) and record.get("divergence_detector") == DETECTOR:
                found[case] = record
    return found


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_traces(path, mu: float, runs: Mapping[str, object], u_cr: float) -> Path:
    """Fig. 7.13-7.16 for one mu: per controller (rows) w, alpha and c2 versus U/U_cr of one
    flight (``runs``: controller -> FlightLog; the table's divergence airspeed marked if
    found)."""
    from aero_dva.flight.divergence import divergence_airspeed

    plt = _plt()
    names = [c for c in graph_controllers() if c in runs]
    fig, axes = plt.subplots(len(names), 3, figsize=(13, 2.6 * len(names) + 0.6),
                             squeeze=False)
    for row, controller in zip(axes, names):
        log = runs[controller]
        ratio = log.airspeed / u_cr
        edge = log.displacements[LEADING_EDGE]
        valid = np.isfinite(edge) & np.isfinite(log.airspeed)
        u_div = divergence_airspeed(log.airspeed[valid], edge[valid],
                                    log.sample_rate) / u_cr  # as in the table
        # without the DVA the recorded c2 acts on nothing: leave its panel empty
        c2 = log.damping if controller != NONE else np.full(ratio.shape, np.nan)
        if controller == NONE:
            row[2].text(0.5, 0.5, label(NONE), ha="center", transform=row[2].transAxes)
        for ax, values, ylabel in ((row[0], log.displacements[0] * 1e3, "w [mm]"),
                                   (row[1], log.displacements[1] * 1e3, "alpha [mrad]"),
                                   (row[2], c2, "c2 [N s/m]")):
            ax.plot(ratio, values, lw=0.5)
            if u_div is not None and math.isfinite(u_div):
                ax.axvline(u_div, color="r", lw=0.8, ls="--")
                # the response before the divergence on its own scale: the growth after it
                # (hundreds of mm) would flatten it; it runs off the panel past the red line
                before = np.abs(values[np.isfinite(values) & (ratio <= u_div)])
                if ax is not row[2] and before.size and before.max() > 0:
                    ax.set_ylim(-1.3 * before.max(), 1.3 * before.max())
            ax.set_ylabel(ylabel)
            ax.grid(True, alpha=0.3)
            ax.set_xlim(0.8, max(1.2, float(np.nanmax(ratio))))
        div = f"U_div = {u_div:.3f} U_cr" if u_div is not None and math.isfinite(u_div) \
            else "no divergence"
        row[0].set_title(f"{label(controller)}: {div}", fontsize=9, loc="left")
    for ax in axes[-1]:
        ax.set_xlabel("U / U_cr [-]")
    fig.suptitle(f"ramp 0.8 -> 1.2 U_cr, density variation mu = {mu:g} (one excitation seed); "
                 "w and alpha scaled to the response before the divergence (red line)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_summary(path, stats: Sequence[CaseStats]) -> Path:
    """U_div / U_cr versus mu per controller: mean, std, min..max, the study's flight."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, controller in enumerate(c for c in graph_controllers() if any(s.controller == c
                                                                  for s in stats)):
        rows = sorted((s for s in stats if s.controller == controller), key=lambda s: s.mu)
        mu = np.array([s.mu for s in rows]) + (k - 1.5) * 0.002  # side by side
        mean = np.array([s.mean for s in rows])
        std = np.nan_to_num(np.array([s.std for s in rows]))
        line = ax.errorbar(mu, mean, yerr=std, marker="o", capsize=3,
                           label=label(controller))
        color = line[0].get_color()
        ax.vlines(mu, [s.min for s in rows], [s.max for s in rows], color=color, lw=4,
                  alpha=0.25)
        seed = [(s.mu, s.study_ratio) for s in rows if s.study_ratio is not None]
        if seed:
            ax.plot(*zip(*seed), marker="*", ms=11, ls=":", color=color, alpha=0.8)
    ax.plot([], [], "k*", ls=":", label="study (one flight)")
    ax.set_xlabel("density variation mu (eq. 7.2) [-]")
    ax.set_ylabel("U_div / U_cr [-]")
    ax.set_title("divergence airspeed: mean +- std (bars: min..max over seeds)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
