"""Stepped-sine files (section 5.2), complex modulus input, and the optional UFF reader."""
import json
import sys

import numpy as np
import pytest

from dva_offline import cli
from dva_offline.isolator import files as isolator_files
from dva_offline.isolator.frf_data import (
    FrfData,
    estimate_modal,
    frf_from_amplitude_phase,
    geometry_factor,
    modulus_to_stiffness,
    stiffness_to_modulus,
    to_receptance,
)
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties

KN = 1e3
# Table 5.4 bubble-mount M-V model with the measured mass 1.041 kg (section 5.2).
BUBBLE = MaxwellModel(1.041, 14.01 * KN, 25.81, (22.27 * KN,), (1588.57,))
SYSTEM_F = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 24 * KN), (80.0, 2000.0))
STUDY_STEPS_HZ = np.arange(3.0, 80.0 + 0.25, 0.5)  # section 5.2: 0.5 Hz steps, 3-80 Hz


def run(capsys, *argv):
    code = cli.main(["isolator", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def write_steps(path, model, quantity="accelerance", f=STUDY_STEPS_HZ, seed=0, extra=None):
    """Steps of a known model with random force amplitudes (10-50 N) and phases."""
    rng = np.random.default_rng(seed)
    force = rng.uniform(10, 50, f.size) * np.exp(1j * rng.uniform(-np.pi, np.pi, f.size))
    h = frf(model, 2 * np.pi * f, quantity)
    isolator_files.write_stepped_sine_csv(path, f, force, h * force, extra)
    return h


def test_amplitude_phase_steps_read_back_as_the_model_frf(tmp_path):
    path = tmp_path / "steps.csv"
    h = write_steps(path, BUBBLE, extra={"temperature_c": np.full(STUDY_STEPS_HZ.size, 23.0)})
    data = isolator_files.read_stepped_sine_csv(path, "accelerance")
    np.testing.assert_allclose(data.values, h, rtol=1e-12)
    assert data.quantity == "accelerance"
    assert list(data.covariates) == ["temperature_c"]
    # Radian phase columns are read as radians.
    text = path.read_text().splitlines()
    header = text[0].replace("_phase_deg", "_phase_rad")
    rows = []
    for line in text[1:]:
        v = [float(x) for x in line.split(",")]
        v[2], v[4] = np.radians(v[2]), np.radians(v[4])
        rows.append(",".join(repr(float(x)) for x in v))
    rad = tmp_path / "rad.csv"
    rad.write_text("\n".join([header, *rows]) + "\n")
    np.testing.assert_allclose(isolator_files.read_stepped_sine_csv(rad, "accelerance").values, h,
                               rtol=1e-12)


def test_frf_from_amplitude_phase_convention():
    # force 2 cos(wt), response 6 cos(wt - 90 deg): H = 3 exp(-j pi/2)
    h = frf_from_amplitude_phase([2.0], [0.0], [6.0], [-np.pi / 2])
    np.testing.assert_allclose(h, [-3j], atol=1e-15)
    with pytest.raises(ValueError, match="force amplitude must be > 0"):
        frf_from_amplitude_phase([0.0], [0.0], [6.0], [0.0])


def test_zero_crossing_and_half_power_of_steps_of_a_voigt_model():
    """For a Voigt model Re(receptance) = 0 exactly at sqrt(k/m); half power gives zeta to
    O(zeta^2) and the step size."""
    model = MaxwellModel(1.0, 36.46 * KN, 6.0)
    f = np.arange(20.0, 40.0, 0.05)
    w = 2 * np.pi * f
    est = estimate_modal(w, frf(model, w))
    assert est.natural_frequency_rad_s == pytest.approx(np.sqrt(36.46 * KN), rel=1e-5)
    assert est.damping_ratio == pytest.approx(modal_properties(model).damping_ratio, rel=0.01)
    assert est.half_power_lower_rad_s < est.peak_rad_s < est.half_power_upper_rad_s


def test_stepped_sine_cli_reproduces_table_5_2_bubble_mount(capsys, tmp_path):
    """Steps of the study's bubble-mount model on the study's grid give Table 5.2's
    187.15 rad/s (to 0.5 %) and zeta 0.09 (to its 2 printed decimals)."""
    path = tmp_path / "bubble_steps.csv"
    write_steps(path, BUBBLE)
    out_csv, png = tmp_path / "frf.csv", tmp_path / "steps.png"
    code, out, err = run(capsys, "stepped-sine", path, "--quantity", "accelerance",
                         "--out", out_csv, "--plot", png, "--json")
    assert code == 0, err
    payload = json.loads(out)
    assert payload["n_steps"] == STUDY_STEPS_HZ.size
    assert payload["natural_frequency_rad_s"] == pytest.approx(187.15, rel=0.005)
    assert round(payload["damping_ratio"], 2) == 0.09
    assert payload["half_power_lower_hz"] < payload["peak_hz"] < payload["half_power_upper_hz"]
    assert payload["warnings"] == []
    written = isolator_files.read_frf_csv(out_csv, "accelerance")
    np.testing.assert_allclose(written.values, frf(BUBBLE, 2 * np.pi * STUDY_STEPS_HZ,
                                                   "accelerance"), rtol=1e-9)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The same file feeds identification directly. With --modal-estimate half-power it imposes
    # the Table 5.2 estimates; by default w_n and zeta come from the unconstrained fit, which
    # recovers the model's own eigenvalue (187.133 rad/s, 0.0893) from noise-free steps.
    common = ["identify", path, "--format", "stepped-sine", "--quantity", "accelerance",
              "--mass", 1.041, "--static-stiffness", 14010, "--elements", 1, "--json"]
    code, out, err = run(capsys, *common, "--modal-estimate", "half-power")
    assert code == 0, err
    fit = json.loads(out)
    assert fit["natural_frequency_rad_s"] == pytest.approx(payload["natural_frequency_rad_s"])
    assert fit["elements"][0]["k"] == pytest.approx(22.27 * KN, rel=0.03)
    code, out, err = run(capsys, *common)
    assert code == 0, err
    fit = json.loads(out)
    assert fit["natural_frequency_rad_s"] == pytest.approx(187.133, abs=0.001)
    assert fit["damping_ratio"] == pytest.approx(0.0893, abs=0.00005)
    assert fit["elements"][0]["k"] == pytest.approx(22.27 * KN, rel=1e-4)


def test_stepped_sine_coarse_steps_warn(capsys, tmp_path):
    path = tmp_path / "coarse.csv"
    write_steps(path, BUBBLE, f=np.arange(3.0, 80.0, 4.0))
    code, out, err = run(capsys, "stepped-sine", path, "--quantity", "accelerance", "--json")
    assert code == 0, err
    assert "between the half-power points" in json.loads(out)["warnings"][0]


STEP_HEADER = ("frequency_hz,force_amplitude_n,force_phase_deg,response_amplitude,"
               "response_phase_deg")


def _steps(n=20, bad=None):
    rows = [[3.0 + i, 10.0, 0.0, 1e-3, -10.0] for i in range(n)]
    if bad:
        bad(rows)
    return STEP_HEADER + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows)


@pytest.mark.parametrize(
    "content, message",
    [
        ("frequency_hz,force_amplitude_n,response_amplitude\n3,1,1\n",
         "missing ['force_phase_deg', 'response_phase_deg']"),
        ("force_amplitude_n\n1\n", "missing column(s) ['frequency_hz']"),
        (_steps(bad=lambda r: r[4].__setitem__(1, 0.0)), "'force_amplitude_n' must be > 0, "
                                                         "got 0 at line 6"),
        (_steps(bad=lambda r: r[2].__setitem__(4, "nan")), "'response_phase_deg' is NaN at "
                                                           "line 4"),
        (_steps(bad=lambda r: r[9].__setitem__(0, 4.0)), "strictly increasing"),
        (_steps(n=6), "too few frequency points: 6"),
        (STEP_HEADER + ",force_phase_rad\n" + "3,1,0,1,0,0\n", "not both"),
    ],
)
def test_bad_stepped_sine_files(capsys, tmp_path, content, message):
    path = tmp_path / "bad_steps.csv"
    path.write_text(content)
    code, out, err = run(capsys, "stepped-sine", path, "--quantity", "accelerance")
    assert code == 2 and out == ""
    assert message in err and "bad_steps.csv" in err, err
    assert len(err.strip().splitlines()) == 1


def test_amplitude_phase_steps_need_a_motion_quantity(capsys, tmp_path):
    path = tmp_path / "steps.csv"
    path.write_text(_steps())
    code, _, err = run(capsys, "stepped-sine", path, "--quantity", "stiffness", "--mass", 1)
    assert code == 2 and "use --quantity receptance" in err


def test_no_resonance_in_the_steps_is_a_clear_error(capsys, tmp_path):
    path = tmp_path / "low.csv"
    write_steps(path, BUBBLE, f=np.arange(3.0, 15.0, 0.5))
    code, _, err = run(capsys, "stepped-sine", path, "--quantity", "accelerance")
    assert code == 2 and "no natural frequency" in err and "low.csv" in err
    # A resonance whose peak sits at the first step has a zero crossing but no half power.
    write_steps(path, BUBBLE, f=np.arange(29.5, 80.0, 0.5))
    code, _, err = run(capsys, "stepped-sine", path, "--quantity", "accelerance")
    assert code == 2 and "no half-power damping" in err, err


# --- complex modulus (dynamic mechanical analysis) -------------------------------------------

def test_geometry_factor_and_modulus_round_trip():
    assert geometry_factor(4e-4, 0.02) == pytest.approx(0.02)
    assert geometry_factor(geometry_factor_m=0.05) == 0.05
    f = np.linspace(1.0, 60.0, 40)
    k_star = frf(SYSTEM_F, 2 * np.pi * f, "stiffness")
    factor = geometry_factor(4e-4, 0.02)
    e_star = stiffness_to_modulus(k_star, factor)  # [Pa]
    back = modulus_to_stiffness(FrfData(f, e_star, "stiffness"), factor)
    np.testing.assert_allclose(back.values, k_star, rtol=1e-14)
    np.testing.assert_allclose(stiffness_to_modulus(back.values, factor), e_star, rtol=1e-14)
    for kwargs, message in [
        ({}, "needs the specimen geometry"),
        ({"area_m2": 4e-4}, "needs the specimen geometry"),
        ({"area_m2": 4e-4, "thickness_m": 0.02, "geometry_factor_m": 0.02}, "not both"),
        ({"area_m2": -1.0, "thickness_m": 0.02}, "area must be > 0"),
        ({"area_m2": 4e-4, "thickness_m": 0.0}, "thickness must be > 0"),
        ({"geometry_factor_m": float("nan")}, "geometry factor"),
    ]:
        with pytest.raises(ValueError, match=message):
            geometry_factor(**kwargs)


def test_identify_from_modulus_matches_identify_from_stiffness(capsys, tmp_path):
    f = np.linspace(0.5, 60.0, 120)
    k_star = frf(SYSTEM_F, 2 * np.pi * f, "stiffness")
    area, thickness = 4e-4, 0.02  # 20 mm x 20 mm x 20 mm block: A/h = 0.02 m
    isolator_files.write_frf_csv(tmp_path / "dma.csv", f, k_star / (area / thickness))
    isolator_files.write_frf_csv(tmp_path / "k.csv", f, k_star)
    modal = modal_properties(SYSTEM_F)
    common = ["--mass", 1, "--static-stiffness", 12000, "--elements", 2,
              "--natural-frequency-rad-s", modal.natural_frequency_rad_s,
              "--damping-ratio", modal.damping_ratio, "--json"]
    code, out, err = run(capsys, "identify", tmp_path / "dma.csv", "--quantity", "modulus",
                         "--area", area, "--thickness", thickness, *common)
    assert code == 0, err
    from_modulus = json.loads(out)
    code, out, err = run(capsys, "identify", tmp_path / "k.csv", "--quantity", "stiffness",
                         *common)
    assert code == 0, err
    from_stiffness = json.loads(out)
    assert from_modulus["geometry_factor_m"] == pytest.approx(0.02)
    assert from_modulus["c"] == pytest.approx(40.0, rel=1e-4)
    assert from_modulus["c"] == pytest.approx(from_stiffness["c"], rel=1e-9)
    for a, b in zip(from_modulus["elements"], from_stiffness["elements"]):
        assert a["k"] == pytest.approx(b["k"], rel=1e-9)
        assert a["c"] == pytest.approx(b["c"], rel=1e-9)
    # Modulus in MPa where Pa was expected: the unit check says what to look at.
    isolator_files.write_frf_csv(tmp_path / "mpa.csv", f, k_star / (area / thickness) / 1e6)
    code, _, err = run(capsys, "identify", tmp_path / "mpa.csv", "--quantity", "modulus",
                       "--geometry-factor", 0.02, *common[:-1])
    assert code == 2 and "Pa vs MPa" in err
    code, _, err = run(capsys, "identify", tmp_path / "dma.csv", "--quantity", "modulus",
                       *common[:-1])
    assert code == 2 and "--geometry-factor" in err
    code, _, err = run(capsys, "identify", tmp_path / "k.csv", "--quantity", "stiffness",
                       "--area", area, *common[:-1])
    assert code == 2 and "only to --quantity modulus" in err


def test_to_receptance_needs_mass_only_for_stiffness():
    f = np.linspace(1.0, 60.0, 40)
    acc = FrfData(f, frf(BUBBLE, 2 * np.pi * f, "accelerance"), "accelerance")
    np.testing.assert_allclose(to_receptance(acc, None)[1], frf(BUBBLE, 2 * np.pi * f),
                               rtol=1e-12)
    stiff = FrfData(f, frf(BUBBLE, 2 * np.pi * f, "stiffness"), "stiffness")
    with pytest.raises(ValueError, match="needs the mass"):
        to_receptance(stiff, None)


# --- optional UFF reader ----------------------------------------------------------------------

def test_uff_without_pyuff_says_how_to_install(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)  # makes `import pyuff` raise ImportError
    path = tmp_path / "frf.uff"
    path.write_text("    -1\n")
    with pytest.raises(ValueError, match=r"pip install 'dva-offline\[uff\]'"):
        isolator_files.read_uff58(path, "accelerance")
    code, _, err = run(capsys, "identify", path, "--mass", 1, "--static-stiffness", 12000)
    assert code == 2 and "pyuff" in err and len(err.strip().splitlines()) == 1
