"""``dva bag info|recover``: output, exit codes, and nothing half-written."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from aero_dva.bag.reader import bag_topics
from dva_offline import cli
from dva_offline.bag.cli import RECOVERED_WITH_LOSSES
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
    assert "closed     no: no metadata.yaml" in out and "damage     cut_0.mcap bytes" in out
    assert "the file ends inside a chunk record" in out
    assert f"run `dva bag recover {cut} --out NEW_BAG`" in out
    # A cut file has no index to say what was lost: recovered, possibly with losses (1).
    assert cli.main(["bag", "recover", str(cut), "--out", str(tmp_path / "new"),
                     "--json"]) == RECOVERED_WITH_LOSSES
    result = json.loads(capsys.readouterr().out)
    assert result["exit_code"] == RECOVERED_WITH_LOSSES == 1  # the code, said in the JSON too
    assert result["damage"]["offset"] > 0 and result["lost"] is None and result["kept"] == sum(
        t.message_count for t in bag_topics(tmp_path / "new").values())
    assert cli.main(["bag", "recover", str(cut), "--out", str(tmp_path / "new2")]) == 1
    out = capsys.readouterr().out
    assert f"kept       {result['kept']} messages" in out and "new bag" in out
    assert "lost       unknown" in out
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


def test_a_flipped_bit_is_reported_damaged_and_recovered_with_losses(bag, tmp_path, capsys):
    """One flipped bit in the third chunk: info says damaged (and, unchecked, says it did not
    check), recover keeps the other chunks and exits 3; the intact bag's copy exits 0."""
    flipped = tmp_path / "flipped"
    flipped.mkdir()
    (mcap,) = bag.glob("*.mcap")
    data = bytearray(mcap.read_bytes())
    data[len(data) // 4] ^= 0x10
    (flipped / mcap.name).write_bytes(bytes(data))
    (flipped / "metadata.yaml").write_text((bag / "metadata.yaml").read_text())
    assert cli.main(["bag", "info", str(flipped)]) == 0
    out = capsys.readouterr().out
    assert "damaged    1 byte range(s) do not read; messages lost: " in out
    assert "chunk fails its CRC" in out and "of 720 the bag's index promises" in out
    assert cli.main(["bag", "info", str(flipped), "--no-verify"]) == 0
    assert "CRCs not checked (--no-verify)" in capsys.readouterr().out
    assert cli.main(["bag", "info", str(flipped), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    (damaged,) = info["damaged"]
    assert info["verified"] and 0 < info["lost"] == damaged["lost"] < 720
    assert info["message_count"] == 720 - info["lost"]
    assert damaged["start"] < len(data) // 4 < damaged["end"]
    assert damaged["start_ns"] <= damaged["end_ns"] and sum(damaged["topics"].values()) == \
        damaged["lost"]
    new = tmp_path / "new"
    assert cli.main(["bag", "recover", str(flipped), "--out", str(new)]) == 1
    assert f"lost       {info['lost']} of 720" in capsys.readouterr().out
    assert sum(t.message_count for t in bag_topics(new).values()) == 720 - info["lost"]
    assert cli.main(["bag", "recover", str(bag), "--out", str(tmp_path / "whole")]) == 0
    assert "lost       0 of 720" in capsys.readouterr().out
