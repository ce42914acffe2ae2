"""Per-run report (``dva report``): markdown numbers, PNGs, and the .rrd with its blueprint."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.flight_summary import summarize
from aero_dva.bag.reader import bag_topics
from dva_offline import cli
from dva_offline.report.contents import SpectrumTrack, _num, build_report
from dva_offline.report.files import inspect_rrd, load_run, write_report, write_rrd

# 10 s ramp 0.8 -> 1.2 U_cr with c2 held at 300 N s/m (stable only to about 1.08 U_cr), so the
# wing diverges within the flight; density varies with mu = 0.05.
SCENARIO = """\
name: short_ramp
duration: 10.0
sample_rate: 1000.0
block_size: 50
airspeed: {kind: ramp, start_ratio: 0.8, end_ratio: 1.2}
density: {base: 1.2, variation: 0.05, frequency: 1.0}
excitation: {force_std: 1000.0, seed: 3}
"""
SERIES = {"/wing/plunge", "/wing/pitch", "/wing/leading_edge", "/damper/c2",
          "/flight/airspeed", "/flight/density"}


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """A diverging flight recorded through the batch path (the simulator node's topics)."""
    from aero_dva.bag.runtime_recording import record_runtime
    from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config

    root = tmp_path_factory.mktemp("report")
    scenario = root / "short_ramp.yaml"
    scenario.write_text(SCENARIO)
    runtime = FlightRuntime(load_runtime_config({"scenario": str(scenario),
                                                 "damper_initial": 300.0,
                                                 "damper_timeout": 1e9}))
    recorded = record_runtime(root / "run", runtime)
    assert recorded.outcome == "diverged"
    return root / "run"


@pytest.fixture(scope="module")
def report(bag, tmp_path_factory):
    return write_report(bag, tmp_path_factory.mktemp("out"))


def test_markdown_lists_the_numbers_of_the_log(bag, report):
    summary = summarize(load_flight_log(bag))
    assert np.isfinite(summary.divergence_airspeed)
    text = report.markdown.read_text()
    assert (f"| divergence airspeed | {summary.divergence_airspeed:.2f} m/s = "
            f"{summary.divergence_ratio:.3f} U_cr |") in text
    assert text.count(f"{summary.divergence_ratio:.3f} U_cr") == 1  # one figure, one place
    assert "sliding" not in text and "1 s windows" not in text
    assert f"over) | {_num(summary.leading_edge_rms * 1e3, '.4f')} mm |" in text
    assert (f"| leading-edge RMS before divergence (not comparable between flights) | "
            f"{summary.leading_edge_rms_before_divergence * 1e3:.4f} mm |") in text
    assert "| applied c2 (before divergence) | 300.0 .. 300.0 N s/m |" in text
    for topic, info in bag_topics(bag).items():
        assert f"| `{topic}` | {info.message_count} |" in text
    assert "controller: **none**" in text  # c2 only ever from the damper's initial value
    assert "simulator's last status: flight stopped at U =" in text
    mu = report.report.scenario["density_variation_mu"]
    assert mu == pytest.approx(0.05, abs=0.002)  # eq. 7.2 amplitude from the held samples
    for name in ("run_timeseries.png", "run.rrd"):
        assert f"]({name})" in text and (report.markdown.parent / name).is_file()
    assert "run_spectra.png" not in text  # the batch path records no spectra
    payload = json.loads(report.json.read_text())
    assert payload["summary"]["divergence_airspeed"] == pytest.approx(
        summary.divergence_airspeed)


def test_rrd_holds_the_time_series_and_a_blueprint(report):
    content = inspect_rrd(report.rrd)
    assert content["stores"] == {"Recording", "Blueprint"}
    assert SERIES <= content["entities"]
    assert "/viewport" in content["entities"]  # the blueprint's layout
    assert any(e.startswith("/view/") for e in content["entities"])
    assert not any(e.startswith("/spectrum") for e in content["entities"])


def test_spectra_get_entities_views_and_a_png(bag, tmp_path):
    data = load_run(bag)
    t = np.arange(0.0, 4.0, 0.1) + 2.0
    mags = np.random.default_rng(0).random((t.size, 2, 16))
    spectrum = SpectrumTrack(time=t, frequencies=np.arange(5.0, 21.0),
                             channels=("plunge", "pitch"),
                             magnitudes=mags / mags.sum(axis=2, keepdims=True))
    data = type(data)(**{**data.__dict__, "spectrum": spectrum})
    content = inspect_rrd(write_rrd(tmp_path / "spec.rrd", data))
    assert {"/spectrum/plunge", "/spectrum/pitch"} | SERIES <= content["entities"]
    from dva_offline.report.files import write_plots

    assert "spectra (PNG)" in write_plots(tmp_path, data)
    assert build_report(data).summary == build_report(load_run(bag)).summary


def test_cli_reports_a_bag_or_its_mcap_file(bag, tmp_path, capsys):
    mcap = next(bag.glob("*.mcap"))
    assert cli.main(["report", str(mcap), "--out", str(tmp_path / "r"), "--no-rrd",
                     "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["rrd"] is None and not list((tmp_path / "r").glob("*.rrd"))
    assert payload["summary"]["stopped_by_simulator"] is True
    assert payload["message_counts"]["/wing/displacement"] == \
        bag_topics(bag)["/wing/displacement"].message_count


def test_cli_names_a_missing_or_unfinished_bag(bag, tmp_path, capsys):
    assert cli.main(["report", str(tmp_path / "nope")]) == 2
    assert "no bag directory or .mcap file" in capsys.readouterr().err
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    shutil.copy(next(bag.glob("*.mcap")), unfinished / "unfinished_0.mcap")
    assert cli.main(["report", str(unfinished), "--out", str(tmp_path / "u")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dva report: error:") and "metadata.yaml" in err
    assert "dva bag recover" in err and "allow_truncated" not in err
    assert not (tmp_path / "u").exists()  # nothing written for a refused bag


def test_cli_reads_a_cut_bag_with_allow_truncated(bag, tmp_path, capsys):
    cut = tmp_path / "cut"
    cut.mkdir()
    data = next(bag.glob("*.mcap")).read_bytes()
    (cut / "cut_0.mcap").write_bytes(data[:len(data) * 2 // 3])
    assert cli.main(["report", str(cut), "--out", str(tmp_path / "r"), "--no-rrd", "--json",
                     "--allow-truncated"]) == 0
    captured = capsys.readouterr()
    payload = json.loads(captured.out)
    assert 0 < payload["message_counts"]["/wing/displacement"] < \
        bag_topics(bag)["/wing/displacement"].message_count
    assert captured.err.count("dva report: warning: MCAP file") == 1  # one line, once


def test_time_series_show_the_flight_up_to_its_divergence(bag, report, tmp_path):
    """A diverged flight: a second column up to the divergence, which is marked where the
    airspeed reached the report's divergence airspeed; a flight that did not: one column."""
    import matplotlib.image

    from dva_offline.report.files import divergence_time, write_plots

    data = load_run(bag)
    summary = report.report.summary
    t_div = divergence_time(data.log, summary.divergence_airspeed)
    k = np.flatnonzero(data.log.time == t_div)[0]
    assert data.log.airspeed[k] >= summary.divergence_airspeed > data.log.airspeed[k - 1]
    both = matplotlib.image.imread(report.pngs["time series (PNG)"])
    one = matplotlib.image.imread(write_plots(tmp_path, data)["time series (PNG)"])
    assert both.shape[1] == 1300 and one.shape[1] == 900  # 13 and 9 inches at 100 dpi
    assert np.isnan(divergence_time(data.log, float("nan")))
