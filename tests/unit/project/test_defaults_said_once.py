"""Defaults said once: the node YAML files (which cannot import) leave the damper's range, the
stale timeout, the airspeed limit and the spectrum band out, so the nodes take them from their
homes; the nodes' declared defaults and the CLIs are those homes' values.

The homes: the damper's range and the stale-command timeout in
``aero_dva.flight.flight_limits`` (re-exported by ``aero_dva.flight.damper``, which uses them);
MAX_DAMPING and the airspeed limit in ``aero_dva.input_ranges`` (flight_limits gives MAX_DAMPING
on); the spectrum band in
``aero_dva.control.law_defaults`` (``aero_dva.control.spectrum`` holds it as an array); the
controllers' parameters in the controller table. The homes import no numerics, so that a node's
``--help`` states them without loading numpy (docs/performance.md).
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from aero_dva.control.spectrum import DEFAULT_FREQUENCIES
from aero_dva.flight.damper import DAMPER_RANGE, DEFAULT_STALE_TIMEOUT, MAX_DAMPING, DamperConfig
from aero_dva.input_ranges import ABSORBER, MAX_AIRSPEED

REPO = Path(__file__).resolve().parents[3]
SRC = REPO / "ros_ws" / "src"

#: (parameters file, node) -> the parameters it must leave to their homes.
LEFT_TO_THE_HOMES = {
    ("ros_ws/src/aero_dva_sim/config/simulator.yaml", "simulator"):
        ("damper_min", "damper_max", "damper_timeout"),
    ("config/graph.yaml", "simulator"): ("damper_min", "damper_max", "damper_timeout"),
    ("ros_ws/src/dva_controller/config/airspeed_controller.yaml", "airspeed_controller"):
        ("damping_min", "damping_max", "max_airspeed"),
    ("ros_ws/src/dva_controller/config/rbf_controller.yaml", "rbf_controller"):
        ("damping_min", "damping_max", "frequencies"),
    ("ros_ws/src/dva_controller/config/spectrum.yaml", "spectrum"): ("frequencies",),
}


@pytest.mark.parametrize("key", sorted(LEFT_TO_THE_HOMES), ids=lambda k: f"{k[0]}:{k[1]}")
def test_the_parameters_files_leave_the_homes_values_to_the_nodes(key):
    path, node = key
    params = yaml.safe_load((REPO / path).read_text())[node]["ros__parameters"]
    said_again = sorted(set(LEFT_TO_THE_HOMES[key]) & set(params))
    assert not said_again, f"{path} repeats {said_again}: leave them to the node's defaults"


def test_the_nodes_declare_the_homes_values():
    pytest.importorskip("dva_ros_common", reason="needs the built workspace")
    from aero_dva.control import controllers as table
    from aero_dva_sim.simulator_spec import SPEC as SIMULATOR
    from dva_controller.controller_spec import node_spec
    from dva_controller.spectrum_spec import SPEC as SPECTRUM

    assert (SIMULATOR["damper_min"].default, SIMULATOR["damper_max"].default) == DAMPER_RANGE
    assert SIMULATOR["damper_timeout"].default == DEFAULT_STALE_TIMEOUT
    schedule, rbf = node_spec(table.controller("schedule")), node_spec(table.controller("rbf"))
    for spec in (schedule, rbf):
        assert (spec["damping_min"].default, spec["damping_max"].default) == DAMPER_RANGE
    assert schedule["max_airspeed"].default == MAX_AIRSPEED
    assert list(rbf["frequencies"].default) == DEFAULT_FREQUENCIES.tolist()
    assert list(SPECTRUM["frequencies"].default) == DEFAULT_FREQUENCIES.tolist()


def test_the_homes_are_what_the_damper_and_the_laws_default_to():
    from aero_dva.control import controllers as table

    assert DamperConfig(*DAMPER_RANGE, fallback_damping=0.0).stale_timeout == \
        DEFAULT_STALE_TIMEOUT
    schedule = table.controller("schedule").defaults()
    assert (schedule["damping_min"], schedule["damping_max"]) == DAMPER_RANGE
    assert schedule["max_airspeed"] == MAX_AIRSPEED
    rbf = table.controller("rbf").defaults()
    assert rbf["frequencies"] == DEFAULT_FREQUENCIES.tolist()
    assert all(p.high == MAX_DAMPING for e in table.controllers() for p in e.params
               if p.unit == "N s/m" and p.low == 0.0)
    # a wing file's c2 is refused where a parameter is: one bound for both
    assert ABSORBER["damping"].high == MAX_DAMPING
