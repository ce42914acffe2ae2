"""Files of the paired evaluation (``dva evaluate``): records, the results table, plots.

In the evaluation directory::

    inputs/             schedule, fixed c2, network (made if not given)
    records.json        every flight's numbers (controller, case, seed, U_div/U_cr, RMS, c2)
    results.json        the summary (what --json prints)
    results.md          the table with the paired differences and the boundaries
    c2_traces.png       applied c2 versus U/U_cr of the first seed, per case and controller
    rms_change.png      RMS change against the best fixed c2 with its 95 % interval, per case
"""
from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from aero_dva.atomic_io import atomic_output

__all__ = ["markdown_results", "plot_paired", "write_paired_results"]

def label(name: str) -> str:
    """A controller's label in tables and plots (its table entry's), or its name."""
    from aero_dva.control import controllers as table

    try:
        return table.controller(name).label
    except ValueError:
        return name


def _f(value, spec: str) -> str:
    return "-" if value is None or (isinstance(value, float) and not math.isfinite(value)) \
        else format(value, spec)


def _interval(stat: Mapping, scale: float, spec: str) -> str:
    low, high = stat["ci95"]
    if stat["mean"] is None:
        return "-"
    text = format(stat["mean"] * scale, spec)
    if low is None or high is None:
        return text
    mark = " *" if (low > 0 or high < 0) else ""
    return f"{text} [{format(low * scale, spec)}, {format(high * scale, spec)}]{mark}"


def _oracle(row: Mapping) -> str:
    stat = row.get("divergence_to_oracle")
    if row["controller"] == "oracle" or not stat or not stat["n"]:
        return "-"
    return _interval(stat, 1.0, "+.4f")


