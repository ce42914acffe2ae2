"""Defaults said once: the node YAML examples (which cannot import) hold the values of the
defaults' homes, and the nodes' parameters and the CLIs take them from there.

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

SRC = Path(__file__).resolve().parents[3] / "ros_ws" / "src"

#: (config file, node, parameter) -> the home's value.
EXPECTED = {
    ("aero_dva_sim/config/simulator.yaml", "simulator", "damper_min"): DAMPER_RANGE[0],
    ("aero_dva_sim/config/simulator.yaml", "simulator", "damper_max"): DAMPER_RANGE[1],
    ("aero_dva_sim/config/simulator.yaml", "simulator", "damper_timeout"): DEFAULT_STALE_TIMEOUT,
    ("dva_controller/config/airspeed_controller.yaml", "airspeed_controller", "damping_min"):
        DAMPER_RANGE[0],
    ("dva_controller/config/airspeed_controller.yaml", "airspeed_controller", "damping_max"):
        DAMPER_RANGE[1],
    ("dva_controller/config/airspeed_controller.yaml", "airspeed_controller", "max_airspeed"):
        MAX_AIRSPEED,
    ("dva_controller/config/rbf_controller.yaml", "rbf_controller", "damping_min"):
        DAMPER_RANGE[0],
    ("dva_controller/config/rbf_controller.yaml", "rbf_controller", "damping_max"):
        DAMPER_RANGE[1],
    ("dva_controller/config/rbf_controller.yaml", "rbf_controller", "frequencies"):
        DEFAULT_FREQUENCIES.tolist(),
    ("dva_controller/config/spectrum.yaml", "spectrum", "frequencies"):
        DEFAULT_FREQUENCIES.tolist(),
}


@pytest.mark.parametrize("key", sorted(EXPECTED), ids=lambda k: f"{k[1]}.{k[2]}")
def test_the_node_yaml_examples_hold_the_homes_values(key):
    path, node, name = key
    params = yaml.safe_load((SRC / path).read_text())[node]["ros__parameters"]
    assert params[name] == EXPECTED[key], f"{path}: {name} is not its home's value"


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
