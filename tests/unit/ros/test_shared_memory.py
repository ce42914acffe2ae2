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
