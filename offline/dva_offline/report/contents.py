"""What one recorded run says, as numbers and a short markdown text (no files opened here).

The input is a :class:`RunData` (read by :mod:`dva_offline.report.files` from a bag written by
``run_flight`` or by the batch path); the scenario is inferred from the recorded signals, so any
bag can be reported, with or without the file it was flown from.
"""
from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from aero_dva.bag.flight_log_io import FlightLog
from aero_dva.bag.flight_summary import FlightSummary, summarize
from aero_dva.control.controllers import by_source

__all__ = ["RunData", "RunReport", "SpectrumTrack", "build_report", "report_markdown"]

# DamperState sources that no controller sends: what set c2 then (the controllers' own sources
# are their table entries', aero_dva.control.controllers.by_source).
DAMPER_SOURCES = {"sweep": "sweep (set by the simulator)", "initial": "none",
                  "fallback": "none (fallback c2)"}


@dataclass(frozen=True)
class SpectrumTrack:
    """The recorded ``dva/spectrum`` messages.

    time : (m,) [s] stamp of each spectrum (end of its window); frequencies : (f,) [Hz];
    channels : names; magnitudes : (m, c, f) eq. 7.3 scaled magnitudes.
    """

    time: np.ndarray
    frequencies: np.ndarray
    channels: tuple[str, ...]
    magnitudes: np.ndarray


@dataclass(frozen=True)
class RunData:
    """A recorded run: the flight arrays, what else the bag holds, and where it came from."""

    bag: str
    log: FlightLog
    message_counts: Mapping[str, int]
    damper_sources: tuple[str, ...] = ()
    spectrum: SpectrumTrack | None = None
    metadata: Mapping = field(default_factory=dict)


@dataclass(frozen=True)
class RunReport:
    """Headline numbers of a run (SI units, ratios of U_cr of the wing without DVA)."""

    bag: str
    controller: str
    scenario: dict
    summary: FlightSummary
    damping_range: tuple[float, float]
    message_counts: dict
    outcome: str

    def to_dict(self) -> dict:
        def clean(v):
            return None if isinstance(v, float) and not math.isfinite(v) else v

        return {"bag": self.bag, "controller": self.controller, "outcome": self.outcome,
                "scenario": {k: clean(v) for k, v in self.scenario.items()},
                "summary": self.summary.to_dict(),
                "damping_range": [clean(float(v)) for v in self.damping_range],
                "message_counts": dict(self.message_counts)}


def _controller(data: RunData) -> str:
    if data.metadata.get("controller"):
        return str(data.metadata["controller"])
    counts = Counter(s for s in data.damper_sources if s)
    if not counts:
        return "unknown (no damper state recorded)"
    source = counts.most_common(1)[0][0]
    entry = by_source(source)
    return entry.name if entry is not None else DAMPER_SOURCES.get(source, source)


def _scenario(log: FlightLog, summary: FlightSummary, metadata: Mapping) -> dict:
    """Scenario as read off the signals (and the run's metadata, where given)."""
    density = log.density[np.isfinite(log.density)]
    base = float(np.mean(density)) if density.size else math.nan
    # eq. 7.2: rho0 (1 + mu sin 2 pi f t): mean rho0, amplitude mu rho0 (held per block, so the
    # recorded extremes fall slightly short of the true ones).
    mu = float((density.max() - density.min()) / (2 * base)) if density.size else math.nan
    force = log.force[np.isfinite(log.force)]
    u_cr = summary.critical_airspeed
    out = {
        "name": metadata.get("scenario_name", ""),
        "file": metadata.get("scenario", ""),
        "duration_flown_s": summary.duration,
        "sample_rate_hz": log.sample_rate,
        "airspeed_start": summary.airspeed_start,
        "airspeed_end": summary.airspeed_end,
        "airspeed_ratio_start": summary.airspeed_start / u_cr if u_cr > 0 else math.nan,
        "airspeed_ratio_end": summary.airspeed_end / u_cr if u_cr > 0 else math.nan,
        "density_mean": base,
        "density_variation_mu": mu,
        "force_std": float(np.std(force)) if force.size else math.nan,
    }
    for key in ("mu", "seed", "absorber"):
        if key in metadata:
            out[key] = metadata[key]
    return out


