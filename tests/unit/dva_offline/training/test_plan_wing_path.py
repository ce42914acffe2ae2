"""A training plan's embedded wing path: taken from the plan's folder when relative, refused
in one line when it is missing or names nothing, never replaced by the package's wing."""
from __future__ import annotations

import json
import shutil

import pytest

from aero_dva.wing.wing_io import default_wing_path, reference_wing_path
from dva_offline import cli

SMALL = ["--ratios", "0.9:0.92:0.02", "--factors", "1.0", "--n-damping", "2"]


@pytest.fixture(scope="module")
def plan_dir(tmp_path_factory):
    """A plan made for the reference wing, kept beside a copy of it as ``wing.yaml``."""
    root = tmp_path_factory.mktemp("plan")
    shutil.copy(reference_wing_path(), root / "wing.yaml")
    assert cli.main(["train", "plan", *SMALL, "--wing", str(root / "wing.yaml"), "--out",
                     str(root / "plan.json")]) == 0
    return root


def _plan_naming(plan_dir, tmp_path, wing: str):
    data = json.loads((plan_dir / "plan.json").read_text())
    data["wing"] = wing
    folder = tmp_path / "moved"
    folder.mkdir()
    (folder / "plan.json").write_text(json.dumps(data))
    return folder / "plan.json"


def test_a_relative_wing_path_is_taken_from_the_plans_folder(plan_dir, tmp_path, monkeypatch,
                                                             capsys):
    plan = _plan_naming(plan_dir, tmp_path, "wing.yaml")
    shutil.copy(plan_dir / "wing.yaml", plan.parent / "wing.yaml")
    monkeypatch.chdir(tmp_path)  # not the plan's folder
    out = tmp_path / "bag"
    assert cli.main(["train", "sweep", "--plan", str(plan), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["wing"] == str((plan.parent / "wing.yaml").resolve())


@pytest.mark.parametrize("wing, words", [
    ("no_such_wing.yaml", "its wing file"),
    ("/nowhere/wing.yaml", "does not exist"),
    ("", "names no wing file"),
])
def test_a_missing_wing_is_refused_never_replaced_by_a_default(plan_dir, tmp_path, capsys,
                                                                wing, words):
    plan = _plan_naming(plan_dir, tmp_path, wing)
    out = tmp_path / "bag"
    assert cli.main(["train", "sweep", "--plan", str(plan), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "--wing" in err[0], err
    assert not out.exists()
    assert default_wing_path().name not in err[0]


def test_train_rbf_refuses_a_bag_whose_plan_names_a_missing_wing(plan_dir, tmp_path,
                                                                  capsys):
    bag = tmp_path / "bag"
    assert cli.main(["train", "sweep", "--plan", str(plan_dir / "plan.json"), "--out",
                     str(bag)]) == 0
    data = json.loads((bag / "training_plan.json").read_text())
    data["wing"] = "gone.yaml"
    (bag / "training_plan.json").write_text(json.dumps(data))
    capsys.readouterr()
    assert cli.main(["train", "rbf", str(bag), "--out", str(tmp_path / "n.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "its wing file" in err and "gone.yaml" in err, err
