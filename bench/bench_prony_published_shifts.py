"""How well a Prony spectrum fits the tension DMA export under given shift factors.

Held-out error (every 4th point of each temperature step from index 2, the loop's split) of a
Prony spectrum (two time constants per decade, non-negative moduli on the training points)
with the shift factors of a file in tests/data/discrepancy/ held fixed, and with a free
vertical factor per step added (fitted by least squares). Shows whether a set of published
shift factors can make a master curve of this export at all.

    PYTHONPATH=offline python bench/bench_prony_published_shifts.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from dva_offline.discrepancy.prony_spectrum import (
    nonnegative_moduli,
    prony_columns,
    relaxation_times,
)

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "discrepancy"


def main() -> None:
    raw = np.genfromtxt(DATA / "dma_tension_raw.csv", delimiter=",", skip_header=2)
    f, e_stor, e_loss, _, step = raw.T
    step = step.astype(int)
    y = (e_stor + 1j * e_loss) * 1e6
    weights = 1.0 / np.abs(y)
    held = np.zeros(f.size, bool)
    for s in np.unique(step):
        held[np.flatnonzero(step == s)[2::4]] = True
    train = ~held
    for name in ("pyvisco_tension_shift_factors.csv", "pyvisco_tension_get_aT.csv"):
        ref = np.genfromtxt(DATA / name, delimiter=",", skip_header=2, encoding="utf-8-sig")
        log_a = ref[np.argsort(ref[:, 0]), 1][step]
        taus = relaxation_times(np.log10(f * 10**log_a), 2.0)
        cols = prony_columns(2 * np.pi * f * 10**log_a, taus)

        def predict(log_b, cols=cols):
            scaled = cols * 10 ** np.concatenate([[0.0], log_b])[step][:, None]
            return scaled @ nonnegative_moduli(scaled, y, weights, train)

        def error(pred, points):
            return float(np.sqrt(np.mean(np.abs((pred - y)[points] * weights[points]) ** 2)))

        fixed = predict(np.zeros(20))

        def resid(v):
            r = ((predict(v) - y) * weights)[train]
            return np.concatenate([r.real, r.imag])

        vertical = least_squares(resid, np.zeros(20), method="lm").x
        print(f"{name}: held-out error {error(fixed, held):.4f} with these shifts; "
              f"{error(predict(vertical), held):.4f} with a free vertical factor per step "
              f"(log10 from {vertical.min():.3f} to {vertical.max():.3f})")


if __name__ == "__main__":
    main()