def build_report(data: RunData) -> RunReport:
    """Numbers of the markdown report: the flight summary, c2 used, message counts."""
    summary = summarize(data.log)
    applied = data.log.applied_damping
    if math.isfinite(summary.divergence_airspeed):
        applied = applied[data.log.airspeed < summary.divergence_airspeed]
    applied = applied[np.isfinite(applied)]
    c2_range = (float(applied.min()), float(applied.max())) if applied.size \
        else (math.nan, math.nan)
    messages = [s["message"] for s in data.log.diagnostics if s["name"] == "simulator: flight"]
    outcome = messages[-1] if messages else "no final simulator status in the log"
    return RunReport(bag=data.bag, controller=_controller(data),
                     scenario=_scenario(data.log, summary, data.metadata), summary=summary,
                     damping_range=c2_range,
                     message_counts=dict(data.message_counts), outcome=outcome)


def _num(value, spec: str) -> str:
    return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) \
        else format(value, spec)


def report_markdown(report: RunReport, links: Mapping[str, str]) -> str:
    """Short markdown report; ``links`` maps a caption to a relative path (PNGs, .rrd)."""
    s, sc = report.summary, report.scenario
    diverged = math.isfinite(s.divergence_airspeed)
    low, high = s.rms_range
    lines = [
        f"# Run report: {sc.get('name') or report.bag}",
        "",
        f"- bag: `{report.bag}`",
        f"- controller: **{report.controller}**",
        f"- the simulator's last status: {report.outcome}",
        "",
        "## Scenario (read from the recorded signals)",
        "",
        f"- airspeed {_num(s.airspeed_start, '.2f')} -> {_num(s.airspeed_end, '.2f')} m/s = "
        f"{_num(sc['airspeed_ratio_start'], '.3f')} -> {_num(sc['airspeed_ratio_end'], '.3f')} "
        f"U_cr (U_cr without DVA {_num(s.critical_airspeed, '.2f')} m/s)",
        f"- flown {_num(s.duration, '.2f')} s at {_num(sc['sample_rate_hz'], 'g')} Hz",
        f"- air density mean {_num(sc['density_mean'], '.4f')} kg/m^3, variation "
        f"mu = {_num(sc['density_variation_mu'], '.3f')} (eq. 7.2, from the recorded extremes)",
        f"- aileron force std {_num(sc['force_std'], '.1f')} N",
    ]
    if sc.get("file"):
        lines.append(f"- scenario file: `{sc['file']}`")
    if "seed" in sc:
        lines.append(f"- excitation seed {sc['seed']}")
    if "absorber" in sc:
        lines.append(f"- absorber: {sc['absorber']}"
                     + (" (the wing without DVA)" if sc["absorber"] == "none" else ""))
    lines += [
        "",
        "## Results",
        "",
        "| quantity | value |",
        "|---|---|",
        "| divergence airspeed | " + (
            f"{s.divergence_airspeed:.2f} m/s = {s.divergence_ratio:.3f} U_cr" if diverged
            else "none within the flight") + " |",
        f"| leading-edge RMS over {low:.2f}-{high:.2f} U_cr (the range dva evaluate compares "
        f"over) | {_num(s.leading_edge_rms * 1e3, '.4f')} mm |",
        f"| mean applied c2 over {low:.2f}-{high:.2f} U_cr | "
        + ("no DVA (absorber none)" if sc.get("absorber") == "none"
           else f"{_num(s.mean_damping, '.1f')} N s/m") + " |",
        "| leading-edge RMS before divergence (not comparable between flights) | "
        f"{_num(s.leading_edge_rms_before_divergence * 1e3, '.4f')} mm |",
        "| applied c2 (before divergence) | " + (
            "no DVA (absorber none)" if sc.get("absorber") == "none" else
            f"{_num(report.damping_range[0], '.1f')} .. {_num(report.damping_range[1], '.1f')} "
            "N s/m") + " |",
        f"| missing samples | {s.missing_samples} |",
        "",
        "## Messages",
        "",
        "| topic | messages |",
        "|---|---|",
    ]
    lines += [f"| `{t}` | {n} |" for t, n in sorted(report.message_counts.items())]
    if links:
        lines += ["", "## Files", ""]
        lines += [f"- [{caption}]({path})" for caption, path in links.items()]
        pngs = [(c, p) for c, p in links.items() if p.endswith(".png")]
        lines += ["", *[f"![{c}]({p})" for c, p in pngs]]
    return "\n".join(lines) + "\n"
