"""``dva isolator`` CLI and file formats, including clear errors for bad files."""
import json

import numpy as np
import pytest

from dva_offline import cli
from dva_offline.isolator import files as isolator_files
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties

KN = 1e3
SYSTEM_F = MaxwellModel(1.0, 12 * KN, 40.0, (12 * KN, 24 * KN), (80.0, 2000.0))


def run(capsys, *argv):
    code = cli.main(["isolator", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def write_frf(path, model, quantity="receptance", f=None, extra=None):
    f = np.linspace(0.5, 50.0, 200) if f is None else f
    h = frf(model, 2 * np.pi * f, quantity)
    isolator_files.write_frf_csv(path, f, h, extra)
    return f, h


def test_modal_json_table_4_1_f(capsys):
    code, out, _ = run(capsys, "modal", "--mass", 1, "--k", 12000, "--c", 40,
                       "--maxwell", "12000,80", "--maxwell", "24000,2000", "--json")
    assert code == 0
    payload = json.loads(out)
    assert payload["natural_frequency_rad_s"] == pytest.approx(214.806, abs=0.0005)
    assert payload["damping_ratio"] == pytest.approx(0.1815, abs=0.0005)
    assert payload["element_types"] == ["B", "C"]
    assert payload["static_stiffness_n_per_m"] == 12000


def test_identify_json_with_covariates_and_plot(capsys, tmp_path):
    path = tmp_path / "f.csv"
    f = np.linspace(0.5, 50.0, 200)
    write_frf(path, SYSTEM_F, f=f, extra={"temperature_c": np.full(f.size, 23.0)})
    modal = modal_properties(SYSTEM_F)
    png = tmp_path / "fit.png"
    code, out, err = run(
        capsys, "identify", path, "--mass", 1, "--static-stiffness", 12000, "--elements", 2,
        "--natural-frequency-rad-s", modal.natural_frequency_rad_s,
        "--damping-ratio", modal.damping_ratio, "--plot", png, "--json",
    )
    assert code == 0, err
    payload = json.loads(out)
    assert payload["c"] == pytest.approx(40.0, rel=1e-4)
    assert [e["type"] for e in payload["elements"]] == ["B", "C"]
    assert payload["elements"][1]["c"] == pytest.approx(2000.0, rel=1e-4)
    assert payload["natural_frequency_rad_s"] == pytest.approx(modal.natural_frequency_rad_s)
    assert payload["frf_error"] < 1e-6
    assert payload["covariates"] == ["temperature_c"]
    assert png.stat().st_size > 1000


def test_identify_auto_estimates_modal_values_and_selects_order(capsys, tmp_path):
    path = tmp_path / "acc.csv"
    model = MaxwellModel(1.041, 14.01 * KN, 25.81, (22.27 * KN,), (1588.57,))
    write_frf(path, model, "accelerance", f=np.arange(3.0, 80.0, 0.5))
    code, out, err = run(capsys, "identify", path, "--quantity", "accelerance", "--mass", 1.041,
                         "--static-stiffness", 14010, "--elements", "auto", "--json")
    assert code == 0, err
    payload = json.loads(out)
    assert payload["order_selection"]["selected_order"] >= 1
    assert payload["natural_frequency_rad_s"] == pytest.approx(187.15, rel=0.01)
    # w_n and zeta come from the zero crossing / half power of the data, which are only
    # approximations for an M-V model; constraining to them costs a few % of FRF error.
    assert payload["frf_error"] < 0.05


@pytest.mark.parametrize(
    "content, message",
    [
        ("frequency_hz,real\n1,2\n", "missing column"),
        ("frequency_hz,real,imag\n" + "".join(f"{i},1e-4,0\n" for i in range(1, 5)),
         "too few frequency points"),
        ("frequency_hz,real,imag\n" + "".join(f"{i},1e-4,0\n" for i in range(1, 20))
         + "3,1e-4,0\n", "strictly increasing"),
        ("frequency_hz,real,imag\n" + "".join(f"{i},1e-4,0\n" for i in range(1, 20))
         + "25,nan,0\n", "NaN at line 21"),
        ("frequency_hz,real,imag\n1,abc,0\n", "not a number"),
    ],
)
def test_identify_bad_files_give_one_line_errors(capsys, tmp_path, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    code, out, err = run(capsys, "identify", path, "--mass", 1, "--static-stiffness", 12000)
    assert code == 2
    assert out == ""
    assert message in err and "bad.csv" in err
    assert len(err.strip().splitlines()) == 1


def test_identify_units_off_by_1000(capsys, tmp_path):
    path = tmp_path / "f.csv"
    write_frf(path, SYSTEM_F)
    code, _, err = run(capsys, "identify", path, "--mass", 1, "--static-stiffness", 12,
                       "--natural-frequency-rad-s", 214.8, "--damping-ratio", 0.18)
    assert code == 2 and "kN/m" in err
    mm_path = tmp_path / "mm.csv"
    f = np.linspace(0.5, 50.0, 200)
    isolator_files.write_frf_csv(mm_path, f, 1000 * frf(SYSTEM_F, 2 * np.pi * f))
    code, _, err = run(capsys, "identify", mm_path, "--mass", 1, "--static-stiffness", 12000,
                       "--natural-frequency-rad-s", 214.8, "--damping-ratio", 0.18)
    assert code == 2 and "off by ~1000" in err
    stiff = tmp_path / "kn.csv"
    isolator_files.write_frf_csv(stiff, f, frf(SYSTEM_F, 2 * np.pi * f, "stiffness") / 1000)
    code, _, err = run(capsys, "identify", stiff, "--quantity", "stiffness", "--mass", 1,
                       "--static-stiffness", 12000, "--natural-frequency-rad-s", 214.8,
                       "--damping-ratio", 0.18)
    assert code == 2 and "off by ~1000" in err


def test_missing_file_is_reported(capsys, tmp_path):
    code, _, err = run(capsys, "identify", tmp_path / "nope.csv", "--mass", 1,
                       "--static-stiffness", 12000)
    assert code == 2 and "no such file" in err


def test_estimate_time_series_to_frf_csv(capsys, tmp_path):
    fs = 1000.0
    rng = np.random.default_rng(0)
    force = rng.standard_normal(8000)
    # A pure gain "system" keeps the test independent of the model code (H = 2 exactly).
    resp = 2.0 * force
    t = np.arange(force.size) / fs
    src = tmp_path / "ts.csv"
    src.write_text("time_s,force_n,acc_1\n" + "".join(
        f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t, force, resp)))
    out_csv = tmp_path / "frf.csv"
    code, out, err = run(capsys, "estimate", src, "--out", out_csv, "--nfft", 1000, "--json")
    assert code == 0, err
    payload = json.loads(out)
    assert payload["fs_hz"] == pytest.approx(fs)
    data = isolator_files.read_frf_csv(out_csv, "accelerance")
    np.testing.assert_allclose(data.values, 2.0, rtol=1e-9)
    np.testing.assert_allclose(data.covariates["coherence"], 1.0, rtol=1e-9)
    assert data.frequency_hz[0] == pytest.approx(1.0)  # fs / nfft, 0 Hz dropped
    bad = tmp_path / "bad_ts.csv"
    bad.write_text("time_s,acc_1\n0,1\n0.001,2\n")
    code, _, err = run(capsys, "estimate", bad, "--out", out_csv)
    assert code == 2 and "force_n" in err


def test_static_subcommand(capsys, tmp_path):
    path = tmp_path / "ld.csv"
    x = np.linspace(0, 1e-3, 11)
    path.write_text("deflection_m,load_n\n" + "".join(f"{a},{23151 * a + 0.2}\n" for a in x))
    code, out, _ = run(capsys, "static", path, "--json")
    assert code == 0
    assert json.loads(out)["static_stiffness_n_per_m"] == pytest.approx(23151, rel=1e-9)


def test_plot_study_writes_figures(capsys, tmp_path):
    code, out, err = run(capsys, "plot", "--study", "--plot-dir", tmp_path, "--json")
    assert code == 0, err
    plots = json.loads(out)["plots"]
    assert len(plots) == 10
    assert any("fig3_05" in p for p in plots) and any("fig3_08" in p for p in plots)


def test_uff58_round_trip(tmp_path):
    pyuff = pytest.importorskip("pyuff")
    f = np.linspace(1.0, 50.0, 100)
    h = frf(SYSTEM_F, 2 * np.pi * f, "accelerance")
    path = tmp_path / "frf.uff"
    ds = pyuff.prepare_58(func_type=4, rsp_node=1, rsp_dir=3, ref_node=1, ref_dir=3,
                          data=h, x=f, id1="accelerance", rsp_ent_name="mass",
                          ref_ent_name="mass", abscissa_spacing=1, ordinate_spec_data_type=12,
                          orddenom_spec_data_type=13)
    pyuff.UFF(str(path)).write_sets(ds, mode="overwrite")
    data = isolator_files.read_uff58(path, "accelerance")
    np.testing.assert_allclose(data.frequency_hz, f, rtol=1e-6)
    np.testing.assert_allclose(data.values, h, rtol=1e-5)


def test_point_selection_by_band_and_coherence(capsys, tmp_path):
    path = tmp_path / "est.csv"
    f = np.arange(0.5, 80.0, 0.5)
    coherence = np.where(f < 5.0, 0.1, 0.99)  # weak low-frequency bins, as a boxcar Welch gives
    h = frf(SYSTEM_F, 2 * np.pi * f, "accelerance")
    h[f < 5.0] *= 3.0  # ... and wrong there
    isolator_files.write_frf_csv(path, f, h, {"coherence": coherence})
    modal = modal_properties(SYSTEM_F)
    common = ["--quantity", "accelerance", "--mass", 1, "--static-stiffness", 12000,
              "--natural-frequency-rad-s", modal.natural_frequency_rad_s,
              "--damping-ratio", modal.damping_ratio, "--json"]
    code, out, err = run(capsys, "identify", path, "--min-coherence", 0.9, "--fmax-hz", 60,
                         *common)
    assert code == 0, err
    assert json.loads(out)["frf_error"] < 1e-6
    code, _, err = run(capsys, "identify", path, "--fmin-hz", 70, "--fmax-hz", 72, *common)
    assert code == 2 and "only 5 of 159 points" in err
    plain = tmp_path / "plain.csv"
    write_frf(plain, SYSTEM_F)
    code, _, err = run(capsys, "identify", plain, "--min-coherence", 0.9, *common[2:])
    assert code == 2 and "needs a 'coherence' column" in err
