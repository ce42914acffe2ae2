"""``dva replay --offline`` on a flight written as the simulator publishes it (no ROS)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from aero_dva.bag.writer import BagWriter
from aero_dva.control.command_laws import RBFLaw
from aero_dva.control.controllers import controller
from aero_dva.control.spectrum import scaled_spectrum
from aero_dva.flight.flight_runtime import FlightRuntime, load_runtime_config
from dva_offline import cli
from dva_offline.replay.bag_io import read_outputs, read_recording
from dva_offline.replay.rerun import CommandRecord, compare, law_commands, spectra_from_inputs
from tests.unit.dva_offline.small_networks import small_spectrum_network

FREQS = np.arange(5.0, 21.0)
NS = 1_000_000_000


def _header(t_ns: int, frame: str = "wing") -> dict:
    return {"stamp": {"sec": t_ns // NS, "nanosec": t_ns % NS}, "frame_id": frame}


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A 3.5 s flight in blocks of 50 samples, with the damper state each block was flown
    with, stamped at its start (as the simulator publishes them), and the c2 commands of a
    network ``net_a`` on the offline spectra recorded as if it had flown."""
    root = tmp_path_factory.mktemp("replay")
    scenario = root / "hold.yaml"
    scenario.write_text("name: hold\nduration: 3.5\nblock_size: 50\n"
                        "airspeed: {kind: constant, value: 90.0}\n"
                        "excitation: {force_std: 1000.0, seed: 4}\n")
    runtime = FlightRuntime(load_runtime_config({"scenario": str(scenario)}))
    net_a, network = small_spectrum_network(root / "net_a.npz", 0.3)
    net_b, _ = small_spectrum_network(root / "net_b.npz", 0.6)
    blocks, states = [], []
    while not runtime.done:
        if runtime.time > 1.0:
            runtime.command(400.0 + 100.0 * round(runtime.time * 10) % 3, "test")
        block = runtime.step()
        blocks.append(block)
        snap = runtime.flown_damper
        states.append((round(snap.time * NS), snap.applied_damping))
    bag = root / "flight"
    with BagWriter(bag) as writer:
        writer.add_topic("/wing/acceleration", "dva_msgs/msg/AccelerationBlock")
        writer.add_topic("/dva/damper_state", "dva_msgs/msg/DamperState")
        writer.add_topic("/flight/condition", "dva_msgs/msg/FlightCondition")
        for block, (state_ns, applied) in zip(blocks, states):
            t0 = round(block.t0 * NS)
            acc = block.accelerations
            writer.write("/wing/acceleration", {
                "header": _header(t0), "sample_rate": 1000.0,
                "first_sample_index": block.first_index, "plunge": acc[0], "pitch": acc[1],
                "leading_edge": acc[2]}, state_ns)
            writer.write("/flight/condition", {"header": _header(t0, ""),
                                               "airspeed": float(block.airspeed[0]),
                                               "air_density": 1.2}, state_ns)
            writer.write("/dva/damper_state", {
                "header": _header(state_ns, ""), "commanded_damping": applied,
                "applied_damping": applied, "min_damping": 0.0, "max_damping": 2500.0,
                "command_age": 0.0, "status": 0, "source": "test"}, state_ns)
    samples = np.concatenate([b.accelerations[:2] for b in blocks], axis=1)
    return {"bag": bag, "net_a": net_a, "net_b": net_b, "network": network,
            "samples": samples, "states": states, "root": root}


