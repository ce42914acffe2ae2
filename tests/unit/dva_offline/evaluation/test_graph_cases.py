"""Evaluation flights: cases, scenarios, best fixed c2, divergence, aggregation, table, plots."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from aero_dva import data_files
from aero_dva.control.dva_design import (
    best_fixed_damping,
    flutter_airspeed_of,
    maximise_on_grid,
)
from aero_dva.flight.scenario_io import scenario_from_dict
from dva_offline import cli
from dva_offline.evaluation.graph_cases import (
    FlightCase,
    aggregate,
    case_grid,
    compare_rbf_with_schedule,
    evaluation_scenario,
    markdown_table,
    parse_controllers,
    parse_mu_list,
    study_ratios,
)
from dva_offline.evaluation.graph_io import load_base_scenario, plot_summary, write_scenario


def test_cases_cover_the_grid_and_reject_bad_input():
    cases = case_grid(("none", "rbf"), (0.0, 0.1), (1, 2, 3))
    assert len(cases) == 12 and len(set(cases)) == 12
    assert cases[0] == FlightCase("none", 0.0, 1) and cases[-1] == FlightCase("rbf", 0.1, 3)
    assert FlightCase("schedule", 0.05, 3).key == "schedule_mu0.05_seed3"
    with pytest.raises(ValueError, match="controller"):
        FlightCase("pid", 0.0, 1)
    with pytest.raises(ValueError, match="mu"):
        FlightCase("none", 1.0, 1)
    with pytest.raises(ValueError, match="seed"):
        FlightCase("none", 0.0, -1)
    assert parse_mu_list("0, 0.05,0.1") == (0.0, 0.05, 0.1)
    assert parse_controllers("rbf,none") == ("none", "rbf")  # canonical order
    for bad in ("0,x", "0,1.5", "0,0"):
        with pytest.raises(ValueError, match="--mu"):
            parse_mu_list(bad)
    with pytest.raises(ValueError, match="--controllers"):
        parse_controllers("none,pid")


def test_evaluation_scenario_changes_only_density_variation_and_seed(tmp_path):
    base = load_base_scenario(data_files.data_file("scenario_ramp.yaml"))
    mapping = evaluation_scenario(base, 0.05, 7)
    path = write_scenario(tmp_path, mapping)
    flown = scenario_from_dict(yaml.safe_load(path.read_text()))
    original = scenario_from_dict(base)
    assert flown.density_variation == 0.05 and flown.seed == 7
    assert (flown.duration, flown.airspeed, flown.force_std, flown.density) == \
        (original.duration, original.airspeed, original.force_std, original.density)
    assert base["excitation"]["seed"] == 1  # the base mapping is not modified
    bad = tmp_path / "steps.yaml"
    bad.write_text(yaml.safe_dump({**base, "airspeed": {"kind": "constant", "value": 90.0}}))
    with pytest.raises(ValueError, match="ramp"):
        load_base_scenario(bad)


def test_best_fixed_damping_finds_the_maximum_between_grid_points():
    def peak(c2):  # a kinked maximum at 437 N s/m (like a change of critical mode)
        return 110.0 - 0.01 * abs(c2 - 437.0) - (0.0 if c2 < 437 else 1e-5 * (c2 - 437) ** 2)

    choice = maximise_on_grid(peak, np.linspace(0, 2500, 26))
    assert choice.damping == pytest.approx(437.0, abs=0.5)
    assert choice.critical_airspeed == pytest.approx(110.0, abs=0.01)
    with pytest.raises(ValueError, match="grid"):
        maximise_on_grid(peak, [0.0, 100.0])
    with pytest.raises(ValueError, match="NaN"):
        maximise_on_grid(lambda c: math.nan, [0.0, 1.0, 2.0])


def test_a_c2_that_never_flutters_is_the_best_not_a_gap():
    # no flutter found up to the search's end ranks above every flutter airspeed: with the
    # NaN this used to be, the maximum over the rest would have picked 300 N s/m
    choice = maximise_on_grid(lambda c: math.inf if c > 900 else 100.0 + c / 10,
                              [0.0, 300.0, 600.0, 1000.0, 1300.0])
    assert (choice.damping, choice.critical_airspeed) == (1000.0, math.inf)


def test_best_fixed_damping_of_the_default_wing_beats_its_neighbours():
    from aero_dva.wing.model import AeroelasticModel
    from aero_dva.wing.wing_io import load_wing

    cfg = load_wing(None)
    model = AeroelasticModel(cfg.wing, cfg.absorber, cfg.aero)
    critical = flutter_airspeed_of(model, 1.2)
    choice = maximise_on_grid(critical, np.linspace(0, 2500, 11))
    assert 500 < choice.damping < 750  # between the grid's best two (step 250)
    for delta in (-20.0, 20.0):
        assert critical(choice.damping + delta) <= choice.critical_airspeed + 1e-6
    assert choice.critical_airspeed >= np.max(choice.grid_critical_airspeed)
    # the default: 51 points over the damper's range, the evaluation's and the switching law's
    best = best_fixed_damping(model, 1.2)
    assert best.damping == pytest.approx(624.713, abs=0.01)
    assert best.critical_airspeed / 100.0 == pytest.approx(1.1505, abs=1e-4)


def _records():
    out = []
    for controller, mu, ratios in (("schedule", 0.1, [1.04, 1.06, 1.05]),
                                   ("rbf", 0.1, [1.10, 1.12, 1.11]),
                                   ("schedule", 0.0, [1.16, 1.15, None])):
        for seed, r in enumerate(ratios):
            out.append({"controller": controller, "mu": mu, "seed": seed, "ok": True,
                        "divergence_ratio": r, "leading_edge_rms": 1e-3 * (seed + 1),
                        "mean_damping": 400.0})
    out.append({"controller": "rbf", "mu": 0.1, "seed": 9, "ok": False, "error": "boom"})
    return out


def test_aggregate_counts_diverged_not_diverged_and_failed_flights():
    stats = aggregate(_records())
    assert [(s.controller, s.mu) for s in stats] == [("schedule", 0.0), ("schedule", 0.1),
                                                     ("rbf", 0.1)]
    sch0, sch1, rbf1 = stats
    assert (sch0.n_flights, sch0.n_diverged, sch0.n_not_diverged) == (3, 2, 1)
    assert sch0.mean == pytest.approx(1.155) and sch0.std == pytest.approx(np.std([1.16, 1.15],
                                                                                  ddof=1))
    assert (rbf1.n_flights, rbf1.n_failed, rbf1.min, rbf1.max) == (4, 1, 1.10, 1.12)
    assert sch1.study_ratio == study_ratios("schedule")[0.1] == 1.04
    assert sch1.mean_rms == pytest.approx(2e-3)
    table = markdown_table(stats)
    assert "| airspeed schedule | 0 | 3 | 2 (1 reached the end) | 1.155 |" in table
    assert "| RBF network | 0.1 | 4 | 3, 1 failed | 1.110 | 0.010 | 1.100 | 1.120 | 1.11 |" \
        in table
    with pytest.raises(ValueError, match="controller"):
        aggregate([{"mu": 0.0, "ok": True}])


def test_key_result_verdict_follows_the_difference_and_its_error():
    (key,) = compare_rbf_with_schedule(aggregate(_records()))
    assert key.mu == 0.1 and key.difference == pytest.approx(0.06)
    assert key.standard_error == pytest.approx(math.sqrt(0.01 ** 2 / 3 * 2))
    assert key.verdict == "rbf better"
    swapped = [dict(r, controller={"rbf": "schedule", "schedule": "rbf"}[r["controller"]])
               for r in _records() if r["mu"] == 0.1]
    (key,) = compare_rbf_with_schedule(aggregate(swapped))
    assert key.verdict == "schedule better"
    close = [dict(r, divergence_ratio=r["divergence_ratio"] + (0.0 if r["controller"] == "rbf"
                                                                 else 0.06))
             for r in _records() if r["mu"] == 0.1 and r["ok"]]
    (key,) = compare_rbf_with_schedule(aggregate(close))
    assert key.verdict == "no significant difference"


def test_summary_plot_is_written(tmp_path):
    path = plot_summary(tmp_path / "summary.png", aggregate(_records()))
    assert path.stat().st_size > 10_000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("argv,message", [
    (["--graph", "--mu", "0,2"], "--mu"), (["--graph", "--controllers", "pid"], "--controllers"),
    (["--graph", "--seeds", "0"], "--seeds"), (["--controllers", "pid"], "--controllers"),
    (["--seeds", "0"], "--seeds"), (["--cases", "rho0,moon"], "--cases"),
    (["--rms-range", "1.1:0.9"], "--rms-range"), (["--rms-range", "x"], "--rms-range"),
    (["--scenario", "nope.yaml"], "nope.yaml")])
def test_cli_rejects_bad_options_in_one_line(capsys, tmp_path, argv, message):
    argv = [str(tmp_path / a) if a.endswith(".yaml") else a for a in argv]
    assert cli.main(["evaluate", "--out", str(tmp_path / "ev"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dva evaluate: error:") and message in err
    assert len(err.strip().splitlines()) == 1


def test_missing_inputs_are_made_with_the_project_commands(tmp_path):
    """Schedule by dva control schedule, fixed c2 by flutter speed, network by dva train rbf."""
    import subprocess
    import sys
    from argparse import Namespace

    from aero_dva.control.rbf_io import load_rbf_network
    from aero_dva.control.schedule_io import load_schedule
    from dva_offline.evaluation.inputs import inputs as _inputs

    sweep = tmp_path / "sweep"  # a mini training plan (264 s of flight)
    done = subprocess.run([sys.executable, "-m", "dva_offline.cli", "train", "sweep",
                           "--ratios", "0.8:1.12:0.02", "--factors", "1.0,1.1", "--n-damping",
                           "4", "--out", str(sweep)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    args = Namespace(schedule=None, fixed_c2=None, network=None, sweep_bag=str(sweep))
    said = []
    made = _inputs(args, ("fixed", "schedule", "rbf"), tmp_path / "inputs", said.append)
    schedule = load_schedule(made["schedule"])
    assert schedule.a1 > 0  # the optimal c2 rises with airspeed near the limit
    # the chapter-6 wing: c2 = 624.7 N s/m keeps it stable up to 1.1505 U_cr
    assert made["fixed_c2"]["damping"] == pytest.approx(624.7, abs=1.0)
    assert made["fixed_c2"]["critical_ratio"] == pytest.approx(1.1505, abs=1e-3)
    assert made["fixed_c2"]["flutter_frequency"] == pytest.approx(8.48, abs=0.01)
    assert load_rbf_network(made["network"]).input_dim == 33
    assert len(said) == 3  # one progress line per input made
    again = _inputs(args, ("fixed", "schedule", "rbf"), tmp_path / "inputs", said.append)
    assert again == made and len(said) == 3  # kept from the first call, not made again
    with pytest.raises(FileNotFoundError, match="--network"):
        _inputs(Namespace(schedule=None, fixed_c2=None, network=str(tmp_path / "x.npz"),
                          sweep_bag=None), ("rbf",), tmp_path / "inputs", said.append)


def test_a_bag_that_lost_messages_is_not_judged():
    from dva_offline.evaluation.graph import bag_problem

    whole = {"end_report_recorded": True, "data_published": 3000, "data_recorded": 3000,
             "data_missing": 0}
    assert bag_problem(whole) is None
    short = dict(whole, data_recorded=2990, data_missing=10)
    assert "lacks 10 of the 3000 data messages" in bag_problem(short)
    no_report = {"end_report_recorded": False, "data_published": None, "data_recorded": 2950,
                 "data_missing": None}
    assert "end-of-flight report" in bag_problem(no_report)
    assert "end-of-flight report" in bag_problem({})  # a summary from before the check
