"""CPU time of the flight-log domain's modal simulation: the compiled pass
(``modal_simulator.simulate``) against the vectorised NumPy reference (``simulate_vectorised``),
timed alternately in this run, with the largest difference between them.

Usage::

    .venv/bin/python bench/bench_modal_simulator.py [--repeats 20] [--conditions 40]

The case is the size of the flight acceptance's flights: 48 s at 1 kHz in blocks of 50 samples
(960 blocks) of the reference wing, each block held at one of ``--conditions`` airspeed/c2
pairs, three acceleration outputs, a random force.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from aero_dva.flight.modal_simulator import ModalBlocks, simulate, simulate_vectorised
from aero_dva.wing.model import AeroelasticModel
from aero_dva.wing.wing_io import load_wing


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--conditions", type=int, default=40)
    args = parser.parse_args()
    wing = load_wing(None)
    model = AeroelasticModel(wing.wing, wing.maxwell_design, wing.aero)
    rng = np.random.default_rng(0)
    k, block, n = args.conditions, 50, 48_000
    a, b = model.matrices(rng.uniform(40.0, 90.0, k), np.full(k, 1.2),
                          rng.uniform(100.0, 1500.0, k))
    c, d = model.acceleration_output(a, b)
    modes = ModalBlocks(a, b, c[:, :3], d[:, :3], 1e-3)
    condition = np.repeat(rng.integers(0, k, n // block // 8), 8)  # held for 8 blocks
    force = 1000.0 * rng.standard_normal(n)
    simulate(modes, condition, force, block)  # compile (or load the cached machine code)
    times = {"compiled": [], "vectorised": []}
    for _ in range(args.repeats):
        for name, fn in (("compiled", simulate), ("vectorised", simulate_vectorised)):
            t0 = time.process_time()
            y = fn(modes, condition, force, block)
            times[name].append(time.process_time() - t0)
    ref = simulate_vectorised(modes, condition, force, block)
    diff = np.max(np.abs(simulate(modes, condition, force, block) - ref)
                  / np.abs(ref).max(axis=1, keepdims=True))
    best = {name: min(t) for name, t in times.items()}
    print(f"48 s flight, {k} conditions, {y.shape[0]} outputs, best of {args.repeats} (CPU):")
    print(f"  vectorised (reference) {1e3 * best['vectorised']:8.2f} ms")
    print(f"  compiled               {1e3 * best['compiled']:8.2f} ms   "
          f"ratio {best['vectorised'] / best['compiled']:.1f}x")
    print(f"  largest difference {diff:.1e} of each output's peak")


if __name__ == "__main__":
    main()
