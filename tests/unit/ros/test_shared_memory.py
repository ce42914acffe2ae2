"""Unsized Fast DDS port files of dead processes are removed; live ones are kept."""
from __future__ import annotations

import os
import time

from dva_ros_common.shared_memory import clear_dead_ports, remove_unsized_ports


def _file(path, size: int, age: float):
    path.write_bytes(b"\0" * size)
    then = time.time() - age
    os.utime(path, (then, then))
    return path


def test_only_old_unsized_ports_and_their_mutex_are_removed(tmp_path):
    dead = _file(tmp_path / "fastrtps_port7913", 0, 120.0)
    mutex = _file(tmp_path / "sem.fastrtps_port7913_mutex", 32, 120.0)
    being_created = _file(tmp_path / "fastrtps_port7915", 0, 1.0)
    live = _file(tmp_path / "fastrtps_port7917", 4096, 120.0)
    other_mutex = _file(tmp_path / "sem.fastrtps_port7917_mutex", 32, 120.0)
    segment = _file(tmp_path / "fastrtps_00de632052a5ac1d", 0, 120.0)
    lock = _file(tmp_path / "fastrtps_port7911_el", 0, 120.0)  # empty by design, held by a live
    other_lock = _file(tmp_path / "fastrtps_port7911_sl", 0, 120.0)

    assert remove_unsized_ports(tmp_path, min_age=60.0) == [dead]
    assert not dead.exists() and not mutex.exists()
    for kept in (being_created, live, other_mutex, segment, lock, other_lock):
        assert kept.exists(), kept.name


def test_a_missing_directory_removes_nothing(tmp_path):
    assert remove_unsized_ports(tmp_path / "absent") == []


def test_each_removed_port_is_said_after_its_remover(tmp_path, capsys):
    dead = _file(tmp_path / "fastrtps_port7913", 0, 120.0)
    _file(tmp_path / "fastrtps_port7915", 4096, 120.0)
    assert clear_dead_ports("[fixed_controller]", tmp_path) == [dead]
    err = capsys.readouterr().err
    assert err == (f"[fixed_controller] removed {dead}: an unsized Fast DDS port file a dead "
                   "process left\n")


def test_only_old_segments_whose_lock_nobody_holds_are_removed(tmp_path, capsys):
    import fcntl

    def segment(name: str, age: float):
        return _file(tmp_path / name, 4096, age), _file(tmp_path / f"{name}_el", 0, age)

    dead, dead_lock = segment("fastrtps_00de632052a5ac1d", 120.0)
    live, live_lock = segment("fastrtps_11de632052a5ac1d", 120.0)
    young, young_lock = segment("fastrtps_22de632052a5ac1d", 1.0)
    port_lock = _file(tmp_path / "fastrtps_port7911_el", 0, 120.0)  # a port's: not a segment
    with open(live_lock, "rb") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # as a live participant holds its segment's lock
        assert clear_dead_ports("[simulator]", tmp_path) == [dead]
    assert not dead.exists() and not dead_lock.exists()
    for kept in (live, live_lock, young, young_lock, port_lock):
        assert kept.exists(), kept.name
    assert capsys.readouterr().err == ""  # a node's one-line errors stay one line
