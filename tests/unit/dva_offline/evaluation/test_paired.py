"""The paired evaluation: cases, per-flight records, paired intervals, the CLI on a mini run."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from aero_dva import data_files
from aero_dva.control.airspeed_schedule import AirspeedSchedule
from aero_dva.control.rbf_io import save_rbf_network
from aero_dva.control.rbf_network import InputScaling, RBFNetwork, spectrum_input_names
from aero_dva.control.schedule_io import save_schedule
from aero_dva.flight.scenario_io import load_scenario
from dva_offline import cli
from dva_offline.evaluation.closed_loop import FlightOutcome
from dva_offline.evaluation.paired import (
    FlightRecord,
    case_scenario,
    default_cases,
    flight_record,
    paired,
    summarise,
)

BASE = load_scenario(data_files.data_file("scenario_ramp.yaml"))


def test_cases_keep_the_ramp_in_metres_per_second():
    cases = default_cases(8.48)
    assert list(cases) == ["rho0", "x0.9", "x1.1", "slow", "1Hz", "2f"]
    assert cases["2f"].frequency == 17.0 and 1 / cases["slow"].frequency >= 20.0
    flown = case_scenario(BASE, cases["x1.1"], 100.0, 7)
    assert flown.airspeed.values == (80.0, 120.0) and not flown.airspeed.relative
    assert flown.density == pytest.approx(1.32) and flown.seed == 7
    assert flown.duration == BASE.duration and flown.force_std == BASE.force_std
    one_hz = case_scenario(BASE, cases["1Hz"], 100.0, 1)
    assert (one_hz.density, one_hz.density_variation, one_hz.density_frequency) == \
        (1.2, 0.1, 1.0)


def test_paired_interval_is_the_t_interval():
    x = np.array([0.3, -0.1, 0.2, 0.4, 0.1])
    st = paired(x)
    half = stats.t.ppf(0.975, 4) * x.std(ddof=1) / math.sqrt(5)
    assert (st.n, st.mean) == (5, pytest.approx(0.18))
    assert (st.low, st.high) == (pytest.approx(0.18 - half), pytest.approx(0.18 + half))
    assert not st.excludes_zero and paired(x + 1).excludes_zero
    assert paired([np.nan, 1.0]).n == 1 and math.isnan(paired([]).mean)


def _outcome(n=30000, grow_at=25000):
    u = np.linspace(80.0, 120.0, n, endpoint=False)
    le = np.random.default_rng(0).normal(0.0, 1e-3, n)
    le[grow_at:] *= np.exp(3.0 * np.arange(n - grow_at) / 1000.0)
    return FlightOutcome(diverged=False, samples=n, sample_rate=1000.0, airspeed=u,
                         density=np.full(n, 1.2), damping=np.full(n, 600.0), leading_edge=le,
                         peak_activation=np.array([0.5, 0.7, 0.9]))


def test_flight_record_takes_the_rms_over_its_airspeeds_only():
    out = _outcome()
    rec = flight_record("rbf", "rho0", 3, out, 100.0, (80.0, 105.0))
    keep = (out.airspeed <= 105.0) & (np.arange(out.samples) >= 2000)
    assert rec.rms == pytest.approx(np.sqrt(np.mean(out.leading_edge[keep] ** 2)))
    assert 1.13 < rec.divergence_ratio < 1.15 and rec.median_peak_activation == 0.7
    short = FlightOutcome(**{**out.__dict__, "airspeed": out.airspeed[:5000],
                             "leading_edge": out.leading_edge[:5000],
                             "damping": out.damping[:5000], "samples": 5000})
    assert math.isnan(flight_record("rbf", "rho0", 3, short, 100.0, (80.0, 105.0)).rms)


def _rec(controller, seed, div, rms):
    return FlightRecord(controller, "rho0", seed, True, div, rms, 500.0, math.nan)


def test_summary_pairs_each_seed_with_the_fixed_c2():
    records = [_rec("fixed", s, 1.15, 1.0 + 0.1 * s) for s in range(4)]
    records += [_rec("rbf", s, 1.16 + 0.001 * s, (1.0 + 0.1 * s) * 0.99) for s in range(4)]
    rows = {r["controller"]: r for r in summarise(records, ("fixed", "rbf"), ("rho0",))}
    rbf = rows["rbf"]
    assert rbf["mean_rms_ratio"] == pytest.approx(0.99)
    assert rbf["rms_change"].mean == pytest.approx(-0.01) and rbf["rms_change"].n == 4
    # the study-to-seed spread of the RMS cancels in the pairing: an exact ratio, zero width
    assert rbf["rms_change"].high == pytest.approx(-0.01) and rbf["rms_change"].excludes_zero
    assert rbf["divergence_difference"].mean == pytest.approx(0.0115)
    assert rows["fixed"]["rms_change"].mean == 0.0


def _network_file(path):
    names, units = spectrum_input_names()
    scale = np.r_[np.full(32, 1e9), 400.0]
    centre = np.zeros((1, 33))
    centre[0, 32] = 600.0 / 400.0
    net = RBFNetwork(centres=centre, output_weights=np.array([-50.0]), output_bias=600.0,
                     spread=1.0, scaling=InputScaling(np.zeros(33), scale), input_names=names,
                     input_units=units)
    return save_rbf_network(net, path)


def test_cli_mini_evaluation(tmp_path, capsys):
    network = _network_file(tmp_path / "net.npz")
    schedule = save_schedule(AirspeedSchedule(-1060.0, 14.6, (110.0, 115.0), (0.0, 2500.0)),
                             tmp_path / "schedule.json")
    out = tmp_path / "ev"
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "2", "--cases", "rho0,1Hz",
                     "--network", str(network), "--schedule", str(schedule), "--fixed-c2",
                     "625", "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    controllers = ("fixed", "schedule", "rbf", "oracle")
    assert payload["controllers"] == list(controllers) and payload["flights"] == 16
    rows = {(r["controller"], r["case"]): r for r in payload["results"]}
    assert set(rows) == {(c, k) for c in controllers for k in ("rho0", "1Hz")}
    for key, row in rows.items():
        assert row["flights"] == 2 and 1.05 < row["mean_divergence_ratio"] < 1.25
        assert row["mean_rms_ratio"] == (1.0 if key[0] == "fixed" else row["mean_rms_ratio"])
    assert rows[("rbf", "rho0")]["median_peak_activation"] > 0.0
    bounds = payload["boundaries"]
    assert bounds["rho0"]["fixed"]["floquet"] is None
    assert 1.10 < bounds["1Hz"]["fixed"]["floquet"] < bounds["rho0"]["fixed"]["frozen"]
    records = json.loads((out / "records.json").read_text())
    assert len(records) == 16 and {r["seed"] for r in records} == {1, 2}
    by = {(r["controller"], r["case"], r["seed"]): r for r in records}
    rbf = rows[("rbf", "rho0")]
    assert rbf["divergence_to_schedule"]["mean"] == pytest.approx(np.mean(
        [by[("rbf", "rho0", s)]["divergence_ratio"] - by[("schedule", "rho0", s)][
            "divergence_ratio"] for s in (1, 2)]))
    table = (out / "results.md").read_text()
    assert "| rho0 | best fixed c2 |" in table and "Floquet" in table
    assert "RBF network minus airspeed schedule" in table
    for name in ("rms_change.png", "c2_traces.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _mini(tmp_path, out, *extra):
    return ["evaluate", "--out", str(out), "--seeds", "3", "--cases", "rho0,1Hz",
            "--controllers", "fixed,oracle", "--fixed-c2", "625", "--no-boundaries",
            "--json", *extra]


def _records(out):
    return json.loads((out / "records.json").read_text())


# Flights on other processes (forked workers, Ray) run the same arithmetic, but numpy's BLAS
# matrix-vector products take SIMD paths that depend on where an array sits in memory, so a
# state can differ in its last bit between processes; a 30 s flight of this linear model moves
# such a difference by a few hundred ulp at most. 1e-9 relative is far above that and far below
# any difference a wrong flight (another seed, controller or case) makes (1e-3 and more).
RECORD_RTOL = 1e-9


def _assert_same_records(got, expected, route):
    assert len(got) == len(expected), route
    for g, e in zip(got, expected, strict=True):
        assert g.keys() == e.keys(), route
        for key, value in e.items():
            if isinstance(value, float) and not isinstance(value, bool):
                assert g[key] == pytest.approx(value, rel=RECORD_RTOL), (route, key, g, e)
            else:
                assert g[key] == value, (route, key, g, e)


def test_parallel_ray_and_resumed_evaluations_give_the_serial_records(tmp_path, capsys):
    """--workers 2 (forked processes), --ray local and a resumed run fly the same flights as
    the serial run: identical records, in the same order."""
    # (the oracle's table is built in the parent and shipped: test_cli_mini_evaluation flies
    # it; here the fixed damper is enough to show the routes fly the same flights)
    def mini(out, *extra):
        return [a if a != "fixed,oracle" else "fixed" for a in _mini(tmp_path, out, *extra)]

    serial = tmp_path / "serial"
    assert cli.main(mini(serial)) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["flights"] == 6 and first["resumed_jobs"] == 0
    expected = _records(serial)
    for name, extra in (("two", ("--workers", "2")), ("ray", ("--ray", "local", "--workers",
                                                                "2"))):
        assert cli.main(mini(tmp_path / name, *extra)) == 0
        capsys.readouterr()
        _assert_same_records(_records(tmp_path / name), expected, name)
    # Resume: one job's file lost (an interrupted run); only it (and the plotted first seed)
    # is flown again, and the records are the same.
    (serial / "flights" / "1Hz_seed3.json").unlink()
    assert cli.main(mini(serial, "--workers", "2")) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["resumed_jobs"] == 5
    _assert_same_records(_records(serial), expected, "resumed")
    # Other settings in the same directory are refused, not mixed.
    assert cli.main(["evaluate", "--out", str(serial), "--seeds", "3", "--cases", "rho0,1Hz",
                     "--controllers", "fixed", "--fixed-c2", "600",
                     "--no-boundaries"]) == 2
    assert "other settings (fixed_c2)" in capsys.readouterr().err
    _assert_same_records(_records(serial), expected, "refused")
