"""Noise measured by the test itself: replicate sweeps and an analyzer's coherence, and the
CLI saying which estimate the verdict used."""
import json

import numpy as np
import pytest

from dva_offline import cli
from dva_offline.discrepancy.fitting import Observations
from dva_offline.discrepancy.noise_sources import (
    coherence_noise,
    replicate_noise,
    replicate_sets,
)


def _obs(levels, sigma, rng, lines=200):
    f = np.linspace(10.0, 100.0, lines)
    h = 1.0 / (1 - (f / 50.0) ** 2 + 0.05j * f / 50.0)
    ys, gs, cs = [], [], []
    for g, level in enumerate(levels):
        e = rng.standard_normal(lines) + 1j * rng.standard_normal(lines)
        ys.append(h * (1 + sigma / np.sqrt(2) * e))
        gs.append(np.full(lines, g))
        cs.append(np.full(lines, level))
    y = np.concatenate(ys)
    return Observations(y, 1 / np.abs(y), np.tile(f, len(levels)), np.concatenate(gs),
                        {"temperature_c": np.concatenate(cs)})


def test_replicates_give_the_noise_of_one_sweep():
    rng = np.random.default_rng(3)
    obs = _obs([20.0, 20.0, 20.0, 20.0, 40.0, 40.0], 0.02, rng)
    assert replicate_sets(obs) == [[0, 1, 2, 3], [4, 5]]
    est = replicate_noise(obs)
    assert est.sigma == pytest.approx(0.02, rel=0.1)
    assert est.method.startswith("replicates")


def test_sweeps_at_different_levels_are_no_replicates():
    obs = _obs([20.0, 30.0, 40.0], 0.02, np.random.default_rng(4))
    assert replicate_sets(obs) == [] and replicate_noise(obs) is None


def test_coherence_needs_the_number_of_averages():
    g2 = np.full(50, 0.9)
    est, note = coherence_noise(g2, 10)
    assert est.sigma == pytest.approx(np.sqrt(0.1 / 0.9 / 10)) and note == ""
    est, note = coherence_noise(g2, None)
    assert est is None and "averages" in note
    est, note = coherence_noise(np.full(5, 1.5), 10)
    assert est is None and "not usable" in note


def _write(path, rows, header):
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:.10g}" for v in r) for r in rows))


def _one_mode_rows(rng, sigma, sets, extra=None):
    f = np.linspace(20.0, 80.0, 61)
    w = 2 * np.pi * f
    h = 1.0 / ((2 * np.pi * 50) ** 2 - w**2 + 2j * 0.03 * 2 * np.pi * 50 * w)
    rows = []
    for s, level in sets:
        e = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
        y = h * (1 + sigma / np.sqrt(2) * e)
        for i in range(f.size):
            rows.append([f[i], y[i].real, y[i].imag, level, s] + ([extra] if extra else []))
    return rows


