"""Wing and typical-section YAML files."""
from __future__ import annotations

import math

import pytest
import yaml

from aero_dva.wing.absorbers import MaxwellAbsorber
from aero_dva.wing.aerodynamics import QuasiSteadyAero
from aero_dva.wing.wing_io import (
    default_wing_path,
    load_section,
    load_wing,
    reference_wing_path,
    save_wing,
)


@pytest.mark.parametrize("path", [default_wing_path(), reference_wing_path()])
def test_packaged_wings_load_with_their_maxwell_design(path):
    cfg = load_wing(path)
    assert cfg.wing.mass == 1000.0
    assert cfg.air_density == 1.2
    assert isinstance(cfg.aero, QuasiSteadyAero) and cfg.aero.pitch_damping == "thin_airfoil"
    assert isinstance(cfg.maxwell_design, MaxwellAbsorber)
    assert cfg.maxwell_design.mass == pytest.approx(0.04 * cfg.wing.mass)


def test_the_default_wing_is_the_chapter6_wing_and_the_reference_wing_stays_a_file():
    assert default_wing_path().name == "chapter6_wing.yaml"
    assert reference_wing_path().name == "reference_wing.yaml"
    assert load_wing() == load_wing(default_wing_path())
    assert load_wing() != load_wing(reference_wing_path())


def test_round_trip(tmp_path):
    cfg = load_wing()
    path = tmp_path / "wing.yaml"
    save_wing(path, cfg)
    assert load_wing(path) == cfg


def test_locked_damper_reads_inf(tmp_path):
    data = yaml.safe_load(reference_wing_path().read_text())
    data["absorber"]["damping"] = "inf"
    path = tmp_path / "w.yaml"
    path.write_text(yaml.safe_dump(data))
    assert math.isinf(load_wing(path).absorber.damping)


@pytest.mark.parametrize("edit,match", [
    (lambda d: d["wing"].update(mass=-5.0), "mass"),
    (lambda d: d["wing"].pop("chord"), "missing key"),
    (lambda d: d["wing"].update(chrod=1.0), "unknown key"),
    (lambda d: d.update(colour="red"), "unknown key"),
    (lambda d: d["absorber"].update(position=9.0), "outside the chord"),
    (lambda d: d["absorber"].update(type="magnetic"), "absorber type"),
    (lambda d: d.update(aero="vortex"), "aero"),
    (lambda d: d.update(aero="wagner"), "pitch_damping"),
])
def test_bad_wing_files_are_named(tmp_path, edit, match):
    data = yaml.safe_load(reference_wing_path().read_text())
    edit(data)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match=match):
        load_wing(path)


def test_section_file(tmp_path):
    path = tmp_path / "section.yaml"
    keys = dict(semichord=1.0, mass_ratio=20.0, radius_of_gyration_sq=0.24, frequency_ratio=0.4,
                static_unbalance=0.1, elastic_axis=-0.2, pitch_frequency=1.0, air_density=1.0)
    path.write_text(yaml.safe_dump(keys))
    assert load_section(path).mass_ratio == 20.0
    path.write_text(yaml.safe_dump({**keys, "mass_ratio": -2.0}))
    with pytest.raises(ValueError, match="mass_ratio"):
        load_section(path)
    path.write_text(yaml.safe_dump({**keys, "sweep": 0.3}))
    with pytest.raises(ValueError, match="unknown key"):
        load_section(path)
