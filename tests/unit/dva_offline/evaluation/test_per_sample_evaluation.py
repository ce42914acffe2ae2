"""`dva evaluate` with the per-sample laws: one table for every controller, the same flights
(the ramp carried on at its slope, the hold at 1.1 U_cr), the cases a law cannot fly marked."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from aero_dva import data_files
from aero_dva.flight.scenario import airspeed_at
from aero_dva.flight.scenario_io import load_scenario
from dva_offline import cli
from dva_offline.evaluation.paired import (
    HOLD,
    DensityCase,
    _hold_numbers,
    case_scenario,
    flight_record,
)

RHO0 = DensityCase("rho0", 1.0, 0.0, 1.0, "constant rho0")


def test_the_ramp_carried_on_is_the_ramp_for_its_first_seconds():
    base = load_scenario(data_files.data_file("scenario_ramp.yaml"))  # 0.8 -> 1.2 in 30 s
    study = case_scenario(base, RHO0, 100.0, 1)
    longer = case_scenario(base, RHO0, 100.0, 1, ramp_to=1.4)
    assert study.duration == 30.0 and longer.duration == pytest.approx(45.0)
    assert longer.n_samples % longer.block_size == 0
    assert longer.airspeed.values == pytest.approx((80.0, 140.0))
    t = np.arange(30000) / 1000.0
    np.testing.assert_allclose(airspeed_at(longer, t), airspeed_at(study, t), rtol=1e-14)
    assert case_scenario(base, RHO0, 100.0, 1, ramp_to=1.1) == study  # not shorter


def _hold(le, target, power, diverged=False):
    return SimpleNamespace(sample_rate=1000.0, leading_edge=np.asarray(le, float),
                           samples=len(le), diverged=diverged, target=np.asarray(target),
                           damping=np.full(len(le), 624.7), damper_power=np.asarray(power))


def test_the_hold_gives_the_rms_switches_and_power_after_its_transient():
    n = int(HOLD[1] * 1000)
    rng = np.random.default_rng(0)
    le = rng.normal(0.0, 1e-3, n)
    target = np.where(np.arange(n) // 25 % 2 == 0, 100.0, 2500.0)  # 20 changes a second
    power = np.full(n, 30.0)
    rms, switches, watts = _hold_numbers(_hold(le, target, power))
    assert rms == pytest.approx(math.sqrt(np.mean(le[2000:] ** 2)))
    assert switches == pytest.approx(40.0, rel=2e-3) and watts == pytest.approx(30.0)
    grown = le * np.exp(np.arange(n) / 4000.0)  # x e^4.5 over the flight: it flutters
    assert math.isnan(_hold_numbers(_hold(grown, target, power))[0])
    assert math.isnan(_hold_numbers(_hold(le[:5000], target[:5000], power[:5000]))[0])
    no_force = _hold(le, target, np.full(n, np.nan))  # a block law's flight: no damper force
    assert math.isnan(_hold_numbers(no_force)[2])


def test_the_practical_boundary_is_the_first_sample_beyond_the_peak_limit():
    n = 10000
    u = np.linspace(80.0, 120.0, n)
    le = np.full(n, 1e-3)
    le[6000] = -0.02
    outcome = SimpleNamespace(sample_rate=1000.0, airspeed=u, leading_edge=le, damping=u,
                              diverged=False, peak_activation=np.empty(0))
    record = flight_record("fixed", "rho0", 1, outcome, 100.0, (80.0, 105.0), peak_limit=0.013)
    assert record.practical_ratio == pytest.approx(u[6000] / 100.0)
    assert math.isnan(flight_record("fixed", "rho0", 1, outcome, 100.0, (80.0, 105.0),
                                    peak_limit=0.03).practical_ratio)


@pytest.mark.slow
def test_evaluate_flies_every_controller_into_one_table(tmp_path, capsys):
    out = tmp_path / "ev"
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "3", "--cases", "rho0,1Hz",
                     "--fixed-c2", "624.7", "--no-boundaries", "--json",
                     "--controllers", "fixed,switching,clipped_optimal"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["controllers"] == ["fixed", "switching", "clipped_optimal"]
    assert payload["ramp_ratio"] == pytest.approx([0.8, 1.4])
    assert 0.012 < payload["peak_limits"]["rho0"] < 0.014  # 20x the RMS at 0.8 U_cr: 13 mm
    rows = {(r["controller"], r["case"]): r for r in payload["results"]}
    assert len(rows) == 6 and "switching" not in payload  # one list, no section of its own
    for law in ("switching", "clipped_optimal"):
        row = rows[(law, "rho0")]
        assert row["flights"] == 3 and row["not_flown"] is None
        # the laws hold past the best constant c2's boundary, in both readings
        assert row["divergence_difference"]["n"] >= 2
        assert row["practical_difference"]["n"] == 3
        assert row["mean_practical_ratio"] > rows[("fixed", "rho0")]["mean_practical_ratio"]
        assert row["rms_hold_change"]["mean"] < 0  # less vibration at 1.1 U_cr
        assert row["switches_per_second"] > 10 and row["damper_power"] > 0
        assert "density varying in time" in rows[(law, "1Hz")]["not_flown"]
    fixed = rows[("fixed", "rho0")]
    assert fixed["switches_per_second"] == 0.0 and fixed["damper_power"] is None
    records = json.loads((out / "records.json").read_text())
    assert {r["controller"] for r in records if r["case"] == "1Hz"} == {"fixed"}
    assert all("practical_ratio" in r and "rms_hold" in r for r in records)
    (pair,) = payload["law_pairs"]  # the clipped-optimal law against the switching law
    assert (pair["law"], pair["against"], pair["case"], pair["flights"]) == (
        "clipped_optimal", "switching", "rho0", 3)
    assert pair["practical"]["n"] == 3
    table = (out / "results.md").read_text()
    assert "| rho0 | clipped-optimal law |" in table and "| 1Hz | switching law | not flown" \
        in table
    assert "| rho0 | clipped-optimal law minus switching law |" in table
    # resumed from the saved records (their missing numbers saved as null), the same table
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "3", "--cases", "rho0,1Hz",
                     "--fixed-c2", "624.7", "--no-boundaries", "--json",
                     "--controllers", "fixed,switching,clipped_optimal"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["resumed_jobs"] == 6 and again["results"] == payload["results"]


def test_bad_gains_end_the_run_before_any_flight(tmp_path, capsys):
    gains = tmp_path / "gains.json"
    gains.write_text('{"format": "something else"}')
    out = tmp_path / "ev"
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "2", "--cases", "rho0",
                     "--controllers", "fixed,switching", "--gains", str(gains)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(gains) in err[0]
    assert not out.exists()  # nothing flown, nothing left behind
    # the switching law's file is no clipped-optimal law
    switching = str(data_files.data_file("switching_gains.json"))
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "2", "--cases", "rho0",
                     "--controllers", "fixed,clipped_optimal", "--gains", switching]) == 2
    assert "design 'lyapunov'" in capsys.readouterr().err
    assert cli.main(["evaluate", "--out", str(out), "--seeds", "2", "--cases", "rho0",
                     "--controllers", "fixed,switching,clipped_optimal", "--gains",
                     switching]) == 2
    assert "one per-sample law" in capsys.readouterr().err
