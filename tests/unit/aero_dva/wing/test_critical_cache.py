"""The kept critical airspeed is the flutter search's number, named by everything it depends on."""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import pytest

from aero_dva.wing import critical_cache
from aero_dva.wing.aerodynamics import WagnerAero
from aero_dva.wing.flutter import bare_critical_airspeed
from aero_dva.wing.wing_io import load_wing


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DVA_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_kept_number_is_the_search_bit_for_bit(cache):
    cfg = load_wing()
    searched = bare_critical_airspeed(cfg.wing, 1.2, cfg.aero)
    first = critical_cache.critical_airspeed(cfg.wing, 1.2, cfg.aero)
    assert first == searched and len(list(cache.iterdir())) == 1
    assert critical_cache.critical_airspeed(cfg.wing, 1.2, cfg.aero) == searched


def test_another_input_is_another_entry(cache):
    cfg = load_wing()
    paths = {critical_cache.entry_path(cfg.wing, 1.2, cfg.aero),
             critical_cache.entry_path(cfg.wing, 1.2 * (1 + 1e-15), cfg.aero),
             critical_cache.entry_path(dataclasses.replace(
                 cfg.wing, mass=cfg.wing.mass * (1 + 1e-15)), 1.2, cfg.aero),
             critical_cache.entry_path(cfg.wing, 1.2, WagnerAero()),
             critical_cache.entry_path(cfg.wing, 1.2, None)}
    assert len(paths) == 5


def test_a_changed_search_is_another_entry(cache, monkeypatch):
    cfg = load_wing()
    before = critical_cache.entry_path(cfg.wing, 1.2, cfg.aero)
    monkeypatch.setattr(critical_cache, "_code_fingerprint", lambda: "another search")
    assert critical_cache.entry_path(cfg.wing, 1.2, cfg.aero) != before


@pytest.mark.parametrize("content", ["", "garbage", f"{critical_cache.FORMAT}\nnot hex\n",
                                     f"{critical_cache.FORMAT}\n{(-1.0).hex()}\n",
                                     f"another format\n{(50.0).hex()}\n"])
def test_a_damaged_entry_is_searched_again_and_rewritten(cache, content):
    cfg = load_wing()
    path = critical_cache.entry_path(cfg.wing, 1.2, cfg.aero)
    path.parent.mkdir(parents=True)
    path.write_text(content)
    assert critical_cache.critical_airspeed(cfg.wing, 1.2, cfg.aero) == \
        bare_critical_airspeed(cfg.wing, 1.2, cfg.aero)
    assert path.read_text().startswith(critical_cache.FORMAT)


def test_an_unwritable_directory_only_costs_the_search(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("not a directory")
    monkeypatch.setenv("DVA_CACHE_DIR", str(blocked / "cache"))
    cfg = load_wing()
    assert critical_cache.critical_airspeed(cfg.wing, 1.2, cfg.aero) == \
        bare_critical_airspeed(cfg.wing, 1.2, cfg.aero)


def test_a_kept_number_spares_scipy(cache):
    """The point of keeping it: a process that finds it imports neither scipy nor the search."""
    cfg = load_wing()
    critical_cache.critical_airspeed(cfg.wing, 1.2, cfg.aero)
    code = ("import sys\nfrom aero_dva.flight.flight_runtime import FlightRuntime, "
            "load_runtime_config\nFlightRuntime(load_runtime_config({}))\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'numba'}), "
            "'aero_dva.wing.flutter' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=dict(os.environ)).stdout
    assert out.strip() == "[] False"
