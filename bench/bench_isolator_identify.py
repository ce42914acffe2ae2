"""Benchmark: default ``dva isolator identify`` on random Maxwell-Voigt systems (issue #18).

Each case draws a system (m = 1 kg, k, c and one Maxwell element; zeta uniform in 0.05-0.45,
w_n in 5-35 Hz), computes its FRF at 400 points over 1-60 Hz, multiplies it by (1 + alpha)
with complex Gaussian alpha of RMS ``noise``, writes it as CSV or UFF 58, and runs the CLI
(``identify FILE --quantity Q --mass 1 --static-stiffness k --json``, default: up to 2
elements, w_n and zeta from the unconstrained fit). Rows: noise x quantity x format, plus the
half-power estimate (``--modal-estimate half-power``, the former default) for comparison and
two rows where the static stiffness given is 2 % off the truth.

Columns: FRF error against the data / noise (median, 95th percentile), |w_n error| and
|zeta error| relative to the truth [%] (median, 95th percentile), the share of cases meeting
all of FRF error <= 2 x noise, |w_n error| <= 0.5 %, |zeta error| <= 2 %, and refusals.

Run: .venv/bin/python bench/bench_isolator_identify.py --cases 50 --seed 0
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from dva_offline import cli
from dva_offline.isolator import files as isolator_files
from dva_offline.isolator.maxwell_model import frf, modal_properties
from dva_offline.isolator.synthetic_systems import add_complex_noise, random_mv_system

F_HZ = np.linspace(1.0, 60.0, 400)
NOISES = (0.001, 0.005, 0.01, 0.02)


def run_case(rng, noise, quantity, fmt, workdir: Path, extra=(), k_factor=1.0) -> dict:
    """One random system through the CLI; returns errors against the truth or the refusal."""
    system = random_mv_system(rng)
    true = modal_properties(system)
    h = add_complex_noise(frf(system, 2 * np.pi * F_HZ, quantity), noise, rng)
    path = workdir / ("frf.uff" if fmt == "uff58" else "frf.csv")
    if fmt == "uff58":
        isolator_files.write_uff58(path, F_HZ, h, quantity)
    else:
        isolator_files.write_frf_csv(path, F_HZ, h)
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli.main(["isolator", "identify", str(path), "--quantity", quantity,
                             "--mass", "1", "--static-stiffness", repr(k_factor * system.k),
                             "--json", *extra])
        except Exception as exc:  # a crash is a failure of the case, reported as refused
            code = 1
            print(f"crash: {exc!r}", file=err)
    seconds = time.perf_counter() - t0
    row = {"zeta": true.damping_ratio, "seconds": seconds}
    if code != 0:
        return {**row, "refused": err.getvalue().strip()}
    payload = json.loads(out.getvalue())
    wn, zeta = payload["natural_frequency_rad_s"], payload["damping_ratio"]
    return {
        **row,
        "refused": None,
        "frf_ratio": payload["frf_error"] / noise,
        "wn_err": 100 * (wn / true.natural_frequency_rad_s - 1),
        "zeta_err": 100 * (zeta / true.damping_ratio - 1),
        "n_elements": payload["n_elements"],
    }


def summarise(label, cases) -> str:
    done = [c for c in cases if c["refused"] is None]
    refused = len(cases) - len(done)
    if not done:
        return f"| {label} | {len(cases)} | - | - | - | - | {refused} |"
    ratio = np.array([c["frf_ratio"] for c in done])
    ew = np.abs([c["wn_err"] for c in done])
    ez = np.abs([c["zeta_err"] for c in done])
    ok = (ratio <= 2) & (ew <= 0.5) & (ez <= 2)
    share = ok.sum() / len(cases)  # refusals count as failures

    def q(a):
        return f"{np.median(a):.3g} / {np.percentile(a, 95):.3g}"

    return (f"| {label} | {len(cases)} | {q(ratio)} | {q(ew)} | {q(ez)} | "
            f"{100 * share:.0f} % | {refused} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=50, help="random systems per row")
    parser.add_argument("--seed", type=int, default=0, help="numpy.random.default_rng seed")
    args = parser.parse_args()
    if args.cases < 1:
        parser.error("--cases must be >= 1")
    rng = np.random.default_rng(args.seed)
    rows = [(f"{100 * s:g} % | {q} | {f} | fit", s, q, f, (), 1.0)
            for s in NOISES for q in ("receptance", "accelerance") for f in ("csv", "uff58")]
    rows.append(("0.5 % | receptance | csv | half-power", 0.005, "receptance", "csv",
                 ("--modal-estimate", "half-power"), 1.0))
    # Sensitivity: the static stiffness passed is 2 % off the truth (a static test's error).
    for sign in (1, -1):
        rows.append((f"0.5 % | receptance | csv | fit, static stiffness {sign * 2:+d} %", 0.005,
                     "receptance", "csv", (), 1.0 + sign * 0.02))
    lines, times, refusals = [], [], {}
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, tqdm(total=len(rows) * args.cases,
                                                    desc="identify") as bar:
        for label, noise, quantity, fmt, extra, k_factor in rows:
            cases = []
            for _ in range(args.cases):
                cases.append(run_case(rng, noise, quantity, fmt, Path(tmp), extra, k_factor))
                bar.update()
            times += [c["seconds"] for c in cases]
            lines.append(summarise(label, cases))
            for c in cases:
                if c["refused"] is not None:
                    reason = c["refused"].split(": ")[-1][:90]
                    refusals[(label, reason)] = refusals.get((label, reason), 0) + 1
    wall = time.perf_counter() - t_start
    print(f"\n{args.cases} random M-V systems per row (zeta 0.05-0.45, w_n 5-35 Hz), 400 "
          f"points 1-60 Hz, seed {args.seed}; median / 95th percentile")
    print("| noise | quantity | format | w_n, zeta from | cases | FRF error / noise | "
          "abs w_n error % | abs zeta error % | within 2x noise, 0.5 %, 2 % | refused |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(lines))
    for (label, reason), count in refusals.items():
        print(f"refused {count}x in row '{label}': {reason}")
    print(f"\nCLI time per case (in-process, file read + fit): median {np.median(times):.2f} s, "
          f"max {np.max(times):.2f} s; total {wall:.0f} s on this machine")


if __name__ == "__main__":
    main()