def test_offline_spectra_are_the_windows_of_the_recorded_samples(flight):
    recording = read_recording(flight["bag"])
    assert len(recording.inputs) == 2 * 70 and len(recording.conditions) == 70
    spectra = spectra_from_inputs(recording.inputs, ("plunge", "pitch"), 2.0, 0.1, FREQS,
                                  "rectangular")
    assert len(spectra) == (3500 - 2000) // 100 + 1
    for i, s in enumerate(spectra):
        start = 100 * i
        assert s.stamp_ns == round((start + 1999) * 1e6)
        window = scaled_spectrum(flight["samples"][:, start:start + 2000], 1000.0, FREQS)
        np.testing.assert_allclose(s.magnitudes, window.magnitudes, rtol=1e-12)
        # c2 of each block = the state stamped at its start
        blocks = range(start // 50, (start + 2000) // 50)
        held = [flight["states"][k][1] for k in blocks]
        assert s.damping == pytest.approx(np.mean(held), rel=1e-12)


def test_dva_replay_offline_writes_a_bag_and_compares(flight, tmp_path, capsys):
    out = tmp_path / "replayed"
    assert cli.main(["replay", str(flight["bag"]), "--controller", "rbf", "--network",
                     str(flight["net_a"]), "--out", str(out), "--offline", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    spectra, commands = read_outputs(out)
    assert len(spectra) == 16 and len(commands) == 16
    law = RBFLaw(flight["network"], (0.0, 2500.0))
    assert [c.damping for c in commands] == [law.command(s.magnitudes, s.damping)[0]
                                             for s in spectra]
    assert result["spectra"]["reference"] == 0  # the bag recorded no spectra
    assert result["commands"]["other"] == 16

    again = tmp_path / "again"
    assert cli.main(["replay", str(flight["bag"]), "--controller", "rbf", "--network",
                     str(flight["net_b"]), "--out", str(again), "--offline", "--json"]) == 0
    _, other = read_outputs(again)
    versus = compare(commands, other)
    assert versus.matched == 16 and not versus.identical and versus.max_abs_difference > 1.0


def test_compare_matches_by_stamp_and_counts_the_unmatched():
    a = [CommandRecord(1, 10.0, "x"), CommandRecord(2, 20.0, "x")]
    assert compare(a, list(a)).identical
    b = [CommandRecord(2, 25.0, "x"), CommandRecord(3, 30.0, "x")]
    c = compare(a, b)
    assert (c.matched, c.max_abs_difference, c.identical) == (1, 5.0, False)
    assert compare(a, [CommandRecord(1, float("nan"), "x"), a[1]]).max_abs_difference == np.inf
    # another controller's commands at other times: against the c2 in force at each stamp
    held = compare(a, [CommandRecord(3, 26.0, "y"), CommandRecord(0, 5.0, "y")]).held
    assert held == {"compared": 1, "mean_difference": 6.0, "max_abs_difference": 6.0,
                    "rms_difference": 6.0}


def test_a_law_of_spectra_skips_spectra_without_a_valid_c2(flight):
    recording = read_recording(flight["bag"])
    shape = (("plunge", "pitch"), FREQS, 2.0, "rectangular")
    spectra = spectra_from_inputs(recording.inputs, shape[0], 2.0, 0.1, FREQS, "rectangular")
    broken = [type(spectra[0])(s.stamp_ns, s.magnitudes, s.band_sums, float("nan"))
              for s in spectra[:3]]
    law = RBFLaw(flight["network"], (0.0, 2500.0))
    assert law_commands(controller("rbf"), law, [], broken, shape) == []
    assert len(law_commands(controller("rbf"), law, [], spectra[:3], shape)) == 3


@pytest.mark.parametrize("case", ["no_network", "out_exists", "no_bag", "wrong_network"])
def test_bad_input_is_a_one_line_error(case, flight, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["replay", str(flight["bag"]), "--controller", "rbf", "--network",
            str(flight["net_a"]), "--out", str(out), "--offline"]
    if case == "no_network":
        argv = argv[:4] + argv[6:]
    elif case == "out_exists":
        out.mkdir()
    elif case == "no_bag":
        argv[1] = str(tmp_path / "missing")
    else:
        bad = tmp_path / "bad.npz"
        bad.write_bytes(b"not a network")
        argv[5] = str(bad)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("dva replay: error:"), err
    assert case == "out_exists" or not out.exists()
