"""``dva evaluate --graph``: the study's evaluation flights through the ROS 2 graph, over seeds.

Flies the ramp 0.8 -> 1.2 U_cr in 30 s (1 kN white aileron force) with air density
rho0 (1 + mu sin 2 pi t), for each controller (none = the wing without DVA, or a controller of
the table that flies through the graph: by default fixed = the best constant c2, schedule =
eq. 7.1, rbf = the spectrum-based network) x mu x excitation seed. Each
flight is one ``run_flight`` (simulator, controller and recorder as separate processes over DDS);
its record is saved as soon as it ends, so an interrupted evaluation resumes where it stopped
(run the same command again) and a failed flight is reported in the table, not fatal.

The schedule, the fixed c2 and the network are made by :mod:`dva_offline.evaluation.inputs`
when not given. Slow (10-20 s of wall time per 30 s flight) but the real thing; the batch
evaluation (``dva evaluate``, :mod:`dva_offline.evaluation.flights`) flies the same runtime and
controllers in one process.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

from aero_dva import exits

__all__ = ["bag_problem", "evaluate_graph"]

RATIO_KEY = "divergence_ratio"  # run_flight's, the project's one detector


def _flight_argv(case, scenario: Path, bag: Path, made: dict, args) -> list[str]:
    from aero_dva.control.controllers import NONE, controller
    from aero_dva_sim.run_flight import executable

    exe = executable("aero_dva_sim", "run_flight")  # not sourced: exits.Failure says how
    argv = [exe, "--scenario", str(scenario), "--output", str(bag), "--json",
            "--real-time-factor", str(args.real_time_factor), "--timeout", str(args.timeout)]
    argv += ["--controller", case.controller]
    if case.controller == NONE:
        return argv + ["--absorber", "none"]
    # its options from the made inputs: --damping the best fixed c2, --schedule, --network
    given = {"damping": repr(made["fixed_c2"]["damping"]) if "fixed_c2" in made else None,
             "schedule": made.get("schedule"), "network": made.get("network")}
    for option in controller(case.controller).options:
        if given.get(option.name) is not None:
            argv += [f"--{option.name}", given[option.name]]
    return argv


def bag_problem(summary: dict) -> str | None:
    """Why a flight's bag cannot be judged (run_flight's summary ``summary``), or None: its
    divergence is read from the bag's last seconds, which a recorder starved of CPU can lose
    (such a flight counts as failed and is flown again, ``--retries``)."""
    if not summary.get("end_report_recorded"):
        return ("the bag lacks the simulator's end-of-flight report (its last messages were "
                "lost on the way to the recorder)")
    missing = summary.get("data_missing")
    if missing:
        return (f"the bag lacks {missing} of the {summary.get('data_published')} data messages "
                "the simulator published (lost on the way to the recorder)")
    return None


def _fly(case, scenario: Path, out: Path, made: dict, args) -> dict:
    """One flight through run_flight; the record (a failed flight is one; a flight refused as
    bad input, which every flight would be, raises ValueError)."""
    from dva_offline.evaluation.graph_io import flight_bag

    bag = flight_bag(out, case)
    for leftover in (bag, bag.with_name(bag.name + "_logs")):  # an interrupted attempt
        shutil.rmtree(leftover, ignore_errors=True)
    from aero_dva.flight.divergence import DETECTOR

    record = {"divergence_detector": DETECTOR,
              "controller": case.controller, "mu": case.mu, "seed": case.seed,
              "scenario": str(scenario), "scenario_name": scenario.stem, "bag": str(bag),
              "absorber": "none" if case.controller == "none" else "maxwell"}
    started = time.monotonic()
    argv = _flight_argv(case, scenario, bag, made, args)
    try:
        result = subprocess.run(argv, capture_output=True, text=True,
                                timeout=args.timeout + 120)
        if result.returncode == exits.BAD_INPUT:  # every flight would refuse it: stop
            lines = result.stderr.strip().splitlines()
            refused = (lines[-1] if lines else "no output").removeprefix("run_flight: error: ")
        elif result.returncode == 0:
            record.update(json.loads(result.stdout))
            incomplete = bag_problem(record)
            if incomplete:
                record.update(ok=False, error=incomplete)
            else:
                record["ok"] = True
        else:
            lines = (result.stderr or "").strip().splitlines()
            record.update(ok=False, error=f"run_flight exited {result.returncode}: "
                          + (lines[-1] if lines else "no output"))
    except subprocess.TimeoutExpired:
        record.update(ok=False, error=f"run_flight took longer than {args.timeout + 120:g} s")
    except json.JSONDecodeError as exc:
        record.update(ok=False, error=f"run_flight printed no JSON summary ({exc})")
    except (ValueError, OSError) as exc:  # the bag does not read back
        record.update(ok=False, error=f"the recorded bag does not read back: {exc}")
    else:
        if result.returncode == exits.BAD_INPUT:
            raise ValueError(f"flight {case.key}: {refused}")
    record["runner_wall_time"] = time.monotonic() - started
    return record


def _fly_retried(out: Path, made: dict, args, log, job) -> dict:
    """``job`` = (case, scenario) flown, again up to ``--retries`` times while it fails; the
    record (never raises for a failed flight). Each run_flight reserves a ROS domain of its own,
    so flights may run side by side (``--workers``, ``--ray``)."""
    case, scenario = job
    for attempt in range(1 + args.retries):
        record = _fly(case, scenario, out, made, args)
        record["attempts"] = attempt + 1
        if record["ok"]:
            break
        if log is not None:
            log(f"flight {case.key} attempt {attempt + 1} failed: {record['error']}")
    return record


def evaluate_graph(args) -> int:
    """Run ``dva evaluate --graph`` (see the module docstring)."""
    from tqdm import tqdm

    from aero_dva import data_files
    from dva_offline.evaluation.cli import check_inputs_used
    from dva_offline.evaluation.graph_cases import (
        aggregate,
        case_grid,
        compare_rbf_with_schedule,
        evaluation_scenario,
        markdown_table,
        parse_controllers,
        parse_mu_list,
    )
    from dva_offline.evaluation.graph_io import (
        flight_record_path,
        load_base_scenario,
        load_records,
        save_json,
        write_scenario,
    )
    from dva_offline.evaluation.inputs import evaluation_directory, log, resumable_or_removed

    if args.retries < 0:
        raise ValueError(f"--retries must be >= 0, got {args.retries}")
    if args.seeds < 1 or args.first_seed < 0:
        raise ValueError(f"--seeds must be >= 1 and --first-seed >= 0, got {args.seeds}, "
                         f"{args.first_seed}")
    if not (args.timeout > 0):
        raise ValueError(f"--timeout must be > 0, got {args.timeout}")
    controllers = parse_controllers(args.controllers)
    check_inputs_used(args, controllers)
    mus = parse_mu_list(args.mu)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    scenario_path = Path(args.scenario) if args.scenario else \
        data_files.data_file("scenario_ramp.yaml")
    base = load_base_scenario(scenario_path)
    started = time.monotonic()
    out, made, _, created = evaluation_directory(args, controllers)  # flights read the paths
    with resumable_or_removed(out, created):
        (out / "flights").mkdir(exist_ok=True)
        scenarios = {(mu, seed): write_scenario(out / "scenarios",
                                                evaluation_scenario(base, mu, seed))
                     for mu in mus for seed in seeds}
        cases = case_grid(controllers, mus, seeds)
        records = {c: r for c, r in load_records(out, cases).items() if r.get("ok")}
        todo = [c for c in cases if c not in records]
        if records:
            log(f"resuming {out}: {len(records)} of {len(cases)} flights already recorded")
        bar = tqdm(total=len(cases), initial=len(records), desc="flights", unit="flight",
                   file=sys.stderr, dynamic_ncols=True)
        flight_times = []
        try:
            from functools import partial

            from dva_offline.evaluation.campaign import run_jobs

            serial = args.workers == 1 and args.ray is None
            # a worker process or thread does not log: its record says what failed
            fly = partial(_fly_retried, out, made, args, log if serial else None)
            jobs = [(c, scenarios[(c.mu, c.seed)]) for c in todo]
            done = ((job[0], record) for job, record in run_jobs(
                jobs, fly, workers=args.workers, ray_address=args.ray))
            for case, record in done:
                if not record["ok"]:
                    log(f"flight {case.key} failed after {record['attempts']} attempt(s): "
                        f"{record['error']}")
                save_json(flight_record_path(out, case), record)
                records[case] = record
                flight_times.append(record["runner_wall_time"])
                if record["ok"]:
                    ratio = record.get(RATIO_KEY)
                    bar.set_postfix_str(f"{case.key}: U_div/U_cr = "
                                        + (f"{ratio:.3f}" if ratio is not None else "none"))
                bar.update(1)
        finally:
            bar.close()
        stats = aggregate(records.values(), ratio_key=RATIO_KEY)
        key = compare_rbf_with_schedule(stats)
        table = markdown_table(stats)
        files = _outputs(out, args, mus, controllers, seeds, records, stats, key, table, made,
                         log)
        elapsed = time.monotonic() - started
        payload = {
            "out": str(out), "scenario": str(scenario_path), "controllers": list(controllers),
            "mu": list(mus), "seeds": seeds, "inputs": made,
            "flights": len(cases), "flown_now": len(flight_times),
            "failed": sum(1 for r in records.values() if not r.get("ok")),
            "wall_time_s": elapsed,
            "mean_flight_wall_time_s": (sum(flight_times) / len(flight_times)
                                        if flight_times else None),
            "cases": [s.to_dict() for s in stats],
            "rbf_vs_schedule": [k.to_dict() for k in key],
            **files,
        }
        save_json(out / "results.json", payload)
        if args.json:
            print(json.dumps(payload))
        else:
            print(table)
            for k in key:
                print(f"mu = {k.mu:g}: RBF - schedule = {k.difference:+.3f} U_cr "
                      f"(SE {k.standard_error:.3f}): {k.verdict}")
            print(f"results: {out / 'results.md'} ({len(flight_times)} flights flown now in "
                  f"{elapsed:.0f} s)")
        return 0 if payload["failed"] == 0 else 1


def _outputs(out, args, mus, controllers, seeds, records, stats, key, table, made, log) -> dict:
    """results.md, plots, per-run reports; returns the files written."""
    from aero_dva.bag.flight_log_io import load_flight_log
    from dva_offline.evaluation.graph_cases import label
    from dva_offline.evaluation.graph_io import plot_summary, plot_traces
    from dva_offline.report.files import write_report

    first = {}  # (controller, mu) -> record of the first seed that flew
    for seed in seeds:
        for (c, m) in ((c, m) for c in controllers for m in mus):
            rec = next((r for r in records.values() if r["controller"] == c and r["mu"] == m
                        and r["seed"] == seed and r.get("ok")), None)
            if rec is not None and (c, m) not in first:
                first[(c, m)] = rec
    files: dict = {"traces": [], "reports": []}
    u_cr = next((r.get("critical_airspeed") for r in first.values()
                 if r.get("critical_airspeed")), None)
    for mu in mus:
        runs = {c: load_flight_log(first[(c, mu)]["bag"]) for c in controllers
                if (c, mu) in first}
        if runs and u_cr:
            path = plot_traces(out / f"traces_mu{mu:g}.png", mu, runs, u_cr)
            files["traces"].append(str(path))
    if stats:
        files["summary_plot"] = str(plot_summary(out / "divergence_vs_mu.png", stats))
    if args.reports != "none":
        for (c, m), rec in first.items():
            report_dir = out / "reports" / f"{c}_mu{m:g}"
            try:
                meta = {"absorber": "none" if c == "none" else "maxwell", **rec}
                written = write_report(rec["bag"], report_dir, rrd=not args.no_rrd,
                                       metadata=meta, stem="run")
                files["reports"].append(str(written.markdown))
            except Exception as exc:  # a report is a by-product: say so, keep the table
                log(f"report of {rec['bag']} failed: {exc}")
    lines = ["# Evaluation flights", "",
             f"Base scenario `{args.scenario or 'scenario_ramp.yaml'}`; seeds {seeds[0]}.."
             f"{seeds[-1]}; U_div / U_cr over the flights that diverged "
             "(U_cr: wing without DVA, base density; U_div: the leading-edge RMS over 1 s "
             "windows sliding by 0.05 s exceeds 10x its start value for good).", ""]
    if "schedule" in made:
        lines.append(f"- schedule: `{made['schedule']}`")
    if "fixed_c2" in made:
        fixed = made["fixed_c2"]
        lines.append(f"- fixed c2: {fixed['damping']:.1f} N s/m ({fixed['source']}"
                     + (f"; flutter at {fixed['critical_ratio']:.4f} U_cr"
                        if "critical_ratio" in fixed else "") + ")")
    if "network" in made:
        lines.append(f"- network: `{made['network']}`")
    lines += ["", table, ""]
    for k in key:
        lines.append(f"- mu = {k.mu:g}: {label('rbf')} {k.rbf_mean:.3f} vs "
                     f"{label('schedule')} {k.schedule_mean:.3f}: difference "
                     f"{k.difference:+.3f} (SE {k.standard_error:.3f}): **{k.verdict}**")
    failed = [r for r in records.values() if not r.get("ok")]
    if failed:
        lines += ["", "Failed flights:", *[f"- {r['bag']}: {r['error']}" for r in failed]]
    lines += ["", "![divergence vs mu](divergence_vs_mu.png)", ""]
    lines += [f"![traces]({Path(p).name})" for p in files["traces"]]
    lines += ["", "Per-run reports: " + ", ".join(
        f"[{Path(p).parent.name}]({Path(p).relative_to(out)})" for p in files["reports"])]
    (out / "results.md").write_text("\n".join(lines) + "\n")
    files["results_md"] = str(out / "results.md")
    return files
