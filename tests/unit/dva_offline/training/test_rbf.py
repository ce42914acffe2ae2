"""Training from a recorded scenario sweep (``dva train sweep --scenario``, ``dva train rbf``).

The planned sweep (the default) is tested in training/test_plan.py."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from aero_dva.bag.flight_log_io import load_flight_log
from aero_dva.bag.reader import BagReadError, MessageTypeError, TopicNotFoundError
from aero_dva.bag.writer import BagWriter
from aero_dva.control.rbf_io import load_rbf_network
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from aero_dva.flight.scenario import AirspeedProfile, Scenario
from dva_offline import cli
from dva_offline.training.labels import label_min_rms
from dva_offline.training.rbf import (
    TrainingDataError,
    adapt_sweep,
    build_dataset,
    find_dwells,
    split_by_airspeed,
    train_network,
)

# A mini sweep: 5 airspeeds x 5 c2 values, dwell 4 s (2 s settling + the 2 s window), all
# stable with a decay rate above 0.5 1/s on the chapter-6 wing. 100 s of flight.
RATIOS = (0.90, 0.93, 0.96, 0.98, 1.0)
C2 = (100.0, 250.0, 400.0, 700.0, 1100.0)
DWELL, WINDOW, RATE = 4.0, 2.0, 1000
MINI_YAML = f"""\
name: mini_sweep
duration: auto
sample_rate: {RATE}.0
block_size: 50
airspeed: {{kind: steps, ratios: {list(RATIOS)}}}
density: {{base: 1.2}}
excitation: {{force_std: 1000.0, seed: 11}}
sweep: {{dwell: {DWELL}, damping: {list(C2)}}}
"""


def dva_executable() -> str:
    beside = Path(sys.executable).with_name("dva")
    found = str(beside) if beside.is_file() else shutil.which("dva")
    if not found:
        pytest.fail("the 'dva' console script is not installed (pip install -e offline)")
    return found


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    """The mini sweep recorded once through ``dva train sweep --as-is`` (the entry point),
    by two processes into a split bag (one file each), which the rest reads as one bag."""
    root = tmp_path_factory.mktemp("train")
    scenario = root / "mini.yaml"
    scenario.write_text(MINI_YAML)
    bag = root / "bag"
    result = subprocess.run(
        [dva_executable(), "train", "sweep", "--scenario", str(scenario), "--as-is",
         "--out", str(bag), "--jobs", "2", "--json"], capture_output=True, text=True,
        timeout=300)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    return {"root": root, "scenario": scenario, "bag": bag, "summary": summary,
            "log": load_flight_log(bag)}


def _direct_rms(scenario_path):
    """Leading-edge RMS of the last 2 s of each dwell, simulated without any recording."""
    runtime = FlightRuntime(load_runtime_config({"scenario": str(scenario_path)}))
    le = []
    while not runtime.done:
        le.append(runtime.step().displacements[2])
    le = np.concatenate(le).reshape(len(RATIOS), len(C2), int(DWELL * RATE))
    return np.sqrt(np.mean(le[..., -int(WINDOW * RATE):] ** 2, axis=-1)), le


def test_sweep_summary(mini):
    s = mini["summary"]
    assert s["outcome"] == "completed" and s["adapted"] is False and s["bag_files"] == 2
    assert s["sim_time_s"] == pytest.approx(len(RATIOS) * len(C2) * DWELL)
    assert s["airspeeds"] == len(RATIOS) and s["c2_values"] == list(C2)


def test_recorded_data_equal_the_direct_simulation(mini):
    _, le = _direct_rms(mini["scenario"])
    # The batch path computes the sweep parallel in time: equal to round-off, not bit for bit.
    np.testing.assert_allclose(mini["log"].displacements[2], le.ravel(), rtol=0,
                               atol=1e-9 * np.abs(le).max())


def test_dwells_come_from_the_recorded_changes(mini):
    log = mini["log"]
    dwells = find_dwells(log.airspeed, log.applied_damping, log.density)
    n = int(DWELL * RATE)
    np.testing.assert_array_equal(dwells.start, np.arange(len(RATIOS) * len(C2)) * n)
    np.testing.assert_array_equal(dwells.damping, np.tile(C2, len(RATIOS)))
    np.testing.assert_array_equal(dwells.density, 1.2)
    # a density change alone cuts too
    rho = np.where(np.arange(log.density.size) < n // 2, 1.08, log.density)
    assert find_dwells(log.airspeed, log.applied_damping, rho).start[:2].tolist() == [0, n // 2]


def test_dataset_has_33_inputs_per_window(mini):
    data = build_dataset(mini["log"], window=WINDOW)
    assert data.inputs.shape == (len(RATIOS) * len(C2), 33)
    np.testing.assert_allclose(data.inputs[:, :16].sum(axis=1), 1.0)  # eq. 7.3 per channel
    np.testing.assert_allclose(data.inputs[:, 16:32].sum(axis=1), 1.0)
    np.testing.assert_array_equal(data.inputs[:, 32], data.damping)
    np.testing.assert_array_equal(
        data.window_start, (np.arange(data.n_windows) + 1) * int(DWELL * RATE) - 2000)
    assert data.input_names[0] == "plunge_5Hz" and data.input_names[-1] == "damping"


def test_the_fast_routes_give_the_previous_data_set(mini):
    # The split bag read message by message and spectra one window at a time (the previous
    # route) against the indexed batch read, the spectra 256 windows per product, and the
    # rows-only read of `dva train rbf`.
    from aero_dva.bag import channels as ch
    from aero_dva.bag.flight_log_io import flight_topics, read_flight_rows
    from dva_offline.training.rbf import build_dataset_from_rows

    previous = build_dataset(load_flight_log(mini["bag"], indexed=False), window=WINDOW,
                             spectra_batch=1)
    batched = build_dataset(mini["log"], window=WINDOW)
    _, wanted = flight_topics(mini["bag"], "", False)
    rows = read_flight_rows(mini["bag"], wanted, {ch.ACCELERATION: ("plunge", "pitch"),
                                                  ch.DISPLACEMENT: ("leading_edge",)})
    lean = build_dataset_from_rows(rows, window=WINDOW)
    assert set(rows.rows[ch.DISPLACEMENT]) == {"leading_edge"}  # nothing else held
    np.testing.assert_allclose(batched.inputs, previous.inputs, rtol=1e-12, atol=0)
    for data in (batched, lean):
        for name in ("airspeed", "density", "damping", "rms", "window_start"):
            np.testing.assert_array_equal(getattr(data, name), getattr(previous, name))
    np.testing.assert_array_equal(lean.inputs, batched.inputs)


def test_labels_pick_the_minimum_rms_c2(mini):
    rms, _ = _direct_rms(mini["scenario"])
    labels = label_min_rms(build_dataset(mini["log"], window=WINDOW))
    np.testing.assert_array_equal(labels.damping, np.asarray(C2)[np.argmin(rms, axis=1)])
    np.testing.assert_allclose(labels.rms, rms.min(axis=1), rtol=1e-12)
    assert np.all(np.diff(labels.airspeed) > 0)


def test_split_holds_out_whole_airspeeds_at_every_density():
    speeds = np.repeat(np.arange(10.0), 3)  # 10 airspeeds, 3 windows (densities) each
    train = split_by_airspeed(speeds, validation_every=5)
    assert np.unique(speeds[~train]).tolist() == [2.0, 7.0]
    assert not set(speeds[train]) & set(speeds[~train])
    with pytest.raises(TrainingDataError, match="too few"):
        split_by_airspeed([1.0, 1.0, 2.0])


def test_saved_network_loads_and_reproduces_training_data(mini, tmp_path):
    out = tmp_path / "net.npz"
    plot = tmp_path / "fig.png"
    assert cli.main(["train", "rbf", str(mini["bag"]), "--out", str(out), "--plot",
                     str(plot), "--labels", "measured-argmin", "--min-activation", "0",
                     "--json"]) == 0
    network = load_rbf_network(out, expected_input_dim=33)
    data = build_dataset(mini["log"], window=WINDOW)
    labels = label_min_rms(data)
    outcome = train_network(data, labels)
    assert network.spread == pytest.approx(outcome.spread)
    mask = outcome.train_mask
    error = np.sqrt(np.mean((network.predict(data.inputs[mask]) - labels.targets[mask]) ** 2))
    assert error == pytest.approx(outcome.training_metrics.rmse, rel=1e-9, abs=1e-9)
    val = np.sqrt(np.mean((network.predict(data.inputs[~mask]) - labels.targets[~mask]) ** 2))
    assert val == pytest.approx(outcome.validation_metrics.rmse, rel=1e-9, abs=1e-9)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_rbf_through_the_entry_point(mini, tmp_path):
    out = tmp_path / "net.npz"
    result = subprocess.run([dva_executable(), "train", "rbf", str(mini["bag"]), "--out",
                             str(out), "--labels", "measured-argmin", "--min-activation", "0",
                             "--json"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["windows"] == len(RATIOS) * len(C2) and summary["airspeeds"] == len(RATIOS)
    assert summary["critical_airspeed_no_dva"] == pytest.approx(100.0, rel=1e-3)
    assert summary["validation_airspeeds"] == 1 and out.is_file()
    assert summary["labels"] == "measured-argmin" and summary["densities"] == [1.2]
    rmse = [row["validation_rmse"] for row in summary["per_spread"]]
    active = [row["median_peak_activation"] >= 0.1 for row in summary["per_spread"]]
    best = min(r for r, a in zip(rmse, active) if a) if any(active) else min(rmse)
    assert summary["validation_rmse"] == best


def test_adapt_sweep_keeps_the_stable_leading_airspeeds():
    sweep = Scenario(name="s", duration=6 * 2 * 2.0, airspeed=AirspeedProfile(
        "steps", (0.8, 0.9, 1.0, 1.1, 1.0, 0.9), relative=True), sweep_damping=(100.0, 200.0))

    def growth(u, c):  # decays at 0.5 1/s or faster up to 100 m/s for c >= 100
        return (np.asarray(u) - 100.0) / 10.0 - 0.5 - (c - 100.0) / 1e3

    adapted = adapt_sweep(sweep, 100.0, growth, min_decay=0.5, settle=1.0, window=2.0)
    assert adapted.ratios.tolist() == [0.8, 0.9, 1.0]
    assert adapted.dropped_ratios.tolist() == [1.1, 1.0, 0.9]
    assert adapted.scenario.dwell == 3.0 and adapted.scenario.duration == 3 * 2 * 3.0
    with pytest.raises(ValueError, match="no airspeed"):
        adapt_sweep(sweep, 100.0, lambda u, c: np.ones_like(u))


def test_adapt_sweep_of_the_shipped_sweep_on_the_default_wing():
    from aero_dva import data_files
    from aero_dva.wing.flutter import growth_rate
    from aero_dva.wing.model import AeroelasticModel

    config = load_runtime_config({"scenario": str(data_files.data_file("scenario_sweep.yaml"))})
    runtime = FlightRuntime(config)
    model = AeroelasticModel(config.wing, config.absorber, config.aero)
    adapted = adapt_sweep(config.scenario, runtime.critical_airspeed,
                          lambda u, c: growth_rate(model, u, 1.2, c),
                          damping=np.linspace(200.0, 770.0, 20))
    assert adapted.ratios[0] == pytest.approx(0.8) and adapted.max_growth.max() > 0
    # A continuous sweep with one c2 list cannot reach 1.14 U_cr (the plan's reason to be).
    assert 1.0 < adapted.ratios[-1] < 1.14 and adapted.dropped_ratios[-1] == pytest.approx(1.14)


# -- corrupt or incomplete logs ---------------------------------------------------------------

def _cli_error(capsys, argv) -> str:
    assert cli.main(argv) == 2
    return capsys.readouterr().err


def test_missing_topic_is_named(tmp_path, capsys):
    with BagWriter(tmp_path / "bag") as writer:
        for topic, kind in (("/wing/acceleration", "AccelerationBlock"),
                            ("/wing/displacement", "DisplacementBlock"),
                            ("/flight/condition", "FlightCondition")):
            writer.add_topic(topic, f"dva_msgs/msg/{kind}")
            writer.write(topic, {}, 0)
    err = _cli_error(capsys, ["train", "rbf", str(tmp_path / "bag"), "--out",
                              str(tmp_path / "n.npz")])
    assert "no topic /dva/damper_state (the applied c2)" in err
    with pytest.raises(TopicNotFoundError):
        from dva_offline.training.rbf_cli import _check_topics

        _check_topics(tmp_path / "bag")


def test_wrong_message_type_is_named(tmp_path, capsys):
    with BagWriter(tmp_path / "bag") as writer:
        for topic, kind in (("/wing/acceleration", "AccelerationBlock"),
                            ("/wing/displacement", "AccelerationBlock"),
                            ("/flight/condition", "FlightCondition"),
                            ("/dva/damper_state", "DamperState")):
            writer.add_topic(topic, f"dva_msgs/msg/{kind}")
            writer.write(topic, {}, 0)
    err = _cli_error(capsys, ["train", "rbf", str(tmp_path / "bag"), "--out",
                              str(tmp_path / "n.npz")])
    assert "'/wing/displacement'" in err and "expected 'dva_msgs/msg/DisplacementBlock'" in err
    with pytest.raises(MessageTypeError):
        load_flight_log(tmp_path / "bag")


def test_truncated_file_is_reported(mini, tmp_path, capsys):
    copy = tmp_path / "bag"
    shutil.copytree(mini["bag"], copy)
    mcap = sorted(copy.glob("*.mcap"))[-1]  # the second file of the split bag
    with open(mcap, "r+b") as stream:
        stream.truncate(mcap.stat().st_size // 2)
    err = _cli_error(capsys, ["train", "rbf", str(copy), "--out", str(tmp_path / "n.npz")])
    assert mcap.name in err and "truncated or corrupt" in err
    with pytest.raises(BagReadError):
        load_flight_log(copy)


def test_too_few_windows_are_reported(mini, tmp_path, capsys):
    err = _cli_error(capsys, ["train", "rbf", str(mini["bag"]), "--out",
                              str(tmp_path / "n.npz"), "--window", "5"])
    assert "no usable 5 s window" in err and "25 dwell(s)" in err
    with pytest.raises(TrainingDataError, match="too few to hold out"):
        log = mini["log"]
        keep = slice(0, 2 * len(C2) * int(DWELL * RATE))  # the first two airspeeds only
        short = replace(log, airspeed=log.airspeed[keep], density=log.density[keep],
                        applied_damping=log.applied_damping[keep],
                        accelerations=log.accelerations[:, keep],
                        displacements=log.displacements[:, keep])
        data = build_dataset(short, window=WINDOW)
        train_network(data, label_min_rms(data))


def test_log_without_applied_c2_is_refused():
    with pytest.raises(TrainingDataError, match="no applied c2"):
        find_dwells(np.full(10, 90.0), np.full(10, np.nan))
