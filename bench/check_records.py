"""Do two ``dva evaluate`` directories hold the same records? (a check, not a timing)

Run:  .venv/bin/python bench/check_records.py BASE_DIR NEW_DIR [--rtol 1e-9]

Compares every flight of ``records.json`` (matched by controller, case and seed), field by
field, and the stability boundaries of ``results.json``, number by number: two values agree
when ``|a - b| <= rtol * max(|a|, |b|)`` (NaN/None only with NaN/None). Prints the largest
relative difference per controller and exits 1 when any value differs by more, when a flight
is in one directory only, or when a field of the base's records is missing from the new ones.
A field only the new records have is a measure added since (listed, not a difference). A
refactoring that must not change the numerics is run on the revision before it and after it
with the same inputs (``--schedule``, ``--network``, ``--fixed-c2``), and this says whether it
did; ``--controllers`` and ``--fields`` narrow the comparison to what did not change by design.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path


def _numbers(value, path=""):
    """(path, number or None) of every number in a JSON value (wall times and paths left out)."""
    if isinstance(value, dict):
        for key, item in value.items():
            if "wall_time" in key or key in ("gains", "out", "files", "inputs", "scenario"):
                continue
            yield from _numbers(item, f"{path}.{key}")
    elif isinstance(value, list):
        for k, item in enumerate(value):
            yield from _numbers(item, f"{path}[{k}]")
    elif value is None or (isinstance(value, (int, float)) and not isinstance(value, bool)):
        yield path, value


def _relative(a, b) -> float:
    if a is None or b is None or (isinstance(a, float) and math.isnan(a)) or \
            (isinstance(b, float) and math.isnan(b)):
        both = (a is None or math.isnan(a)) and (b is None or math.isnan(b))
        return 0.0 if both else math.inf
    scale = max(abs(a), abs(b))
    return 0.0 if scale == 0 else abs(a - b) / scale


def compare(base: Path, new: Path, controllers=None, fields=None
            ) -> tuple[dict[str, float], list[str], set[str]]:
    """Largest relative difference per controller (and for the boundaries), what is missing,
    and the record fields only the new records have."""
    worst: dict[str, float] = {}
    missing: list[str] = []
    added: set[str] = set()

    def keyed(path):
        rows = json.loads((path / "records.json").read_text())
        return {(r["controller"], r["case"], r["seed"]): r for r in rows
                if controllers is None or r["controller"] in controllers}

    a, b = keyed(base), keyed(new)
    missing += [f"{k} only in {base}" for k in a.keys() - b.keys()]
    missing += [f"{k} only in {new}" for k in b.keys() - a.keys()]
    for key in a.keys() & b.keys():
        xs = {p: v for p, v in _numbers(a[key]) if fields is None or p.lstrip(".") in fields}
        ys = {p: v for p, v in _numbers(b[key]) if fields is None or p.lstrip(".") in fields}
        missing += [f"field {p} of {key} only in {base}" for p in xs.keys() - ys.keys()]
        added |= {p.lstrip(".") for p in ys.keys() - xs.keys()}
        for p in xs.keys() & ys.keys():
            worst[key[0]] = max(worst.get(key[0], 0.0), _relative(xs[p], ys[p]))
    ra, rb = (json.loads((p / "results.json").read_text()) for p in (base, new))
    for section in ("boundaries",):
        if section in ra or section in rb:
            if section not in ra or section not in rb:
                missing.append(f"section {section!r} in one results.json only")
                continue
            xs, ys = dict(_numbers(ra[section])), dict(_numbers(rb[section]))
            missing += [f"{section}{p} in one results.json only" for p in xs.keys() ^ ys.keys()]
            for p in xs.keys() & ys.keys():
                worst[section] = max(worst.get(section, 0.0), _relative(xs[p], ys[p]))
    return worst, missing, added


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--rtol", type=float, default=1e-9)
    parser.add_argument("--controllers", default=None,
                        help="compare these controllers' flights only (comma-separated)")
    parser.add_argument("--fields", default=None,
                        help="compare these record fields only (comma-separated)")
    args = parser.parse_args()

    def chosen(text):
        return None if text is None else {v.strip() for v in text.split(",") if v.strip()}

    worst, missing, added = compare(args.base, args.new, chosen(args.controllers),
                                    chosen(args.fields))
    for name, value in sorted(worst.items()):
        verdict = "ok" if value <= args.rtol else "DIFFERS"
        print(f"{name:16s} largest relative difference {value:.3g} ({verdict})")
    for line in missing:
        print(f"missing: {line}")
    if added:
        print(f"fields only in {args.new} (measures added): {', '.join(sorted(added))}")
    bad = missing or any(v > args.rtol for v in worst.values())
    print("records differ" if bad else f"records equal to {args.rtol:g}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