def test_cli_uses_replicates_and_says_so(tmp_path, capsys):
    path = tmp_path / "rep.csv"
    _write(path, _one_mode_rows(np.random.default_rng(6), 0.01,
                                [(1, 5.0), (2, 5.0), (3, 5.0)]),
           "frequency_hz,real,imag,force_n,sweep")
    assert cli.main(["discrepancy", "modal", str(path), "--quantity", "receptance", "--group-by",
                     "sweep", "--max-steps", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["noise_floor"]["method"].startswith("replicates")
    assert out["noise_estimates"]["replicates"] == pytest.approx(0.01, rel=0.25)
    assert out["verdict"]["status"] == "consistent"


def test_cli_coherence_column_with_and_without_averages(tmp_path, capsys):
    path = tmp_path / "coh.csv"
    _write(path, _one_mode_rows(np.random.default_rng(7), 0.01, [(1, 5.0), (2, 10.0)],
                                extra=0.95),
           "frequency_hz,real,imag,force_n,sweep,Coh")
    args = ["discrepancy", "modal", str(path), "--quantity", "receptance", "--group-by", "sweep",
            "--columns", "coherence=Coh", "--max-steps", "1", "--json"]
    assert cli.main([*args, "--averages", "20"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["noise_floor"]["method"].startswith("coherence")
    assert out["noise_floor"]["sigma"] == pytest.approx(np.sqrt(0.05 / 0.95 / 20))
    assert "coherence" not in json.dumps(out["candidates"])  # not analysed as a covariate
    assert cli.main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["noise_floor"]["method"].startswith("1.4826 MAD")
    assert any("averages" in n for n in out["noise_estimates"]["notes"])
    assert cli.main([*args, "--averages", "0"]) == 2
    assert "--averages" in capsys.readouterr().err


def test_sweeps_whose_covariates_differ_by_their_scatter_are_replicates():
    """Two sweeps at one nominal temperature and strain: the measured values drift within
    each sweep (range 0.02 K, 0.01 %) and their means differ by less than that."""
    from dva_offline.discrepancy.noise_sources import sweep_replicates

    rng = np.random.default_rng(1)
    f0 = np.geomspace(0.01, 1.0, 12)
    f = [f0, np.r_[f0, 1.5, 4.6, 21.5]]

    def sweep(t, strain, n):
        return {"temperature_c": t + 0.01 * rng.uniform(-1, 1, n),
                "strain": strain + 0.005 * rng.uniform(-1, 1, n)}

    covs = [sweep(30.0, 2.0, 12), sweep(30.004, 2.003, 15)]
    assert sweep_replicates(covs, f) == [[0, 1]]
    # 1 K apart: another condition (the old rule, 1 % of the file's spread, said the same
    # sweeps were never replicates: the spread was the difference itself)
    covs[1]["temperature_c"] = covs[1]["temperature_c"] + 1.0
    assert sweep_replicates(covs, f) == []
    # the user says it outright
    assert sweep_replicates(covs, f, declared=[30.0, 30.0]) == [[0, 1]]
    # sweeps that share fewer than 5 lines give no scatter
    assert sweep_replicates(covs, [f[0][:6], f[0][3:]], declared=[30.0, 30.0]) == []


def test_replicate_noise_on_the_lines_the_sweeps_share():
    rng = np.random.default_rng(2)
    f1, f2 = np.linspace(10.0, 60.0, 51), np.linspace(30.0, 100.0, 71)

    def h(f):
        return 1.0 / (1 - (f / 50.0) ** 2 + 0.05j * f / 50.0)

    y = [h(f) * (1 + 0.01 / np.sqrt(2) * (rng.standard_normal(f.size)
                                          + 1j * rng.standard_normal(f.size))) for f in (f1, f2)]
    obs = Observations(np.concatenate(y), 1 / np.abs(np.concatenate(y)), np.r_[f1, f2],
                       np.repeat([0, 1], [f1.size, f2.size]),
                       {"temperature_c": np.repeat([20.0, 20.0], [f1.size, f2.size])})
    est = replicate_noise(obs)
    assert est.sigma == pytest.approx(0.01, rel=0.3) and "share" in est.method
    assert est.n_differences == 31  # the 31 lines of 30-60 Hz


def test_cli_repeated_sweeps_with_drifting_covariates(tmp_path, capsys):
    """Three sweeps of one condition whose measured force drifts within each sweep: they are
    replicates, their scatter is the noise, the report gives the second-difference estimate
    beside it, and no covariate is analysed (one condition)."""
    rng = np.random.default_rng(8)
    rows = _one_mode_rows(rng, 0.01, [(1, 5.0), (2, 5.0), (3, 5.0)])
    for r in rows:
        r[3] += 0.02 * rng.uniform(-1, 1) + 0.005 * r[4]  # drift 0.04 N, means 0.015 N apart
    path = tmp_path / "rep.csv"
    _write(path, rows, "frequency_hz,real,imag,force_n,sweep")
    assert cli.main(["discrepancy", "modal", str(path), "--quantity", "receptance",
                     "--group-by", "sweep", "--max-steps", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    est = out["noise_estimates"]
    assert out["noise_floor"]["method"].startswith("replicates")
    assert est["replicate_sets"] == [[0, 1, 2]] and "scatter" in est["replicates_found_by"]
    assert est["replicates"] == pytest.approx(0.01, rel=0.25)
    assert est["second_differences"] > 0
    assert out["verdict"]["status"] in ("consistent", "no_covariate_effect")
    assert not any(c["applicable"] for c in out["candidates"]
                   if c["effect"] in ("amplitude_dependence", "covariate_shift"))
    # the same sweeps declared by a column of their nominal force
    rows = [r + [5.0] for r in rows]
    _write(path, rows, "frequency_hz,real,imag,force_n,sweep,nominal_n")
    assert cli.main(["discrepancy", "modal", str(path), "--quantity", "receptance",
                     "--group-by", "sweep", "--replicates", "nominal_n", "--max-steps", "1",
                     "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["noise_estimates"]["replicates_found_by"] == "declared by --replicates nominal_n"
    assert cli.main(["discrepancy", "modal", str(path), "--quantity", "receptance",
                     "--group-by", "sweep", "--replicates", "nope"]) == 2
    assert "--replicates column 'nope' not found" in capsys.readouterr().err


def test_sweeps_whose_difference_is_smooth_are_no_replicates():
    """Two force-controlled sweeps whose force swings through the resonance by more than the
    levels differ (the jointed beam's force control: 0.80-1.17 N and 1.08-1.72 N): the
    covariate test alone takes them for replicates; their difference is a resonance that
    moved, smooth along the band, not noise, so they are not, and the note says why."""
    from dva_offline.discrepancy.noise_sources import sweep_replicates, white_difference

    rng = np.random.default_rng(5)
    f = np.linspace(79.2, 81.2, 41)

    def sweep(fr, force):
        h = 1.0 / (fr**2 - f**2 + 2j * 0.002 * fr * f)
        v = h * (1 + 0.005 / np.sqrt(2) * (rng.standard_normal(f.size)
                                           + 1j * rng.standard_normal(f.size)))
        return v, {"force_n": force * (1 - 0.35 * np.abs(h) / np.abs(h).max())}

    (v1, c1), (v2, c2) = sweep(80.3, 1.15), sweep(80.2, 1.7)
    assert abs(np.mean(c1["force_n"]) - np.mean(c2["force_n"])) < np.ptp(c2["force_n"])
    assert sweep_replicates([c1, c2], [f, f]) == [[0, 1]]  # the covariates alone
    notes = []
    assert sweep_replicates([c1, c2], [f, f], values=[v1, v2], notes=notes) == []
    assert "difference is no noise" in notes[0]
    eta, p = white_difference([v1, v2], [f, f])
    assert eta < 0.5 and p < 0.001
    # two true replicates of the same sweep: white, kept
    (w1, d1), (w2, d2) = sweep(80.3, 1.15), sweep(80.3, 1.15)
    eta, p = white_difference([w1, w2], [f, f])
    assert 1.4 < eta < 2.6 and p > 0.01
    assert sweep_replicates([d1, d2], [f, f], values=[w1, w2]) == [[0, 1]]
    # the user's word stands
    assert sweep_replicates([c1, c2], [f, f], declared=[1.0, 1.0], values=[v1, v2]) == [[0, 1]]
