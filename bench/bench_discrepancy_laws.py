"""Effects whose law is outside the library's forms, and files with no effect: rates over seeds.

Usage::

    PYTHONPATH=offline python bench/bench_discrepancy_laws.py [--cases N] [--seed0 S]
        [--only CASE,CASE] [--no-laws] [--max-steps K] [--log FILE.jsonl]

For every case of :mod:`dva_offline.discrepancy.synthetic_laws` (default 40 seeds from 3000,
seeds no test uses) it runs the whole loop (``frf`` or ``modal`` as a user would) and prints:

* ``right``: for a case with an expected name (``EXPECTED``), the verdict ``explained`` with
  that effect; for a phase-only distortion, no ``sensor_delay`` named or added; for a file
  with no effect, ``consistent`` or ``no_covariate_effect``;
* ``recovers``: (baseline error - final error) / (baseline error - per-condition error), the
  held-out errors of the pooled baseline, the loop's final model and the baseline fitted to
  each condition alone (the saturated reference): the share of what the per-condition fits
  reach that the final model reaches (median, lowest, and how many cases reach >= 90 %);
* the laws chosen for the hidden coordinate and, for power laws, the fitted exponent against
  the hidden one.

``--no-laws`` runs the loop without the laws (the library's fixed forms only), for the
before/after on the same cases. Not a timed test: the machine is shared.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter

import numpy as np
from tqdm import tqdm

from dva_offline.discrepancy import loop, synthetic_laws
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.discrepancy.modal_domain import ModalDomain, to_receptance
from dva_offline.isolator.frf_data import split_conditions


def run_case(case: str, seed: int, laws: bool = True, max_steps: int = 12):
    """(generated case, domain, result) of the whole loop on one case."""
    c = synthetic_laws.generate(case, np.random.default_rng(seed))
    cov = [k for k in c.covariates if k != "set"] or None
    if synthetic_laws.domain_of(case) == "modal":
        rec = to_receptance(c.frequency_hz, c.values, c.quantity)
        conds = split_conditions(c.frequency_hz, rec, "receptance", c.covariates,
                                 list(c.condition_columns))
        dom = ModalDomain(conds, quantity=c.quantity, covariates=cov)
    else:
        conds = split_conditions(c.frequency_hz, c.values, c.quantity, c.covariates,
                                 list(c.condition_columns))
        dom = FrfDomain(conds, mass=c.mass, static_stiffness=c.static_stiffness, covariates=cov)
    rule = loop.DecisionRule(max_steps=max_steps, covariate_laws=laws)
    return c, dom, loop.run(dom, rule=rule)


def right(case: str, res) -> bool:
    """The per-case criterion (module docstring)."""
    v = res.verdict
    expected = synthetic_laws.EXPECTED[case]
    if case in synthetic_laws.NO_EFFECT:
        return v.status in ("consistent", "no_covariate_effect")
    if expected is None:  # a phase-only distortion: never a delay
        return v.effect != "sensor_delay" and all(s.effect != "sensor_delay"
                                                  for s in res.steps)
    return v.status == "explained" and v.effect == expected


def recovery(res) -> float:
    """(baseline - final) / (baseline - per-condition) held-out error; NaN without them."""
    ref, fin = res.reference, res.final
    if ref is None or fin is None or not res.baseline.error > ref.error:
        return np.nan
    return (res.baseline.error - fin.error) / (res.baseline.error - ref.error)


def law_summary(case: str, c, res) -> dict:
    """The laws of the named effect's law step and, for power laws, the fitted exponents
    against the hidden ones."""
    step = next((s for s in res.steps if getattr(s.fit, "law", None) is not None), None)
    out = {"laws": {}, "exponents": []}
    if step is None:
        return out
    law = step.fit.law
    est = {e.name: e for e in step.fit.estimates}
    for p in law.parts:
        out["laws"][p.coordinate] = p.law
    truth = []
    if case == "power_level":
        truth = [("storage", c.parameters["exponent"])]
        if c.parameters["loss_change"]:
            truth.append(("loss", c.parameters["loss_exponent"]))
    elif case == "structure_power_level":
        truth = [(f"mode {m['mode']} stiffness", m["exponent"]) for m in c.parameters["modes"]]
    for coord, e_true in truth:
        part = next((p for p in law.parts if p.coordinate == coord), None)
        if part is not None and part.law == "power_change":
            e = est[part.names[1]]
            out["exponents"].append({"coordinate": coord, "true": e_true, "fitted": e.value,
                                     "std": e.std})
        else:
            out["exponents"].append({"coordinate": coord, "true": e_true,
                                     "law": part.law if part is not None else None})
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=40)
    parser.add_argument("--seed0", type=int, default=3000)
    parser.add_argument("--only", default=",".join(synthetic_laws.CASES))
    parser.add_argument("--no-laws", action="store_true",
                        help="the library's fixed forms only (the loop before the laws)")
    parser.add_argument("--max-steps", type=int, default=loop.DecisionRule.max_steps)
    parser.add_argument("--log", default=None)
    args = parser.parse_args(argv)
    cases = [c.strip() for c in args.only.split(",") if c.strip()]
    unknown = set(cases) - set(synthetic_laws.CASES)
    if unknown:
        parser.error(f"unknown cases {sorted(unknown)}; choose from {synthetic_laws.CASES}")
    log = open(args.log, "w") if args.log else None  # noqa: SIM115 (closed below)
    seeds = range(args.seed0, args.seed0 + args.cases)
    print(f"seeds {seeds.start}..{seeds.stop - 1}, {args.cases} cases per row, laws "
          f"{'off' if args.no_laws else 'on'}")
    print(f"{'case':24s} {'right':>7s}  {'recovers: median':>16s} {'lowest':>7s} {'>=0.9':>6s}"
          f"  {'|de| median':>11s}  {'s/case':>6s}  verdicts; laws")
    try:
        for case in cases:
            ok, rec, de, total = 0, [], [], 0.0
            verdicts, chosen = Counter(), Counter()
            for seed in tqdm(seeds, desc=case, file=sys.stderr, leave=False):
                start = time.perf_counter()
                c, dom, res = run_case(case, seed, not args.no_laws, args.max_steps)
                dt = time.perf_counter() - start
                total += dt
                v = res.verdict
                good = right(case, res)
                ok += good
                verdicts[f"{v.status}:{v.effect}" if v.effect else v.status] += 1
                r = recovery(res)
                if synthetic_laws.EXPECTED[case] is not None:
                    rec.append(r)
                laws = law_summary(case, c, res)
                chosen.update(laws["laws"].values())
                de += [abs(e["fitted"] - e["true"]) for e in laws["exponents"] if "fitted" in e]
                if log:
                    log.write(json.dumps({
                        "case": case, "seed": seed, "sigma": c.sigma, "truth": c.parameters,
                        "status": v.status, "named": v.effect, "label": v.label,
                        "right": good, "recovery": r, "baseline_error": res.baseline.error,
                        "reference_error": None if res.reference is None else
                        res.reference.error,
                        "final_error": None if res.final is None else res.final.error,
                        "noise_floor": res.noise.sigma,
                        "steps": [[s.effect, s.label, s.error_before, s.error_after,
                                   s.fit.law.describe(s.fit)
                                   if getattr(s.fit, "law", None) else None]
                                  for s in res.steps],
                        "implausible": [[x.effect, x.reason] for x in res.candidates
                                        if getattr(x, "implausible", False)],
                        "laws": laws, "seconds": dt}, default=float) + "\n")
                    log.flush()
            rec_ok = [x for x in rec if np.isfinite(x)]
            med = f"{np.median(rec_ok):.3f}" if rec_ok else "-"
            low = f"{min(rec_ok):.3f}" if rec_ok else "-"
            reach = f"{sum(x >= 0.9 for x in rec_ok)}/{len(rec)}" if rec else "-"
            dem = f"{np.median(de):.3f}" if de else "-"
            print(f"{case:24s} {ok:3d}/{args.cases:<3d}  {med:>16s} {low:>7s} {reach:>6s}  "
                  f"{dem:>11s}  {total / args.cases:6.2f}  {dict(verdicts)}; {dict(chosen)}",
                  flush=True)
    finally:
        if log:
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
