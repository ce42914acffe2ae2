#!/usr/bin/env python3
"""Calibrate the reference wing toward the study's chapter-6 ratios (docs/wing.md, Calibration).

Run (one process; it is long, so nice it on a shared machine):

    source scripts/env.sh
    nice -n 10 python scripts/calibrate_reference_wing.py \
        --checkpoint runs/wing_calibration.jsonl --max-seconds 3600 \
        --candidate runs/candidate_wing.yaml

Every evaluation is appended to the checkpoint (JSON lines) as soon as it is done; running the
same command again resumes: earlier candidates are replayed from the file instead of being
evaluated again (same ``--seed``). The best candidate so far is written to ``--candidate`` as
a wing file whenever it improves, and at the end it is re-evaluated with the exact settings of
``dva wing design`` and printed next to the study and the current reference wing. The search
itself is :mod:`dva_offline.wing.calibration`.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from aero_dva.wing.wing_io import WingConfig, load_wing, reference_wing_path, save_wing
from dva_offline.wing import calibration as wc


def read_checkpoint(path: Path) -> list:
    """Evaluations stored in a checkpoint file (a truncated last line is skipped)."""
    if not path.exists():
        return []
    out = []
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            try:
                out.append(wc.Evaluation.from_dict(json.loads(line)))
            except (json.JSONDecodeError, KeyError):
                continue
    return out


def write_candidate(path: Path, evaluation: wc.Evaluation, reference: WingConfig,
                    header: str) -> None:
    """The candidate as a wing file (with the reference wing's absorber and density)."""
    wing, aero, _ = wc.build_wing(evaluation.params, evaluation.pitch_damping)
    save_wing(path, WingConfig(wing, reference.air_density, aero, reference.absorber))
    text = path.read_text(encoding="utf-8")
    path.write_text("".join(f"# {line}\n" for line in header.splitlines()) + text,
                    encoding="utf-8")


def _fmt(x: float) -> str:
    return "   nan" if math.isnan(x) else f"{x:.4f}"


def report(best: wc.Evaluation, current: dict) -> str:
    """Ratios of ``best`` next to the study's and the current reference wing's."""
    lines = [f"{'study result':40s} {'study':>6s} {'current':>7s} {'candidate':>9s}"]
    for key, target in wc.STUDY_TARGETS.items():
        lines.append(f"{key:40s} {target:6.3f} {_fmt(current[key]):>7s} "
                     f"{_fmt(best.ratios[key]):>9s}")
    cur = wc.calibration_cost(current)
    new = wc.calibration_cost(best.ratios, best.flutter_frequency)
    lines.append(f"{'max |error|':40s} {'':6s} {cur.max_error:7.4f} {new.max_error:9.4f}")
    lines.append(f"{'cost':40s} {'':6s} {cur.total:7.1f} {new.total:9.1f}")
    lines.append(f"wrong trends, current:   {list(cur.wrong_trends) or 'none'}")
    lines.append(f"wrong trends, candidate: {list(new.wrong_trends) or 'none'}")
    lines.append(f"candidate shape ({best.pitch_damping}): "
                 + ", ".join(f"{k} = {v:.4g}" for k, v in best.params.items()))
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path, required=True,
                        help="JSON-lines file of all evaluations (appended; resumes)")
    parser.add_argument("--candidate", type=Path, help="write the best wing here (YAML)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-random", type=int, default=200)
    parser.add_argument("--max-evaluations", type=int, help="budget of new evaluations")
    parser.add_argument("--max-seconds", type=float, help="wall-time budget [s]")
    parser.add_argument("--restarts", type=int, default=8)
    parser.add_argument("--local-iterations", type=int, default=150)
    parser.add_argument("--variants", nargs="+", default=list(wc.PITCH_DAMPING_VARIANTS),
                        choices=wc.PITCH_DAMPING_VARIANTS)
    parser.add_argument("--start", action="append", default=[], metavar="NAME=VALUE,...",
                        help="also start from the reference shape with these parameters "
                             "changed, e.g. ea_frac=0.2,freq_ratio=1.2 (repeatable)")
    parser.add_argument("--no-final-check", action="store_true",
                        help="skip re-evaluating the best with the exact design settings")
    args = parser.parse_args(argv)

    reference = load_wing(reference_wing_path())  # the calibration starts from the first wing
    history = read_checkpoint(args.checkpoint)
    args.checkpoint.parent.mkdir(parents=True, exist_ok=True)
    print(f"checkpoint {args.checkpoint}: {len(history)} earlier evaluations", flush=True)
    t0 = time.perf_counter()
    state = {"count": 0, "best": math.inf}

    def on_evaluation(e: wc.Evaluation, best: wc.Evaluation, fresh: bool) -> None:
        state["count"] += 1
        if fresh:
            with open(args.checkpoint, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(e.to_dict()) + "\n")
        if fresh or state["count"] % 50 == 0:
            trends = len(e.wrong_trends) if e.ratios else "-"
            print(f"{state['count']:5d} {time.perf_counter() - t0:7.0f}s {e.phase:9s} "
                  f"{e.pitch_damping:12s} cost {e.cost:10.1f} max|err| {e.max_error:6.3f} "
                  f"wrong trends {trends}  | best {best.cost:8.1f} "
                  f"(max|err| {best.max_error:.3f}, {len(best.wrong_trends)} wrong)"
                  + (f"  {e.note}" if e.note else ""), flush=True)
        if best.cost < state["best"]:
            state["best"] = best.cost
            if args.candidate is not None and best.ratios:
                write_candidate(args.candidate, best, reference,
                                "Calibration candidate (scripts/calibrate_reference_wing.py), "
                                f"cost {best.cost:.1f} (fast settings)")

    base = wc.params_from_wing(reference.wing)
    starts = [(base, reference.aero.pitch_damping)]
    for text in args.start:
        changes = dict(item.split("=", 1) for item in text.split(","))
        unknown = sorted(set(changes) - set(wc.NAMES))
        if unknown:
            parser.error(f"--start: unknown parameters {unknown} (known: {list(wc.NAMES)})")
        starts.append(({**base, **{k: float(v) for k, v in changes.items()}},
                       reference.aero.pitch_damping))
    done = wc.search(seed=args.seed, n_random=args.n_random,
                     max_evaluations=args.max_evaluations, max_seconds=args.max_seconds,
                     history=history, starts=starts, on_evaluation=on_evaluation,
                     variants=tuple(args.variants), local_iterations=args.local_iterations,
                     restarts=args.restarts)
    best = min(done, key=lambda e: e.cost)
    print(f"{len(done)} candidates, best cost {best.cost:.1f}", flush=True)
    if args.no_final_check or not best.ratios:
        return 0
    exact = wc.evaluate(best.params, best.pitch_damping, fast=False, phase="final")
    current = wc.study_ratios(reference.wing, reference.aero, fast=False)
    text = report(exact, current)
    print(text, flush=True)
    if args.candidate is not None:
        write_candidate(args.candidate, exact, reference,
                        "Calibration candidate (scripts/calibrate_reference_wing.py), exact "
                        "design settings:\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
