"""Two simultaneous effects and measured-covariate jitter (FRF domain), and structures (modal).

Usage::

    PYTHONPATH=offline python bench/bench_discrepancy_combined.py [--cases N] [--seed0 S]
        [--only pairs|jitter|structure] [--log FILE.jsonl]

Rows:

* ``pair A+B`` (:data:`~dva_offline.discrepancy.synthetic_combined.PAIRS`): both effects named
  among the loop's steps; also how often the verdict is ``explained`` (the loop reached the
  noise) and how many steps named an effect that was not hidden;
* ``jitter E``: one covariate effect with the temperature / level recorded per point as an
  instrument does (drift, scatter, a ``set`` column to group by): named in the verdict and the
  held-out error at least halved by the first step (the single-effect criterion);
* ``structure E`` (modal domain, 3 modes, accelerance, with jitter for the covariate effects):
  the same single-effect criterion; ``structure none``: ``consistent``.

Not a timed test: the machine is shared, times are indicative.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from tqdm import tqdm

from dva_offline.discrepancy import loop, structure_synthetic
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.discrepancy.modal_domain import ModalDomain, to_receptance
from dva_offline.discrepancy.synthetic_combined import PAIRS, generate_combined
from dva_offline.isolator.frf_data import split_conditions


def frf_case(effects, seed, jitter):
    case = generate_combined(effects, np.random.default_rng(seed), jitter=jitter)
    conds = split_conditions(case.frequency_hz, case.values, case.quantity, case.covariates,
                             list(case.condition_columns))
    cov = [c for c in case.covariates if c != "set"]
    dom = FrfDomain(conds, mass=case.mass, static_stiffness=case.static_stiffness,
                    covariates=cov or None)
    return case, loop.run(dom)


def structure_case(effect, seed):
    case = structure_synthetic.generate_structure(effect, np.random.default_rng(seed),
                                                  jitter=effect not in (None, "sensor_delay"))
    rec = to_receptance(case.frequency_hz, case.values, case.quantity)
    conds = split_conditions(case.frequency_hz, rec, "receptance", case.covariates,
                             list(case.condition_columns))
    cov = [c for c in case.covariates if c != "set"]
    dom = ModalDomain(conds, quantity=case.quantity, covariates=cov or None)
    return case, loop.run(dom)


def single_ok(effect, res) -> bool:
    v = res.verdict
    if effect is None:
        return v.status == "consistent"
    return (v.status == "explained" and v.effect == effect
            and res.augmented.error <= 0.5 * res.baseline.error)


def record(kind, effects, seed, case, res, seconds):
    return {"kind": kind, "effects": list(effects), "seed": seed, "sigma": case.sigma,
            "status": res.verdict.status, "named": res.verdict.effect,
            "steps": [[s.effect, s.label, s.error_before, s.error_after] for s in res.steps],
            "final": None if res.final is None else [res.final.status, res.final.error,
                                                     res.final.noise, res.final.reason],
            "baseline_error": res.baseline.error, "noise_floor": res.noise.sigma,
            "seconds": seconds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=20)
    parser.add_argument("--seed0", type=int, default=2000)
    parser.add_argument("--only", choices=("pairs", "jitter", "structure"), default=None)
    parser.add_argument("--log", default=None)
    args = parser.parse_args(argv)
    log = open(args.log, "w") if args.log else None  # noqa: SIM115 (closed below)
    seeds = range(args.seed0, args.seed0 + args.cases)
    print(f"seeds {seeds.start}..{seeds.stop - 1}, {args.cases} cases per row")
    print(f"{'row':44s} {'accepted':>9s}  {'explained':>9s}  {'extra names':>11s}  {'s/case':>6s}")
    rows = []
    if args.only in (None, "pairs"):
        rows += [("pair", p) for p in PAIRS]
    if args.only in (None, "jitter"):
        rows += [("jitter", (e,)) for e in ("covariate_shift", "amplitude_dependence")]
    if args.only in (None, "structure"):
        rows += [("structure", (e,)) for e in (*structure_synthetic.EFFECTS, None)]
    try:
        for kind, effects in rows:
            ok = explained = extra = 0
            total = 0.0
            for seed in tqdm(seeds, desc=f"{kind} {'+'.join(map(str, effects))}",
                             file=sys.stderr, leave=False):
                start = time.perf_counter()
                if kind == "structure":
                    case, res = structure_case(effects[0], seed)
                else:
                    case, res = frf_case(effects, seed, jitter=kind == "jitter")
                dt = time.perf_counter() - start
                total += dt
                named = {s.effect for s in res.steps}
                if kind == "pair":
                    ok += set(effects) <= named
                    extra += bool(named - set(effects))
                else:
                    ok += single_ok(effects[0], res)
                    extra += bool(res.verdict.effect not in (None, effects[0]))
                explained += res.verdict.status == "explained"
                if log:
                    log.write(json.dumps(record(kind, [e or "none" for e in effects], seed,
                                                case, res, dt)) + "\n")
                    log.flush()
            name = f"{kind} {'+'.join(e or 'none' for e in effects)}"
            print(f"{name:44s} {ok:4d}/{args.cases:<4d} {explained:5d}/{args.cases:<4d}"
                  f" {extra:11d}  {total / args.cases:6.2f}", flush=True)
    finally:
        if log:
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
