"""``dva bag info|recover``: output, exit codes, and nothing half-written."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from aero_dva.bag.reader import bag_topics
from dva_offline import cli
from tests.unit.aero_dva.bag.reference_bag import write_batch_bag


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    return write_batch_bag(tmp_path_factory.mktemp("bags") / "run")


@pytest.fixture
def cut(bag, tmp_path):
    """The bag as a killed recorder leaves it: no metadata.yaml, the file cut at 60 %."""
    path = tmp_path / "cut"
    path.mkdir()
    data = next(bag.glob("*.mcap")).read_bytes()
    (path / "cut_0.mcap").write_bytes(data[:len(data) * 6 // 10])
    return path


def test_info_of_a_closed_bag(bag, capsys):
    assert cli.main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "closed     yes" in out and "messages   720" in out
    assert "/wing/acceleration" in out and "dva_msgs/msg/AccelerationBlock" in out
    assert "duration   5.917 s" in out  # log times from the first block's end to the last's
    assert cli.main(["bag", "info", str(bag), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["closed"] and info["damage"] is None
    assert {t["name"]: t["count"] for t in info["topics"]}["/clock"] == 120


def test_info_and_recover_of_a_cut_bag(cut, tmp_path, capsys):
    assert cli.main(["bag", "info", str(cut)]) == 0
    out = capsys.readouterr().out
    assert "closed     no: no metadata.yaml" in out and "damage     cut_0.mcap at byte" in out
    assert f"run `dva bag recover {cut} --out NEW_BAG`" in out
    assert cli.main(["bag", "recover", str(cut), "--out", str(tmp_path / "new"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["damage"]["offset"] > 0 and result["kept"] == sum(
        t.message_count for t in bag_topics(tmp_path / "new").values())
    assert cli.main(["bag", "recover", str(cut), "--out", str(tmp_path / "new2")]) == 0
    out = capsys.readouterr().out
    assert f"kept       {result['kept']} messages" in out and "new bag" in out
    assert cli.main(["bag", "info", str(tmp_path / "new")]) == 0
    assert "closed     yes" in capsys.readouterr().out


@pytest.mark.parametrize("content", [b"", b"\x00\xff" * 100, b"MCAP? no"])
def test_bad_input_is_one_line_exit_2_and_no_output(content, tmp_path):
    bad = tmp_path / "bad file ü.mcap"
    bad.write_bytes(content)
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "dva_offline.cli", "bag", "recover",
                             str(bad), "--out", str(out)], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("dva bag: error:") and result.stderr.count("\n") == 1
    assert "Traceback" not in result.stderr and not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == [bad.name]


def test_recover_into_an_existing_bag_is_refused(bag, cut, capsys):
    assert cli.main(["bag", "recover", str(cut), "--out", str(bag)]) == 2
    assert "exists and is not empty" in capsys.readouterr().err
    assert cli.main(["bag", "info", str(cut.parent / "nowhere")]) == 2
    assert "does not exist" in capsys.readouterr().err
