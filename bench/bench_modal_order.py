"""CPU time and chosen order of the modal baseline (``ModalDomain.baseline``) on three generated
structures (3 modes; seed 2 clean, seeds 3 and 4 with one mode softening with the level).

Usage::

    PYTHONPATH=offline python bench/bench_modal_order.py LABEL

Run it once with PYTHONPATH pointing at another revision's ``offline`` to compare (CPU time of
this process's fits; the machine is shared, read runs made side by side).
"""
import sys
import time

import numpy as np

from dva_offline.discrepancy import loop, structure_synthetic
from dva_offline.discrepancy.modal_domain import ModalDomain, to_receptance
from dva_offline.isolator.frf_data import split_conditions


def main(label: str) -> None:
    total, orders = 0.0, []
    for seed in (2, 3, 4):
        effect = None if seed == 2 else "amplitude_dependence"
        case = structure_synthetic.generate_structure(effect, np.random.default_rng(seed))
        rec = to_receptance(case.frequency_hz, case.values, case.quantity)
        conds = split_conditions(case.frequency_hz, rec, "receptance", case.covariates,
                                 list(case.condition_columns))
        cov = [c for c in case.covariates if c != "set"]
        dom = ModalDomain(conds, quantity=case.quantity, covariates=cov or None)
        split = loop.holdout_split(dom.observations.groups)
        start = time.process_time()
        dom.baseline(split.train)
        total += time.process_time() - start
        orders.append(dom.baseline_order)
    print(label, "baseline CPU s", round(total, 2), "orders", orders)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "this tree")
