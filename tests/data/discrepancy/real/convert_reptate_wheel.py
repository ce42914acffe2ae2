"""Two more polyisoprene melts of RepTate's data, as shipped in its PyPI wheel, as CSVs.

Run once: python convert_reptate_wheel.py RepTate-1.3.3-py3-none-any.whl OUTDIR
(the wheel from PyPI: `pip download --no-deps reptate==1.3.3`). Reads, inside the wheel,
RepTate-1.3.3.data/data/data/PI_LINEAR/osc/*.osc (rheometer exports: one header line
`T=..;Mw=..;...`, column names, units, then rows) and writes

- pi33k_melt_reptate.csv: PI33K-8 at -40, -30, -20, -10 and 0 C (files PI33K-8_<T>C_FS_PP10);
- pi1000k_repeats_reptate.csv: PI1000k-02 at 30 C, two frequency sweeps of one loading
  (files PI1000k-02_30C_FS3_PP10 and _FS6_PP10).

Per row: angular frequency [rad/s], G' [Pa], G'' [Pa], the first Temp column (the temperature
the instrument measured at that point [C]), the strain amplitude [%] (column Strain or g),
`set` (the file's nominal temperature [C], or the sweep number FS3 -> 3, FS6 -> 6) and, for the
repeats, `T_set` (the nominal temperature). Rows in the files' order; values copied as text.
"""
import csv
import hashlib
import re
import sys
import zipfile
from pathlib import Path

OSC = "RepTate-1.3.3.data/data/data/PI_LINEAR/osc/"


def read_osc(text):
    lines = text.splitlines()
    nominal = float(re.search(r"(?:^|;)T=([-0-9.]+);", lines[0]).group(1))
    names = lines[1].split("\t")
    freq = "Freq" if "Freq" in names else "w"
    strain = "Strain" if "Strain" in names else "g"
    col = {n: names.index(n) for n in (freq, "G'", 'G"', "Temp", strain)}
    assert lines[2].split("\t")[:3] == ["rad/s", "Pa", "Pa"], lines[2]
    assert lines[2].split("\t")[col[strain]] == "%", lines[2]
    rows = []
    for line in lines[3:]:
        cells = line.split()
        if cells:
            rows.append([cells[col[n]] for n in (freq, "G'", 'G"', "Temp", strain)])
    return nominal, rows


def members(wheel, pattern):
    with zipfile.ZipFile(wheel) as zf:
        out = []
        for name in sorted(n for n in zf.namelist() if re.fullmatch(OSC + pattern, n)):
            data = zf.read(name)
            print(Path(name).name, hashlib.sha256(data).hexdigest())
            out.append((Path(name).name, data.decode("latin-1")))
    return out


def write(path, header, units, blocks):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerow(units)
        for rows, extra in blocks:
            for r in rows:
                w.writerow(r + extra)
    print(f"wrote {path}: " + ", ".join(f"{len(r)} points" for r, _ in blocks))


def main(wheel, out):
    print("wheel", hashlib.sha256(Path(wheel).read_bytes()).hexdigest())
    out = Path(out)
    sweeps = [read_osc(t) for _, t in members(wheel, r"PI33K-8_-?\d+C_FS_PP10\.osc")]
    sweeps.sort(key=lambda s: s[0])
    write(out / "pi33k_melt_reptate.csv", ["omega", "G_stor", "G_loss", "T", "strain", "set"],
          ["rad/s", "Pa", "Pa", "C", "%", "-"],
          [(rows, [f"{nominal:g}"]) for nominal, rows in sweeps])
    blocks = []
    for name, text in members(wheel, r"PI1000k-02_30C_FS[36]_PP10\.osc"):
        nominal, rows = read_osc(text)
        sweep = re.search(r"_FS(\d)_", name).group(1)
        blocks.append((rows, [sweep, f"{nominal:g}"]))
    write(out / "pi1000k_repeats_reptate.csv",
          ["omega", "G_stor", "G_loss", "T", "strain", "set", "T_set"],
          ["rad/s", "Pa", "Pa", "C", "%", "-", "C"], blocks)


if __name__ == "__main__":
    main(*sys.argv[1:3])
