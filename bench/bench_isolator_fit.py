"""Benchmark: M-M-V identification of Table 4.1 System F from 300 FRF points (section 4.3).

Compares, in the same run, the constrained SLSQP fit (eq. 4.11-4.12, scaled log-parameters,
analytic gradients; all initial guesses, and only the first one) with a plain
``scipy.optimize.least_squares`` fit of the same residuals without the natural-frequency /
damping-ratio constraints. Prints wall times (median of repeats), their ratio, and FRF errors
against the noise-free system.

Run: .venv/bin/python bench/bench_isolator_fit.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from dva_offline.isolator.maxwell_fit import (
    FitWarning,
    add_frf_noise,
    fit_maxwell_model,
    fit_unconstrained_least_squares,
    initial_guesses,
)
from dva_offline.isolator.maxwell_model import MaxwellModel, frf, modal_properties
from dva_offline.isolator.mv_curves import frf_error


def timed(fn, repeats, *fn_args, **fn_kwargs):
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn(*fn_args, **fn_kwargs)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    system = MaxwellModel(1.0, 12e3, 40.0, (12e3, 24e3), (80.0, 2000.0))
    modal = modal_properties(system)
    omega = np.linspace(0.0, 300.0, 300)
    h0 = frf(system, omega)
    print(f"System F: w_n = {modal.natural_frequency_rad_s:.3f} rad/s, "
          f"zeta = {modal.damping_ratio:.4f}; 300 points, 0-300 rad/s; "
          f"median of {args.repeats} repeats")
    print(f"{'sigma':>6} {'method':>14} {'time [s]':>9} {'FRF err':>9} {'constraint':>10}")
    for sigma in (0.0, 0.01, 0.05):
        h = add_frf_noise(h0, sigma, np.random.default_rng(args.seed))
        fit_args = (omega, h, 1.0, 12e3, 2, modal.natural_frequency_rad_s, modal.damping_ratio)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitWarning)
            first = initial_guesses(1.0, 12e3, 2, *fit_args[-2:])[:1]
            t_sqp, sqp = timed(fit_maxwell_model, args.repeats, *fit_args)
            t_one, one = timed(fit_maxwell_model, args.repeats, *fit_args, initial=first)
            t_ls, ls = timed(fit_unconstrained_least_squares, args.repeats, *fit_args)
        for name, t, fit in (("slsqp", t_sqp, sqp), ("slsqp 1 start", t_one, one),
                             ("least_squares", t_ls, ls)):
            err = frf_error(frf(fit.model, omega), h0)
            print(f"{sigma:6.2f} {name:>14} {t:9.3f} {err:9.2e} {fit.constraint_error:10.1e}")
        print(f"{'':6} {'ratio':>14} {t_sqp / t_ls:9.2f}  (slsqp / least_squares; "
              f"1 start: {t_one / t_ls:.2f})")


if __name__ == "__main__":
    main()
