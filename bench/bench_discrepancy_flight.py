"""Detection rates of the flight-log discrepancy domain on generated flights.

    PYTHONPATH=offline python bench/bench_discrepancy_flight.py [N] [FIRST_SEED] [EFFECT,...]

For every hidden effect (and clean flights, and the outside-library sensor gain error), N
flights (seeds FIRST_SEED..) are generated with :mod:`dva_offline.discrepancy.flight_synthetic`
and recorded through the batch path into MCAP bags, read back and analysed. Prints per case
the verdict and errors, then per effect: verdicts, how often the hidden effect was named, how
often the held-out error was at least halved, the median augmented/baseline error and the
time per case (generation + reading + analysis, and analysis alone).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dva_offline.discrepancy import loop
from dva_offline.discrepancy.flight_domain import FlightDomain, arrays_from_log
from dva_offline.discrepancy.flight_synthetic import (
    LIBRARY_EFFECTS,
    OUTSIDE_EFFECTS,
    generate_flight,
)


def main(argv) -> int:
    from aero_dva.bag.flight_log_io import load_flight_log
    from aero_dva.wing.wing_io import load_wing

    n = int(argv[1]) if len(argv) > 1 else 10
    first = int(argv[2]) if len(argv) > 2 else 0
    effects = argv[3].split(",") if len(argv) > 3 else ["none", *LIBRARY_EFFECTS,
                                                         *OUTSIDE_EFFECTS]
    wing = load_wing(None)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for effect in effects:
            hidden = None if effect == "none" else effect
            for seed in range(first, first + n):
                t0 = time.perf_counter()
                case = generate_flight(hidden, seed, Path(tmp) / f"{effect}_{seed}")
                domain = FlightDomain(arrays_from_log(load_flight_log(case.path)), wing)
                t1 = time.perf_counter()
                res = loop.run(domain, rule=domain.decision_rule)
                t2 = time.perf_counter()
                v = res.verdict
                ratio = (res.augmented.error / res.baseline.error
                         if res.augmented is not None else np.nan)
                rows.append((effect, seed, v.status, v.effect, ratio, t2 - t0, t2 - t1))
                print(f"{effect:16s} seed {seed:3d}: {v.status:11s} {str(v.effect):16s} "
                      f"baseline {res.baseline.error:.4f} noise {res.noise.sigma:.4f} "
                      f"ratio {ratio:.2f}  {t2 - t0:.1f} s  {case.parameters}", flush=True)
    print("\neffect            verdicts                    named  halved  median ratio  s/case"
          "  s/analysis")
    for effect in effects:
        sel = [r for r in rows if r[0] == effect]
        counts = {s: sum(r[2] == s for r in sel) for s in loop.STATUSES}
        named = sum(r[3] == effect for r in sel)
        halved = sum(r[3] == effect and r[4] <= 0.5 for r in sel)
        ratios = [r[4] for r in sel if r[3] == effect]
        med = float(np.median(ratios)) if ratios else float("nan")
        verdicts = ", ".join(f"{k} {v}" for k, v in counts.items() if v)
        print(f"{effect:16s}  {verdicts:26s}  {named:2d}/{len(sel)}  {halved:2d}/{len(sel)}  "
              f"{med:12.2f}  {np.mean([r[5] for r in sel]):6.1f}  "
              f"{np.mean([r[6] for r in sel]):10.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
