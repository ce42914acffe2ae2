"""The measured data sets of the tests, run as the tests run them: verdict, recovery, plausibility.

Usage::

    PYTHONPATH=offline python bench/bench_discrepancy_real.py [--only NAME,NAME] [--log FILE]

For every measured set of ``tests/unit/dva_offline/discrepancy/test_real_data.py`` (the same
command line, through the CLI with ``--json``) it prints the verdict against the one the
physics leads one to expect (tests/data/discrepancy/real/README.md), the held-out errors of
the pooled baseline, of the per-condition fits (the saturated reference) and of the final
model, the share of the per-condition fits' improvement the final model recovers
((baseline - final) / (baseline - per-condition)), and the candidates listed implausible (never
added) with the check that no step added one of them. Not a timed test.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
from pathlib import Path

from tqdm import tqdm

from dva_offline import cli

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "discrepancy"
REAL = DATA / "real"
MELT = ["--quantity", "modulus", "--columns", "f=omega,real=G_stor,imag=G_loss,temperature_c=T",
        "--group-by", "set"]
# name: (command after ``dva``, expected (status, effect); effect None: no covariate effect)
SETS = {
    "dma_tension": (["discrepancy", "frf", str(DATA / "dma_tension_raw.csv"), "--quantity",
                     "modulus", "--columns", "f=f,real=E_stor,imag=E_loss,temperature_c=T",
                     "--group-by", "Set"], ("explained", "covariate_shift")),
    "dma_shear": (["discrepancy", "frf", str(DATA / "dma_shear_eplexor.csv"), "--quantity",
                   "modulus", "--columns", "f=f,real=G',imag=G'',temperature_c=T",
                   "--covariates", "temperature_c", "--max-steps", "2"],
                  ("explained", "covariate_shift")),
    "brb_response": (["discrepancy", "modal", str(REAL / "brb_response_control.csv"),
                      "--quantity", "accelerance", "--group-by", "level", "--covariates",
                      "response_amplitude_ms2", "--max-steps", "1"],
                     ("explained", "amplitude_dependence")),
    "brb_force": (["discrepancy", "modal", str(REAL / "brb_force_control.csv"), "--quantity",
                   "accelerance", "--group-by", "level", "--covariates", "force_n",
                   "--max-steps", "2"], ("explained", "amplitude_dependence")),
    "impact_hits": (["discrepancy", "modal", str(REAL / "impact_hits_pyfrf.csv"), "--quantity",
                     "accelerance", "--group-by", "hit", "--covariates", "force_peak_n"],
                    ("no_covariate_effect", None)),
    "pi88k": (["discrepancy", "frf", str(REAL / "pi88k_melt_reptate.csv"), *MELT,
               "--max-steps", "1"], ("explained", "covariate_shift")),
    "pi33k": (["discrepancy", "frf", str(REAL / "pi33k_melt_reptate.csv"), *MELT,
               "--covariates", "temperature_c"], ("explained", "covariate_shift")),
    "pi1000k": (["discrepancy", "frf", str(REAL / "pi1000k_repeats_reptate.csv"), *MELT,
                 "--replicates", "T_set", "--max-steps", "1"], (None, None)),
}
COVARIATE_EFFECTS = ("amplitude_dependence", "covariate_shift")


def run(args: list[str]) -> dict:
    """The CLI's JSON report of one command (its exit code must be 0)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = cli.main([*args, "--json"])
    if code != 0:
        raise RuntimeError(f"dva {' '.join(args)} exited {code}")
    return json.loads(out.getvalue())


def summary(name: str, out: dict) -> dict:
    status, effect = SETS[name][1]
    v = out["verdict"]
    if status is None:  # no covariate effect: no covariate effect named or even applicable
        right = v["effect"] not in COVARIATE_EFFECTS and not any(
            c["applicable"] for c in out["candidates"] if c["effect"] in COVARIATE_EFFECTS)
    else:
        right = (v["status"], v["effect"]) == (status, effect)
    base = out["baseline"]["error"]
    ref = out.get("saturated_reference") or {}
    final = (out.get("final") or {}).get("error")
    if final is None:
        final = (out.get("augmented") or {}).get("error", base)
    recovery = None
    if v["effect"] in COVARIATE_EFFECTS and ref.get("error") is not None and base > ref["error"]:
        recovery = (base - final) / (base - ref["error"])
    odd = [(c["effect"], c["form"], c["reason"]) for c in out["candidates"]
           if c.get("implausible")]
    added = [(s["effect"], s["form"]) for s in out.get("steps", [])]
    return {"set": name, "status": v["status"], "effect": v["effect"], "form": v.get("form"),
            "right": right, "baseline": base, "per_condition": ref.get("error"),
            "reference_used": ref.get("used"), "final": final, "recovery": recovery,
            "noise": out["noise_floor"]["sigma"], "steps": added, "implausible": odd,
            "implausible_added": any((e, f) in added for e, f, _ in odd)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=",".join(SETS))
    parser.add_argument("--log", default=None, help="one JSON line per set")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    unknown = set(names) - set(SETS)
    if unknown:
        parser.error(f"unknown sets {sorted(unknown)}; choose from {list(SETS)}")
    print(f"{'set':13s} {'right':5s} {'verdict':38s} {'baseline':>8s} {'per-cond':>8s} "
          f"{'final':>8s} {'recovers':>8s}  {'s':>5s}  implausible (added?)")
    log = open(args.log, "w") if args.log else None  # noqa: SIM115 (closed below)
    try:
        for name in tqdm(names, file=sys.stderr, leave=False):
            start = time.perf_counter()
            s = summary(name, run(SETS[name][0]))
            s["seconds"] = time.perf_counter() - start
            verdict = f"{s['status']}:{s['effect']}" + (f" ({s['form']})" if s["form"] else "")
            pc = "-" if s["per_condition"] is None else f"{s['per_condition']:.4f}"
            rec = "-" if s["recovery"] is None else f"{100 * s['recovery']:.0f} %"
            odd = "; ".join(f"{e} ({f})" for e, f, _ in s["implausible"]) or "none"
            print(f"{name:13s} {str(s['right']):5s} {verdict:38s} {s['baseline']:8.4f} {pc:>8s} "
                  f"{s['final']:8.4f} {rec:>8s}  {s['seconds']:5.0f}  {odd} "
                  f"({'ADDED' if s['implausible_added'] else 'none added'})", flush=True)
            if log:
                log.write(json.dumps(s) + "\n")
                log.flush()
    finally:
        if log:
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
