"""Detection rates and run time of the discrepancy loop on generated FRF data sets.

Usage: ``PYTHONPATH=offline python bench/bench_discrepancy.py [--max-steps N] [CASES_PER_EFFECT]
[EFFECT ...]`` (``--max-steps 1``: the first step only, the loop as it was before it iterated)

For each effect (the library's, ``none`` for clean data, and the two outside the library) it
generates CASES_PER_EFFECT data sets with seeds 0, 1, ... and prints how often the verdict
names the hidden effect, the median ratio of augmented to baseline held-out error, the
verdict counts and the mean time per case. Not a timed test.
"""
from __future__ import annotations

import sys
import time
from collections import Counter

import numpy as np

from dva_offline.discrepancy import loop, synthetic
from dva_offline.discrepancy.frf_domain import FrfDomain
from dva_offline.isolator.frf_data import split_conditions

EFFECTS = ("none", *synthetic.LIBRARY_EFFECTS, *synthetic.OUTSIDE_EFFECTS)


def run_case(effect, seed, quantity="receptance", clean_covariate=None,
             max_steps=loop.DecisionRule.max_steps):
    case = synthetic.generate_case(effect, np.random.default_rng(seed), quantity=quantity,
                                   clean_covariate=clean_covariate)
    conditions = split_conditions(case.frequency_hz, case.values, quantity, case.covariates,
                                  list(case.condition_columns))
    fixed = case.n_elements if effect == "maxwell_element" else None
    domain = FrfDomain(conditions, mass=case.mass, static_stiffness=case.static_stiffness,
                       elements=fixed)
    return case, loop.run(domain, rule=loop.DecisionRule(max_steps=max_steps))


def main(argv):
    max_steps = loop.DecisionRule.max_steps
    if "--max-steps" in argv:
        at = argv.index("--max-steps")
        max_steps, argv = int(argv[at + 1]), argv[:at] + argv[at + 2:]
    n = int(argv[0]) if argv else 10
    effects = argv[1:] or EFFECTS
    for effect in effects:
        start = time.perf_counter()
        verdicts, ratios, hits = Counter(), [], 0
        for seed in range(n):
            case, res = run_case(None if effect == "none" else effect, seed,
                                 max_steps=max_steps)
            v = res.verdict
            verdicts[f"{v.status}:{v.effect}" if v.effect else v.status] += 1
            if v.effect == case.effect and v.effect is not None:
                hits += 1
                ratios.append(res.augmented.error / res.baseline.error)
        dt = (time.perf_counter() - start) / n
        med = f"{np.median(ratios):.3f}" if ratios else "-"
        print(f"{effect:22s} named {hits:3d}/{n}  median error ratio {med}  "
              f"{dict(verdicts)}  {dt:.2f} s/case", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
