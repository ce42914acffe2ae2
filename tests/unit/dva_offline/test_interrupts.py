"""Interrupts leave a complete result or nothing that looks complete: a sweep cut short is
kept marked "interrupted" (its metadata, ``dva bag info``), ``dva train rbf`` refuses it
unless ``--allow-partial`` and then says what is missing; a cut ``dva bag recover`` leaves no
hidden ``.partial`` folder; a cut or failed ``dva evaluate`` no ``inputs/``; SIGTERM ends a
``dva`` command as SIGINT does (one line, exit 130)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from aero_dva.bag.reader import bag_interruption, read_messages
from aero_dva.bag.writer import INTERRUPTED_KEY
from dva_offline import cli
from dva_offline.training.plan_io import PLAN_FILE, load_plan

SMALL = ["--ratios", "0.8:1.12:0.02", "--factors", "1.0", "--n-damping", "4"]
WAIT = 300.0  # [s] a guard against a hang: every wait below is for a condition


@pytest.fixture(scope="module")
def cut_sweep(tmp_path_factory):
    """A planned sweep recorded in batches of 8 dwells, cut by an interrupt after the second
    batch, inside the CLI's recording guard."""
    from dva_offline.training import cli as train_cli
    from dva_offline.training import recording_io
    from dva_offline.training.cli import _wing

    root = tmp_path_factory.mktemp("cut")
    assert cli.main(["train", "plan", *SMALL, "--out", str(root / "plan.json")]) == 0
    plan, wing = load_plan(root / "plan.json")
    _, model, _, wing_id = _wing(wing)
    batches = []

    def progress(done, total):
        batches.append(done)
        if len(batches) == 2:
            raise KeyboardInterrupt

    bag = root / "bag"
    with pytest.raises(KeyboardInterrupt), train_cli._recording_into(bag):
        recording_io.record_plan(bag, model, plan, wing=wing_id[0],
                                 wing_fingerprint=wing_id[1], batch=8, progress=progress)
    return {"bag": bag, "plan": plan, "recorded": batches[-1], "root": root}


def test_a_cut_sweep_is_kept_marked_interrupted(cut_sweep, capsys):
    bag = cut_sweep["bag"]
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert "interrupted" in meta["custom_data"][INTERRUPTED_KEY]
    assert "interrupted" in bag_interruption(bag)
    assert (bag / PLAN_FILE).is_file()  # written first: the bag says what it was to hold
    assert sum(1 for _ in read_messages(bag, ["/wing/acceleration"])) > 0
    assert cli.main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "interrupted (SIGINT or SIGTERM) before its end" in out


def test_train_rbf_refuses_a_cut_sweep_and_with_allow_partial_says_what_is_missing(
        cut_sweep, tmp_path, capsys):
    bag, plan = cut_sweep["bag"], cut_sweep["plan"]
    net = tmp_path / "net.npz"
    assert cli.main(["train", "rbf", str(bag), "--out", str(net)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "is not a whole sweep" in err and "--allow-partial" in err
    assert "no end-of-flight report" in err and "interrupted" in err
    assert not net.exists()
    missing = plan.n_dwells - 16  # two batches of 8 dwells were recorded
    cli.main(["train", "rbf", str(bag), "--out", str(net), "--allow-partial",
              "--validation-every", "2"])
    err = capsys.readouterr().err
    assert f"{missing} of the plan's {plan.n_dwells} dwells have no window" in err


def test_a_failed_sweep_leaves_no_bag(tmp_path):
    from dva_offline.training import cli as train_cli

    bag = tmp_path / "bag"
    with pytest.raises(RuntimeError), train_cli._recording_into(bag):
        bag.mkdir()
        (bag / "half.mcap").write_bytes(b"\x89MCAP0\r\n")
        raise RuntimeError("a failure mid-recording")
    assert not bag.exists()


def test_a_cut_recovery_leaves_no_partial_folder(tmp_path, monkeypatch):
    from aero_dva.bag import recovery
    from bench.faults.resource_bombs import valid_bag

    source = valid_bag(tmp_path / "source")

    def cut(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(recovery, "_copy", cut)
    with pytest.raises(KeyboardInterrupt):
        recovery.recover_bag(source, tmp_path / "copy")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["source"]


def _dva(*args, **kwargs) -> subprocess.Popen:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen([sys.executable, "-m", "dva_offline.cli", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            **kwargs)


def _wait_for(condition, process) -> None:
    deadline = time.monotonic() + WAIT
    while not condition():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the condition never held"
        time.sleep(0.05)


@pytest.mark.slow
@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT])
def test_a_signalled_evaluate_ends_in_one_line_and_leaves_no_inputs(tmp_path, stop):
    out = tmp_path / "eval"
    process = _dva("evaluate", "--controllers", "fixed,schedule", "--cases", "rho0",
                   "--seeds", "2", "--out", str(out))
    _wait_for(lambda: (out / "inputs").is_dir(), process)
    process.send_signal(stop)
    _, err = process.communicate(timeout=WAIT)
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == f"dva evaluate: interrupted by {stop.name}"
    assert not out.exists()


@pytest.mark.slow
def test_a_sigtermed_sweep_is_kept_marked_interrupted(tmp_path):
    bag = tmp_path / "bag"
    process = _dva("train", "sweep", "--out", str(bag))  # the default plan: minutes
    _wait_for(lambda: (bag / PLAN_FILE).is_file(), process)  # the recording has begun
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=WAIT)
    assert process.returncode == 130, err
    lines = err.strip().splitlines()
    assert lines[-1] == "dva train: interrupted by SIGTERM"
    assert any("marked interrupted" in line for line in lines[:-1])
    assert "interrupted" in bag_interruption(bag)


def test_a_failed_evaluate_leaves_no_inputs(tmp_path, monkeypatch, capsys):
    from dva_offline.evaluation import flights

    def broken(*args, **kwargs):
        raise RuntimeError("a failure while flying")

    monkeypatch.setattr(flights, "fly_paired", broken)
    out = tmp_path / "eval"
    code = cli.main(["evaluate", "--controllers", "fixed", "--fixed-c2", "624.7", "--cases",
                     "rho0", "--seeds", "2", "--no-boundaries", "--out", str(out)])
    assert code == 3 and not out.exists(), capsys.readouterr().err
    assert Path(tmp_path).exists()
