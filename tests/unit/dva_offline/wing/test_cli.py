"""``dva wing``: JSON on stdout, one-line errors, PNG plots."""
from __future__ import annotations

import json

import pytest
import yaml

from dva_offline.cli import main

HP_SECTION = dict(semichord=1.0, mass_ratio=20.0, radius_of_gyration_sq=0.24,
                  frequency_ratio=0.4, static_unbalance=0.1, elastic_axis=-0.2,
                  pitch_frequency=1.0, air_density=1.0)


def run(capsys, *argv):
    code = main(["wing", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_flutter_json_reference_wing(capsys):
    code, out, _ = run(capsys, "flutter", "--json", "--absorber", "none")
    assert code == 0
    data = json.loads(out)
    assert data["critical_airspeed"] == pytest.approx(100.0, rel=0.05)
    assert data["flutter_frequency"] > 0 and data["kind"] == "flutter"


def test_flutter_json_typical_section_theodorsen(capsys, tmp_path):
    path = tmp_path / "hp.yaml"
    path.write_text(yaml.safe_dump(HP_SECTION))
    code, out, _ = run(capsys, "flutter", "--json", "--section", str(path), "--aero",
                       "theodorsen")
    assert code == 0
    data = json.loads(out)
    assert data["critical_airspeed"] == pytest.approx(2.17, rel=0.02)  # Hodges & Pierce


def test_flutter_with_si_absorbers_and_tuning(capsys):
    code, out, _ = run(capsys, "flutter", "--json", "--absorber", "passive", "--k1", "91560",
                       "--c1", "860")
    passive = json.loads(out)
    assert code == 0 and passive["absorber"]["position"] > 1.0
    code, out, _ = run(capsys, "flutter", "--json", "--absorber", "maxwell", "--k1", "90000",
                       "--k2", "70000", "--tune", "--c-max", "1200")
    tuned = json.loads(out)
    assert code == 0 and tuned["tuned"] and tuned["ratio"] > 1.0
    assert 0 < tuned["tuned_setting"]["damping"] <= 1200


def test_absorber_options_change_the_wing_files_absorber(capsys):
    """``--c2`` alone changes the file's Maxwell absorber: the same answer as the whole absorber
    given with that c2, and not the default c2's."""
    def flutter(*argv):
        code, out, _ = run(capsys, "flutter", "--json", *argv)
        assert code == 0
        return json.loads(out)

    default = flutter()
    alone = flutter("--c2", "624.7")
    whole = flutter("--absorber", "maxwell", "--m1", "40", "--k1", "90000", "--k2", "70000",
                    "--position", "1.53", "--c2", "624.7")
    assert alone["absorber"]["damping"] == 624.7
    assert alone["critical_airspeed"] == pytest.approx(whole["critical_airspeed"], rel=1e-12)
    assert round(alone["critical_airspeed"], 3) == 115.048
    assert abs(alone["critical_airspeed"] - default["critical_airspeed"]) > 1.0


@pytest.mark.parametrize("argv,match", [
    (["flutter", "--c1", "5"], "--c1 does not apply to the wing file's maxwell absorber"),
    (["flutter", "--tune", "--c2", "5"], "--c2 and --tune"),
    (["flutter", "--c-max", "3"], "--c-max bounds the tuned damper"),
    (["flutter", "--absorber", "none", "--k1", "4"], "--k1 sets an absorber"),
    (["flutter", "--absorber", "passive", "--k1", "1e5", "--c1", "3", "--k2", "4"],
     "--k2 does not apply to --absorber passive"),
    (["flutter", "--absorber", "maxwell", "--k1", "1e5", "--k2", "1e5", "--c2", "9",
      "--c1", "3"], "--c1 does not apply to --absorber maxwell"),
    (["modal", "--absorber", "passive", "--k1", "1e5", "--c1", "3", "--tune", "--c1", "4"],
     "--k1 and --tune"),
])
def test_unused_absorber_options_are_refused(capsys, argv, match):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert match in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("argv,match", [
    (["flutter", "--absorber", "passive", "--k1", "1e5"], "--c1"),
    (["flutter", "--absorber", "passive", "--k1", "1e5", "--c1", "10", "--position", "5"],
     "outside the chord"),
    (["flutter", "--absorber", "passive", "--m1", "-3", "--k1", "1e5", "--c1", "10"], "mass"),
    (["flutter", "--density", "nan"], "density"),
    (["flutter", "--wing", "/nonexistent/wing.yaml"], "wing.yaml"),
    (["simulate", "--flights", "0"], "flights"),
])
def test_bad_inputs_are_one_line_errors(capsys, argv, match):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert match in err and len(err.strip().splitlines()) == 1


def test_modal_plot_and_json(capsys, tmp_path):
    png = tmp_path / "modal.png"
    code, out, _ = run(capsys, "modal", "--json", "--points", "61", "--absorber", "none",
                       "--plot", str(png))
    data = json.loads(out)
    assert code == 0 and png.stat().st_size > 1000
    assert len(data["modes"]) == 2 and len(data["airspeed"]) == 61


def test_simulate_short_ramp(capsys, tmp_path):
    png = tmp_path / "flight.png"
    code, out, err = run(capsys, "simulate", "--json", "--duration", "6", "--absorber", "none",
                         "--flights", "2", "--seed", "3", "--plot", str(png))
    data = json.loads(out)
    assert code == 0 and png.stat().st_size > 1000
    assert len(data["divergence_airspeed"]) == 2
    assert data["critical_airspeed"] == pytest.approx(100.0, rel=0.05)
