"""Outputs that cannot collide (aero_dva.atomic_io): of many runs asking for one name at once,
exactly one gets it; a default name moves on; a held output refuses a second run."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import pytest

from aero_dva.atomic_io import (
    OutputBusyError,
    atomic_output,
    check_writable,
    new_directory,
    output_lock,
    unique_directory,
)
from aero_dva.bag.writer import BagWriter, open_new_bag_file

N = 8  # processes racing for one name

#: One racer: a fresh interpreter (a fork of this test process could inherit the locks of
#: threads other tests left running, e.g. Ray's or rerun's, and hang), ready when it has
#: imported, claiming when the go file appears, printing what it got.
RACER = textwrap.dedent("""
    import os, sys, time
    from pathlib import Path
    from aero_dva.atomic_io import new_directory, unique_directory
    mode, target, ready, go = sys.argv[1:]
    Path(ready).touch()
    while not os.path.exists(go):
        time.sleep(0.001)
    if mode == "default":
        print(unique_directory(Path(target), siblings=("_logs",)))
    else:
        try:
            new_directory(Path(target), "--output", siblings=("_logs",))
            print("created")
        except FileExistsError as exc:
            print(f"refused: {exc}")
""")


def _race(mode: str, target, tmp_path) -> list[str]:
    """What each of N racers for ``target`` got, all let go at once once all have started."""
    go = tmp_path / "go"
    ready = [tmp_path / f"ready_{i}" for i in range(N)]
    racers = [subprocess.Popen([sys.executable, "-c", RACER, mode, str(target), str(r), str(go)],
                               stdout=subprocess.PIPE, text=True) for r in ready]
    try:
        while not all(r.exists() for r in ready):  # a condition: every racer has imported
            assert all(p.poll() is None for p in racers), "a racer ended before the start"
            time.sleep(0.01)
        go.touch()
        outputs = [p.communicate(timeout=600)[0].strip() for p in racers]
    finally:
        for p in racers:
            if p.poll() is None:
                p.kill()
    assert all(p.returncode == 0 for p in racers), outputs
    return outputs


def test_runs_started_together_get_distinct_default_names(tmp_path):
    stem = tmp_path / "runs" / "ramp_fixed_20261128T120000Z"
    names = _race("default", stem, tmp_path)
    assert len(set(names)) == N
    assert sorted(names) == sorted([str(stem)] + [f"{stem}_{n}" for n in range(2, N + 1)])
    for name in names:  # each with its own logs folder, both empty
        assert not any((tmp_path / "runs" / name).iterdir())
        assert not any((tmp_path / "runs" / f"{name}_logs").iterdir())


def test_of_runs_given_one_name_at_once_exactly_one_gets_it(tmp_path):
    results = _race("given", tmp_path / "bag", tmp_path)
    assert results.count("created") == 1
    assert all("choose another name" in r for r in results if r != "created")


def test_a_taken_name_or_logs_folder_is_refused_and_nothing_is_left(tmp_path):
    (tmp_path / "x_logs").mkdir()
    with pytest.raises(FileExistsError, match="x_logs' exists; choose another name"):
        new_directory(tmp_path / "x", "--output", siblings=("_logs",))
    assert not (tmp_path / "x").exists()  # the half it had made is gone again
    (tmp_path / "a_file").write_text("")
    with pytest.raises(NotADirectoryError, match="is not a directory"):
        new_directory(tmp_path / "a_file" / "bag", "--output")
    # a default name whose logs folder is taken moves on as well
    assert unique_directory(tmp_path / "x", siblings=("_logs",)) == tmp_path / "x_2"


def test_a_held_output_refuses_a_second_run_until_it_is_released(tmp_path):
    out = tmp_path / "schedule.json"
    held = textwrap.dedent(f"""
        import sys
        from aero_dva.atomic_io import output_lock
        with output_lock({str(out)!r}, "--out"):
            print("held", flush=True)
            sys.stdin.readline()
    """)
    other = subprocess.Popen([sys.executable, "-c", held], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout.readline().strip() == "held"
        with pytest.raises(OutputBusyError, match="being written by another run"), \
                output_lock(out, "--out"):
            pass
    finally:
        other.communicate("\n", timeout=60)
    with output_lock(out, "--out"):  # released: free again, and once more after
        pass
    with output_lock(out, "--out"):
        pass


def test_two_bag_writers_never_share_one_bag_directory(tmp_path):
    bag = tmp_path / "bag"
    bag.mkdir()  # empty: a writer takes it
    with BagWriter(bag) as first:
        # a second writer that checked the directory empty before the first's file appeared
        # is refused when it creates the file, never mixed in
        with pytest.raises(FileExistsError, match="another writer has this bag"):
            open_new_bag_file(first.mcap_path)


def test_an_output_that_could_not_be_written_is_refused_before_any_work(tmp_path):
    (tmp_path / "a_file").write_text("")
    with pytest.raises(NotADirectoryError, match="'.*a_file' is not a directory"):
        check_writable(tmp_path / "a_file" / "sub" / "out.json", "--out")
    check_writable(tmp_path / "new" / "deeper" / "out.json")  # folders still to be made: fine
    if os.geteuid() != 0:  # (root writes anywhere a read-only file system allows)
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(PermissionError, match="no permission to write in"):
            check_writable(locked / "out.json", "--out")


def test_a_file_output_gets_its_folder_and_a_failure_names_the_output(tmp_path):
    target = tmp_path / "made" / "for" / "it.json"
    with atomic_output(target) as stream:
        stream.write("{}")
    assert target.read_text() == "{}"
    (tmp_path / "a_file").write_text("")
    with pytest.raises(OSError) as raised, atomic_output(tmp_path / "a_file" / "x.json"):
        pass
    assert raised.value.filename == str(tmp_path / "a_file" / "x.json")  # not a temporary name
