"""Benchmark of faults: what survives a killed recorder or controller, command bursts, bad files.

Run (after ./test.sh or ./run.sh has set everything up)::

    source scripts/env.sh && python bench/bench_faults.py [--trials 20] [--only recorder,...]
        [--seed 0] [--json FILE] [--keep DIR]

Measures, with nodes run as processes exactly as ``ros2 run`` starts them, on a ROS_DOMAIN_ID
reserved per trial:

- recorder: ``mcap_recorder`` killed by SIGINT, SIGTERM or SIGKILL at a random moment of a
  flight (``--trials`` each), and by SIGINT right after being frozen for 0.5 s
  (SIGSTOP/SIGCONT: a recorder half a second behind its publishers); acceleration blocks
  lost, counted by the simulator's sample indexes against what a probe node had received when
  the signal was sent; after SIGKILL the bag goes through
  ``bench.faults.bag_recovery.recover`` and is checked against the chunks complete in the
  file. The lost stretch is set against the recorder's flush period (ratio).
- controller: ``fixed_controller`` killed by SIGKILL at a random moment, with the simulator in
  lockstep (as run_flight flies) and free running; time until ``dva/damper_state`` reports the
  stale fallback and the warning reaches ``/diagnostics``, and the c2 applied meanwhile. The
  sim-time delay is set against the damper timeout (ratio).
- burst: ``--trials`` bursts of damper commands at 10 kHz for each kind (valid, above range,
  NaN, +-inf, negative, huge, mixed): the c2 applied, statuses, diagnostics and log warnings.
- cli: every ``dva`` command that reads a file, with malformed files (bench.faults.cli_matrix).

Prints markdown tables (docs/reliability.md holds them); ``--json`` writes every trial.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from aero_dva.flight.damper import DEFAULT_STALE_TIMEOUT

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # run as a script: the bench package sits at the repository root
    sys.path.insert(0, str(REPO))

from aero_dva.atomic_io import atomic_output  # noqa: E402
from bench.faults import cli_matrix  # noqa: E402

SECTIONS = ("recorder", "controller", "burst", "cli")
FLUSH_PERIOD = 1.0  # [s] the recorder's default
DAMPER_TIMEOUT = DEFAULT_STALE_TIMEOUT  # [s sim] the simulator's default
STALL = 0.5  # [s] recorder frozen (SIGSTOP) right before the signal: a recorder that far behind


def _median(values) -> float:
    values = [v for v in values if v is not None and not math.isnan(v)]
    return statistics.median(values) if values else math.nan


def _fmt(value, spec: str = ".3g") -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return format(value, spec)


def _trial_dir(root: Path, name: str) -> Path:
    path = root / name
    path.mkdir(parents=True)
    return path


# (signal, seconds the recorder is frozen right before it)
RECORDER_FAULTS = (("SIGINT", 0.0), ("SIGTERM", 0.0), ("SIGKILL", 0.0), ("SIGINT", STALL))


def run_recorder(root: Path, trials: int, rng: np.random.Generator) -> tuple[list, str]:
    from bench.faults.recorder_faults import run_recorder_trial

    records = []
    for name, stall in RECORDER_FAULTS:
        for i in range(trials):
            kill_after = float(rng.uniform(0.2, 3.0)) + stall
            trial = run_recorder_trial(name, kill_after,
                                       _trial_dir(root, f"rec_{name}_{stall:g}_{i}"),
                                       flush_period=FLUSH_PERIOD, stall=stall)
            records.append(trial)
            print(f"  recorder {name} (stall {stall:g} s) {i + 1}/{trials}: after "
                  f"{kill_after:.2f} s, lost {trial.lost} of {trial.published_before}, gaps "
                  f"{trial.gaps}, after the signal {trial.after_signal}",
                  file=sys.stderr, flush=True)
    rows = ["| signal | trials | exit codes | bag closed | blocks before the signal (median) "
            "| trials losing blocks | blocks lost: median / max (of them, while frozen) | lost "
            "stretch [s]: median / max (/ flush period) | gaps | blocks recorded after the "
            "signal: median / max | complete-chunk blocks not recovered | read back by |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, stall in RECORDER_FAULTS:
        group = [t for t in records if t.signal == name and t.stall == stall]
        label = name if stall == 0 else f"{name}, recorder frozen {stall:g} s before"
        codes = ", ".join(f"{c}: {n}" for c, n in sorted(Counter(t.exit_code for t in group)
                                                         .items(), key=str))
        lost = [t.lost for t in group]
        window = [t.lost_window for t in group]
        missing = [t.missing_from_complete_chunks for t in group
                   if t.missing_from_complete_chunks is not None]
        rows.append(
            f"| {label} | {len(group)} | {codes} | {sum(t.closed for t in group)} "
            f"| {_median([t.published_before for t in group]):.0f} "
            f"| {sum(v > 0 for v in lost)} | {_median(lost):.0f} / {max(lost)}"
            + (f" ({sum(t.lost_in_stall for t in group)} of {sum(lost)})" if stall else "")
            + " "
            f"| {_fmt(_median(window), '.2f')} / {max(window):.2f} "
            f"({max(window) / FLUSH_PERIOD:.2f}) | {sum(t.gaps for t in group)} "
            f"| {_median([t.after_signal for t in group]):.0f} / "
            f"{max(t.after_signal for t in group)} "
            f"| {sum(missing) if missing else 'n/a'} "
            f"| {', '.join(sorted({t.method for t in group}))} |")
    return records, "\n".join(rows)


def run_controller(root: Path, trials: int, rng: np.random.Generator) -> tuple[list, str]:
    from bench.faults.controller_faults import MODES, run_controller_trial

    records = []
    for mode in MODES:
        for i in range(trials):
            kill_after = float(rng.uniform(0.1, 1.5))
            trial = run_controller_trial(mode, kill_after, _trial_dir(root, f"ctl_{mode}_{i}"),
                                         damper_timeout=DAMPER_TIMEOUT)
            records.append(trial)
            print(f"  controller {mode} {i + 1}/{trials}: fallback after "
                  f"{trial.fallback_wall_delay:.3f} s wall", file=sys.stderr, flush=True)
    rows = ["| simulator | trials | kill to fallback state [s wall]: median / max | last "
            "command to fallback [s sim]: min-max (/ damper timeout) | warning on /diagnostics "
            "after the kill [s wall]: median / max | c2 applied until then [N s/m] | fallback "
            "c2 [N s/m] | longest wait for the controller [s wall]: median / max | trials "
            "waiting more than once |",
            "|---|---|---|---|---|---|---|---|---|"]
    for mode in MODES:
        group = [t for t in records if t.mode == mode]
        wall = [t.fallback_wall_delay for t in group]
        age = [t.command_age for t in group]
        diag = [t.diagnostic_wall_delay for t in group if t.diagnostic_wall_delay is not None]
        rows.append(
            f"| {mode} | {len(group)} | {_median(wall):.3f} / {max(wall):.3f} "
            f"| {min(age):.3f}-{max(age):.3f} ({max(age) / DAMPER_TIMEOUT:.2f}) "
            f"| {_fmt(_median(diag), '.3f')} / {_fmt(max(diag) if diag else None, '.3f')} "
            f"({len(diag)} of {len(group)}) "
            f"| {min(t.applied_min for t in group):g}-{max(t.applied_max for t in group):g} "
            f"| {', '.join(f'{v:g}' for v in sorted({t.fallback for t in group}))} "
            f"| {_median([t.longest_stall for t in group]):.3f} / "
            f"{max(t.longest_stall for t in group):.3f} "
            f"| {sum(len([g for g in t.stalls if g > 1.0]) > 1 for t in group)} |")
    return records, "\n".join(rows)


def run_burst(root: Path, trials: int, rng: np.random.Generator) -> tuple[list, str]:
    from bench.faults.command_faults import KINDS, run_burst_session

    sessions = []
    for kind in KINDS:
        session = run_burst_session(kind, trials, _trial_dir(root, f"burst_{len(sessions)}"),
                                    seed=int(rng.integers(2**31)))
        sessions.append(session)
        print(f"  burst {kind}: {session.sent} commands, {session.rejected} rejected",
              file=sys.stderr, flush=True)
    rows = ["| commands | bursts | rate [kHz]: median | c2 applied [N s/m] | applied always "
            "finite and in range | damper statuses during the bursts | rejected by the "
            "simulator / sent | /diagnostics reports per burst: max | log warnings per burst: "
            "max | sim rate during bursts: min |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for session in sessions:
        group = session.trials
        statuses = Counter()
        for t in group:
            statuses.update(t.statuses)
        rejected = (f"{session.rejected} / {session.sent}" if session.summary_seen
                    else f"n/a / {session.sent}")
        rows.append(
            f"| {session.kind} | {len(group)} | {_median([t.rate for t in group]) / 1e3:.2f} "
            f"| {min(t.applied_min for t in group):.0f}-{max(t.applied_max for t in group):.0f} "
            f"| {sum(t.applied_valid for t in group)} of {len(group)} "
            f"| {', '.join(f'{k} {n}' for k, n in statuses.most_common())} | {rejected} "
            f"| {max(t.diagnostics for t in group)} | {max(t.logs for t in group)} "
            f"| {min(t.sim_rate for t in group):.2f} |")
    return sessions, "\n".join(rows)


def run_cli(root: Path) -> tuple[list, str]:
    cases = cli_matrix.build_cases(root / "cli")
    outcomes = []
    for number, case in enumerate(cases):
        outcome = cli_matrix.run_case(case)
        outcomes.append(outcome)
        print(f"  cli {number + 1}/{len(cases)} {case.label}: exit {outcome.code}"
              + ("" if outcome.passed else f"  FAILS: {'; '.join(outcome.problems())}"),
              file=sys.stderr, flush=True)
    kinds = list(dict.fromkeys(o.case.kind for o in outcomes))
    rows = ["| command | input | " + " | ".join(kinds) + " |",
            "|---|---|" + "---|" * len(kinds)]
    by_command: dict[tuple[str, str], dict[str, object]] = {}
    for o in outcomes:
        by_command.setdefault((o.case.command.name, o.case.command.option), {})[o.case.kind] = o
    for (name, option), cells in by_command.items():
        texts = []
        for kind in kinds:
            o = cells.get(kind)
            if o is None:
                texts.append("")
            else:
                mark = "ok" if o.passed else "FAIL"
                texts.append(f"{mark} {o.code} ({o.seconds:.1f} s)")
        rows.append(f"| dva {name} | {option} | " + " | ".join(texts) + " |")
    passed = sum(o.passed for o in outcomes)
    worst = max(outcomes, key=lambda o: o.seconds)
    memory = max(outcomes, key=lambda o: o.peak_rss_mb)
    rows += ["", f"{passed} of {len(outcomes)} cases pass (exit 2 with one error line naming the "
             "file, no traceback, no output left; odd-path cases with valid files: exit 0). "
             f"Slowest: {worst.case.label} {worst.seconds:.1f} s; most memory: "
             f"{memory.case.label} {memory.peak_rss_mb:.0f} MB."]
    failures = [o for o in outcomes if not o.passed]
    rows += [f"- FAIL {o.case.label}: {'; '.join(o.problems())}" for o in failures]
    return outcomes, "\n".join(rows)


def _json_ready(records) -> list:
    out = []
    for r in records:
        if hasattr(r, "to_dict"):
            out.append(r.to_dict())
        elif hasattr(r, "trials"):
            out.append({"kind": r.kind, "sent": r.sent, "rejected": r.rejected,
                        "summary_seen": r.summary_seen,
                        "trials": [t.to_dict() for t in r.trials]})
        else:  # a CLI outcome
            out.append({"case": r.case.label, "argv": r.case.argv, "expect_ok": r.case.expect_ok,
                        "code": r.code, "stderr": r.stderr, "seconds": r.seconds,
                        "peak_rss_mb": r.peak_rss_mb, "problems": r.problems()})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20,
                        help="trials per fault (kills per signal and mode, bursts per kind)")
    parser.add_argument("--only", default=",".join(SECTIONS),
                        help=f"comma-separated subset of {','.join(SECTIONS)}")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the kill moments")
    parser.add_argument("--json", metavar="FILE", help="write every trial as JSON")
    parser.add_argument("--keep", metavar="DIR", help="keep bags and logs in DIR")
    args = parser.parse_args(argv)
    only = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = sorted(set(only) - set(SECTIONS))
    if unknown or args.trials < 1:
        parser.error(f"unknown sections {unknown}" if unknown else "--trials must be >= 1")
    rng = np.random.default_rng(args.seed)
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_faults_"))
    root.mkdir(parents=True, exist_ok=True)
    runners = {"recorder": lambda: run_recorder(root, args.trials, rng),
               "controller": lambda: run_controller(root, args.trials, rng),
               "burst": lambda: run_burst(root, args.trials, rng),
               "cli": lambda: run_cli(root)}
    results = {}
    try:
        for section in only:
            started = time.monotonic()
            records, table = runners[section]()
            results[section] = _json_ready(records)
            print(f"\n## {section} ({time.monotonic() - started:.0f} s)\n\n{table}", flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    if args.json:
        with atomic_output(args.json) as stream:
            json.dump({"trials": args.trials, "seed": args.seed, "results": results}, stream,
                      indent=1, default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