def markdown_results(payload: Mapping) -> str:
    """The results table and the boundaries as markdown."""
    ramp = payload.get("ramp_ratio") or [math.nan, math.nan]
    hold = payload.get("hold") or [math.nan, math.nan, math.nan]
    limits = payload.get("peak_limits") or {}
    lines = [
        f"U_cr = {payload['critical_airspeed_no_dva']:.3f} m/s (bare wing, base density); "
        f"best fixed c2 = {payload['fixed_c2']:.1f} N s/m; {len(payload['seeds'])} seeds "
        f"per case. Every controller flies the same flights: the ramp {ramp[0]:g} -> "
        f"{ramp[1]:g} U_cr at the study's slope, and {hold[1]:g} s held at {hold[0]:g} U_cr. "
        "U_div: the divergence airspeed (the project's one detector); practical: the first "
        "leading edge beyond the peak limit ("
        + ", ".join(f"{k} {v * 1e3:.1f} mm" for k, v in limits.items())
        + f", 20x the fixed c2's stationary RMS at {ramp[0]:g} U_cr). RMS change: over "
        f"{payload['rms_range_ratio'][0]:g} .. {payload['rms_range_ratio'][1]:g} U_cr of the "
        f"ramp, and over the hold after {hold[2]:g} s (a hold that flutters has none). "
        "Switches/s: changes of the damper's target; damper power: F^2/c2 over the hold, "
        "from the damper force a per-sample law's flight reports (- for the block laws, "
        "whose flights report none). Differences are paired (same seed) against the best "
        "fixed c2, with 95 % t-intervals over the seeds; * marks an interval that excludes "
        "zero.", "",
        "| case | controller | U_div/U_cr | diff. to fixed [U_cr] | diff. to oracle [U_cr] | "
        "practical [U_cr] | diff. to fixed [U_cr] | RMS change [%] | RMS at "
        f"{hold[0]:g} U_cr change [%] | switches/s | damper power [W] | mean c2 [N s/m] | "
        "activation |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in payload["results"]:
        name = label(row["controller"])
        if row.get("not_flown"):
            lines.append(f"| {row['case']} | {name} | not flown: {row['not_flown']} |"
                         + " - |" * 10)
            continue
        div = _f(row["mean_divergence_ratio"], ".4f")
        if row["diverged"] < row["flights"]:
            div += f" ({row['flights'] - row['diverged']} reached the end)"
        practical = _f(row.get("mean_practical_ratio"), ".4f")
        if row.get("reached_limit", row["flights"]) < row["flights"]:
            practical += f" ({row['flights'] - row['reached_limit']} never reached the limit)"
        hold_change = "-" if row["controller"] == "fixed" else \
            _interval(row["rms_hold_change"], 100.0, "+.1f")
        if row.get("hold_fluttered"):
            hold_change += f" ({row['hold_fluttered']} fluttered)"
        fixed = row["controller"] == "fixed"
        lines.append(
            f"| {row['case']} | {name} | {div} | "
            f"{'-' if fixed else _interval(row['divergence_difference'], 1.0, '+.4f')} | "
            f"{_oracle(row)} | {practical} | "
            f"{'-' if fixed else _interval(row['practical_difference'], 1.0, '+.4f')} | "
            f"{'-' if fixed else _interval(row['rms_change'], 100.0, '+.2f')} | "
            f"{hold_change} | {_f(row.get('switches_per_second'), '.1f')} | "
            f"{_f(row.get('damper_power'), '.1f')} | "
            f"{_f(row['mean_c2'], '.0f')} | {_f(row['median_peak_activation'], '.3f')} |")
    rbf = [r for r in payload["results"] if r["controller"] == "rbf"
           and (r.get("divergence_to_schedule") or {}).get("n")]
    if rbf:
        lines += ["", "RBF network minus airspeed schedule, same seeds (the study's key claim: "
                  "under density variation the network beats the schedule):", "",
                  "| case | U_div/U_cr difference | RMS change [%] |", "|---|---|---|"]
        lines += [f"| {r['case']} | {_interval(r['divergence_to_schedule'], 1.0, '+.4f')} | "
                  f"{_interval(r['rms_to_schedule'], 100.0, '+.2f')} |" for r in rbf]
    pairs = payload.get("law_pairs") or []
    if pairs:
        lines += ["", "The per-sample laws against each other, same seeds (paired differences, "
                  "95 % intervals):", "",
                  "| case | law minus law | U_div/U_cr difference | practical difference | "
                  "RMS change [%] | RMS at the hold change [%] |", "|---|---|---|---|---|---|"]
        lines += [f"| {r['case']} | {label(r['law'])} minus {label(r['against'])} | "
                  f"{_interval(r['divergence'], 1.0, '+.4f')} | "
                  f"{_interval(r['practical'], 1.0, '+.4f')} | "
                  f"{_interval(r['rms'], 100.0, '+.2f')} | "
                  f"{_interval(r['rms_hold'], 100.0, '+.1f')} |" for r in pairs]
    bounds = payload.get("boundaries") or {}
    if bounds:
        laws = list(dict.fromkeys(law for rows in bounds.values() for law in rows))
        lines += ["", "Stability boundaries of the control laws [U/U_cr] (frozen: eigenvalues "
                  "at the case's density, or the lowest over its cycle; Floquet: the periodic "
                  "system):", "",
                  "| case | " + " | ".join(f"{label(n)} frozen | Floquet" for n in laws) + " |",
                  "|---|" + "---|---|" * len(laws)]
        for case, rows in bounds.items():
            cells = []
            for law in laws:
                b = rows.get(law, {})
                cells += [_f(b.get("frozen"), ".4f"), _f(b.get("floquet"), ".4f")]
            lines.append(f"| {case} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_paired_results(out, payload: Mapping, records: Sequence) -> dict:
    """records.json and results.md (atomically); returns their paths."""
    out = Path(out)
    with atomic_output(out / "records.json") as handle:
        json.dump([r.to_dict() for r in records], handle, allow_nan=False)
    with atomic_output(out / "results.md") as handle:
        handle.write("# Evaluation flights (dva evaluate)\n\n" + markdown_results(payload)
                     + "\n\n![rms change](rms_change.png)\n\n![c2 traces](c2_traces.png)\n")
    return {"records": str(out / "records.json"), "results_md": str(out / "results.md")}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_paired(out, payload: Mapping, kept: Mapping, critical_airspeed: float) -> dict:
    """rms_change.png and c2_traces.png; returns their paths."""
    plt = _plt()
    out = Path(out)
    cases = [c["case"] for c in payload["cases"]]
    controllers = [c for c in payload["controllers"] if c != "fixed"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for k, controller in enumerate(controllers):
        rows = {r["case"]: r for r in payload["results"] if r["controller"] == controller}
        x = np.arange(len(cases)) + (k - (len(controllers) - 1) / 2) * 0.2
        for ax, key, scale in ((axes[0], "rms_change", 100.0),
                               (axes[1], "divergence_difference", 1.0)):
            mean = np.array([_num(rows[c][key]["mean"]) * scale for c in cases])
            low = np.array([_num(rows[c][key]["ci95"][0]) * scale for c in cases])
            high = np.array([_num(rows[c][key]["ci95"][1]) * scale for c in cases])
            ax.errorbar(x, mean, yerr=[mean - low, high - mean], fmt="o", capsize=3,
                        label=label(controller), color=f"C{k}")
    for ax, title, unit in (
            (axes[0], "leading-edge RMS change against the best fixed c2", "RMS change [%]"),
            (axes[1], "U_div/U_cr difference to the best fixed c2", "U_div/U_cr difference [-]")):
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_ylabel(unit)
        ax.set_xlabel("density case")
        ax.set_xticks(np.arange(len(cases)), cases)
        ax.set_title(title, fontsize=10)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("paired differences (same seeds), mean and 95 % interval", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "rms_change.png", dpi=100)
    plt.close(fig)
    files = {"rms_change_plot": str(out / "rms_change.png")}
    if kept:
        fig, axes = plt.subplots(2, (len(cases) + 1) // 2, figsize=(14, 7), squeeze=False)
        for ax, case in zip(axes.ravel(), cases):
            for k, controller in enumerate(payload["controllers"]):
                hit = [v for (c, n, _), v in kept.items() if c == controller and n == case]
                if hit:
                    ax.plot(hit[0].airspeed / critical_airspeed, hit[0].damping, lw=0.8,
                            color=f"C{k - 1}" if controller != "fixed" else "k",
                            label=label(controller))
            ax.set_title(case, fontsize=9)
            ax.set_xlabel("U / U_cr [-]")
            ax.set_ylabel("applied c2 [N s/m]")
            ax.grid(True, alpha=0.3)
        axes.ravel()[0].legend(fontsize=7)
        fig.suptitle("applied c2 along the ramp, first seed", fontsize=10)
        fig.tight_layout()
        fig.savefig(out / "c2_traces.png", dpi=100)
        plt.close(fig)
        files["c2_traces_plot"] = str(out / "c2_traces.png")
    return files


def _num(value) -> float:
    return math.nan if value is None else float(value)
