"""Shear moduli of the polyisoprene melt PI88k_09 at eight temperatures (RepTate) as one CSV.

Run once: python convert_reptate_pi88k.py DIR_WITH_OSC OUT.csv
Reads RepTate's data/PI_LINEAR/osc/PI88K-09_FS_<T>C_PP-10.osc (a rheometer export: one header
line `T=..;Mw=94.9;...`, column names, units, then tab-separated rows) and keeps per row the
angular frequency [rad/s], G' [Pa], G'' [Pa] and the first Temp column (the temperature the
instrument measured at that point [C]); `set` is the file's nominal temperature [C]. Rows are
written in the files' order (each sweep from 100 rad/s down), sweeps from cold to warm.
Values are copied as text, unchanged.
"""
import csv
import hashlib
import re
import sys
from pathlib import Path


def read_osc(path):
    lines = path.read_text(encoding="latin-1").splitlines()
    nominal = float(re.search(r"(?:^|;)T=([-0-9.]+);", lines[0]).group(1))
    names = lines[1].split("\t")
    col = {n: names.index(n) for n in ("Freq", "G'", 'G"', "Temp")}
    assert lines[2].split("\t")[:3] == ["rad/s", "Pa", "Pa"], lines[2]
    rows = []
    for line in lines[3:]:
        cells = line.split()
        if cells:
            rows.append([cells[col["Freq"]], cells[col["G'"]], cells[col['G"']],
                         cells[col["Temp"]]])
    return nominal, rows


def main(src, out):
    sweeps = []
    for path in sorted(Path(src).glob("PI88K-09_FS_*C_PP-10.osc")):
        print(path.name, hashlib.sha256(path.read_bytes()).hexdigest())
        sweeps.append(read_osc(path))
    sweeps.sort(key=lambda s: s[0])
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["omega", "G_stor", "G_loss", "T", "set"])
        w.writerow(["rad/s", "Pa", "Pa", "C", "-"])
        for nominal, rows in sweeps:
            for r in rows:
                w.writerow(r + [f"{nominal:g}"])
            print(f"T = {nominal:g} C: {len(rows)} points")


if __name__ == "__main__":
    main(*sys.argv[1:3])
