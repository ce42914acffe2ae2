"""Files of a per-run report: read a bag, write the rerun recording (.rrd), PNGs and markdown.

The .rrd holds the time series on the ``sim_time`` timeline under ``/wing`` (plunge w [m],
pitch alpha [rad], leading edge [m]), ``/damper`` (applied c2 [N s/m]), ``/flight`` (airspeed
[m/s], density [kg/m^3]) and, when the bag has ``dva/spectrum``, ``/spectrum/<channel>`` (the
scaled magnitudes as a bar chart per spectrum message), plus a default blueprint laying these out
as time-series views and bar-chart views, so the viewer opens on a useful layout.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aero_dva.bag import channels as ch
from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import bag_topics, read_messages
from dva_offline.report.contents import RunData, SpectrumTrack, build_report, report_markdown

__all__ = ["ReportFiles", "divergence_time", "inspect_rrd", "load_run", "write_plots",
           "write_report", "write_rrd"]

TIMELINE = "sim_time"
SERIES = {  # entity path -> (FlightLog attribute, row or None, scale, legend)
    "/wing/plunge": ("displacements", 0, 1.0, "w [m]"),
    "/wing/pitch": ("displacements", 1, 1.0, "alpha [rad]"),
    "/wing/leading_edge": ("displacements", 2, 1.0, "leading edge [m]"),
    "/damper/c2": ("applied_damping", None, 1.0, "applied c2 [N s/m]"),
    "/flight/airspeed": ("airspeed", None, 1.0, "airspeed [m/s]"),
    "/flight/density": ("density", None, 1.0, "density [kg/m^3]"),
}


def load_run(bag, metadata: dict | None = None, *, allow_truncated: bool = False) -> RunData:
    """Read a bag directory or .mcap file (``load_flight_log`` plus the spectra and the damper
    sources); ``metadata`` (e.g. controller, scenario file) is what the bag cannot say.
    ``allow_truncated`` reads what a cut, unclosed or damaged bag still holds.

    A sidecar ``<bag>.json`` (written by ``dva evaluate`` and ``run_flight --json`` users) is read
    when no metadata is given.
    """
    bag = Path(bag)
    log = load_flight_log(bag, allow_truncated=allow_truncated)
    topics = bag_topics(bag, allow_truncated=allow_truncated)
    counts = {name: info.message_count for name, info in topics.items()}
    sources: list[str] = []
    damper_topic, spectrum_topic = ch.DAMPER_STATE.absolute(), ch.SPECTRUM.absolute()
    if damper_topic in topics:
        sources = [r.message.source for r in read_messages(
            bag, [damper_topic], allow_truncated=allow_truncated)]
    spectrum = None
    if counts.get(spectrum_topic):
        stamps, mags, freqs, names = [], [], None, None
        for record in read_messages(
                bag, [spectrum_topic], allow_truncated=allow_truncated,
                expected_types={spectrum_topic: ch.SPECTRUM.type_name}):
            msg = record.message
            freqs = np.asarray(msg.frequencies, dtype=float)
            names = tuple(msg.channel_names)
            stamps.append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
            mags.append(np.asarray(msg.magnitudes, dtype=float).reshape(len(names), freqs.size))
        spectrum = SpectrumTrack(time=np.array(stamps), frequencies=freqs, channels=names,
                                 magnitudes=np.array(mags))
    if metadata is None:
        sidecar = bag.with_name(bag.name + ".json") if bag.is_dir() else bag.with_suffix(".json")
        metadata = json.loads(sidecar.read_text()) if sidecar.is_file() else {}
    return RunData(bag=str(bag.resolve()), log=log, message_counts=counts,
                   damper_sources=tuple(sources), spectrum=spectrum, metadata=metadata)


def _blueprint(spectrum: SpectrumTrack | None):
    import rerun.blueprint as rrb

    series = rrb.Vertical(
        rrb.TimeSeriesView(origin="/wing", contents=["/wing/leading_edge"],
                           name="leading edge [m]"),
        rrb.TimeSeriesView(origin="/wing", contents=["/wing/plunge"], name="plunge w [m]"),
        rrb.TimeSeriesView(origin="/wing", contents=["/wing/pitch"], name="pitch alpha [rad]"),
        rrb.TimeSeriesView(origin="/damper", name="applied c2 [N s/m]"),
        rrb.TimeSeriesView(origin="/flight", contents=["/flight/airspeed"],
                           name="airspeed [m/s]"),
        rrb.TimeSeriesView(origin="/flight", contents=["/flight/density"],
                           name="air density [kg/m^3]"),
        name="time series")
    if spectrum is None:
        return rrb.Blueprint(series, collapse_panels=True)
    bars = rrb.Vertical(*[rrb.BarChartView(origin=f"/spectrum/{c}", name=f"scaled spectrum {c} "
                                           f"({spectrum.frequencies[0]:g}..."
                                           f"{spectrum.frequencies[-1]:g} Hz)")
                          for c in spectrum.channels], name="spectra")
    return rrb.Blueprint(rrb.Horizontal(series, bars, column_shares=[3, 2]),
                         collapse_panels=True)


def write_rrd(path, data: RunData, application_id: str = "aero_dva_run") -> Path:
    """Write ``data`` as a rerun recording with its default blueprint; returns the path."""
    try:
        import rerun as rr
    except ImportError:
        raise ValueError("writing the .rrd needs the rerun-sdk package (pip install rerun-sdk); "
                         "or pass --no-rrd") from None

    path = Path(path)
    log = data.log
    rec = rr.RecordingStream(application_id, recording_id=Path(data.bag).name)
    rec.save(path, default_blueprint=_blueprint(data.spectrum))
    valid = np.isfinite(log.displacements[0])
    time = rr.TimeColumn(TIMELINE, duration=log.time[valid])
    for entity, (attribute, row, scale, legend) in SERIES.items():
        values = getattr(log, attribute)
        values = (values[row] if row is not None else values)[valid] * scale
        rec.log(entity, rr.SeriesLines(names=legend), static=True)
        rec.send_columns(entity, indexes=[time], columns=rr.Scalars.columns(scalars=values))
    if data.spectrum is not None:
        sp = data.spectrum
        for i, stamp in enumerate(sp.time):  # one bar chart per spectrum message
            rec.set_time(TIMELINE, duration=float(stamp))
            for k, channel in enumerate(sp.channels):
                rec.log(f"/spectrum/{channel}", rr.BarChart(sp.magnitudes[i, k]))
    rec.flush()
    rec.disconnect()
    return path


def inspect_rrd(path) -> dict:
    """What a .rrd holds, read back with the ``rerun`` command line (``rerun rrd print``):
    ``{"stores": {"Recording", "Blueprint"}, "entities": {...}}``. Raises ValueError if the file
    does not load."""
    exe = shutil.which("rerun") or str(Path(__import__("sys").executable).with_name("rerun"))
    result = subprocess.run([exe, "rrd", "print", str(path)], capture_output=True, text=True,
                            timeout=120)
    if result.returncode != 0:
        raise ValueError(f"{path}: rerun cannot read it: {result.stderr.strip()[-500:]}")
    stores = set(re.findall(r"StoreId\(\s*(\w+),", result.stdout))
    entities = set(re.findall(r"^Chunk\(\S+\) with \d+ rows \([^)]*\) - (\S+) - ",
                              result.stdout, flags=re.M))
    return {"stores": stores, "entities": entities}


def divergence_time(log, divergence_airspeed: float) -> float:
    """[s] the time the flight reached ``divergence_airspeed`` (NaN if it did not diverge)."""
    if not np.isfinite(divergence_airspeed):
        return float("nan")
    reached = np.flatnonzero(np.isfinite(log.airspeed) & (log.airspeed >= divergence_airspeed))
    return float(log.time[reached[0]]) if reached.size else float("nan")


def write_plots(out_dir, data: RunData, stem: str = "run",
                divergence_airspeed: float = float("nan"),
                critical_airspeed: float = float("nan")) -> dict[str, Path]:
    """PNG plots: time series (leading edge, w, alpha, c2, airspeed, density) and, if recorded,
    the spectra (scaled magnitude versus time and frequency per channel). Returns caption ->
    path.

    A flight that diverged (``divergence_airspeed``, the report's) gets a second column of the
    same signals up to the divergence, on their own scales: on the whole flight the last
    seconds' growth (hundreds of mm) flattens everything before it. The divergence is marked
    by a dashed red line at the time the airspeed reached it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    log = data.log
    rows = [(log.displacements[2] * 1e3, "leading edge [mm]"),
            (log.displacements[0] * 1e3, "plunge w [mm]"),
            (log.displacements[1] * 1e3, "pitch alpha [mrad]"),
            (log.applied_damping, "applied c2 [N s/m]"), (log.airspeed, "airspeed U [m/s]"),
            (log.density, "density rho [kg/m^3]")]
    t_div = divergence_time(log, divergence_airspeed)
    diverged = np.isfinite(t_div)
    u_cr = critical_airspeed if np.isfinite(critical_airspeed) and critical_airspeed > 0 \
        else None
    fig, axes = plt.subplots(len(rows), 2 if diverged else 1, figsize=(13 if diverged else 9, 11),
                             sharex="col", squeeze=False)
    before = log.time <= t_div if diverged else np.ones(log.time.size, bool)
    for r, (values, label) in enumerate(rows):
        columns = [(axes[r, 0], np.ones(log.time.size, bool))]
        if diverged:
            columns.append((axes[r, 1], before))
        for ax, keep in columns:
            ax.plot(log.time[keep], values[keep], lw=0.6)
            ax.set_ylabel(label, fontsize=9)
            ax.grid(True, alpha=0.3)
            if u_cr is not None and r == 4:
                ax.axhline(u_cr, color="0.4", ls=":", lw=0.8)
                ax.annotate(f"U_cr {u_cr:.1f} m/s (no DVA)", (log.time[0], u_cr), fontsize=7,
                            color="0.3", va="bottom")
        if diverged:
            axes[r, 0].axvline(t_div, color="tab:red", ls="--", lw=0.9)
    where = "" if not diverged else (
        f"diverged at {divergence_airspeed:.1f} m/s"
        + (f" = {divergence_airspeed / u_cr:.3f} U_cr" if u_cr else "") + f" (t = {t_div:.1f} s)")
    axes[0, 0].set_title("whole flight" + (f"; red line: {where}" if diverged else
                                           ": no divergence within the flight"), fontsize=10)
    if diverged:
        axes[0, 1].set_title(f"up to the divergence (t <= {t_div:.1f} s), own scales",
                             fontsize=10)
        axes[-1, 1].set_xlabel("time [s]")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(f"{Path(data.bag).name}", fontsize=11)
    fig.tight_layout()
    paths = {"time series (PNG)": out_dir / f"{stem}_timeseries.png"}
    fig.savefig(paths["time series (PNG)"], dpi=100)
    plt.close(fig)
    if data.spectrum is not None and data.spectrum.time.size:
        sp = data.spectrum
        fig, axes = plt.subplots(len(sp.channels), 1, figsize=(9, 3 * len(sp.channels)),
                                 sharex=True, squeeze=False)
        for k, (ax, channel) in enumerate(zip(axes[:, 0], sp.channels)):
            mesh = ax.pcolormesh(sp.time, sp.frequencies, sp.magnitudes[:, k, :].T,
                                 shading="nearest")
            fig.colorbar(mesh, ax=ax, label="scaled magnitude [-]")
            ax.set_ylabel(f"{channel}: f [Hz]")
            if diverged:
                ax.axvline(t_div, color="tab:red", ls="--", lw=0.9)
        axes[0, 0].set_title("eq. 7.3 scaled spectra (each sums to 1 over its band)"
                             + (f"; red line: {where}" if diverged else ""), fontsize=10)
        axes[-1, 0].set_xlabel("time [s] (end of the 2 s window)")
        fig.tight_layout()
        paths["spectra (PNG)"] = out_dir / f"{stem}_spectra.png"
        fig.savefig(paths["spectra (PNG)"], dpi=100)
        plt.close(fig)
    return paths


@dataclass(frozen=True)
class ReportFiles:
    markdown: Path
    json: Path
    pngs: dict
    rrd: Path | None
    report: object  # RunReport


def write_report(bag, out_dir, rrd: bool = True, metadata: dict | None = None,
                 stem: str = "run", *, allow_truncated: bool = False) -> ReportFiles:
    """Read ``bag`` and write ``<stem>.md``, ``<stem>.json``, the PNGs and ``<stem>.rrd``
    (``allow_truncated``: see :func:`load_run`)."""
    out_dir = Path(out_dir)
    data = load_run(bag, metadata, allow_truncated=allow_truncated)
    out_dir.mkdir(parents=True, exist_ok=True)
    report = build_report(data)
    pngs = write_plots(out_dir, data, stem, report.summary.divergence_airspeed,
                       report.summary.critical_airspeed)
    links = {caption: p.name for caption, p in pngs.items()}
    rrd_path = None
    if rrd:
        rrd_path = write_rrd(out_dir / f"{stem}.rrd", data)
        links["rerun recording (open with `rerun " + rrd_path.name + "`)"] = rrd_path.name
    md = out_dir / f"{stem}.md"
    md.write_text(report_markdown(report, links))
    js = out_dir / f"{stem}.json"
    payload = report.to_dict()
    payload.update(markdown=str(md), pngs={c: str(p) for c, p in pngs.items()},
                   rrd=str(rrd_path) if rrd_path else None)
    js.write_text(json.dumps(payload, indent=1))
    return ReportFiles(markdown=md, json=js, pngs=pngs, rrd=rrd_path, report=report)
