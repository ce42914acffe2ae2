"""Undo the master-curve shift of pyvisco's sample_data/freq_Eplexor_master_shear.xls.

Run once (needs xlrd, not a project dependency): python convert_eplexor_shear.py XLS OUT.csv
See README.md for what it does and the checks it prints.
"""
import csv
import sys

import numpy as np
import xlrd


def main(xls, out):
    book = xlrd.open_workbook(xls)
    shift = book.sheet_by_name("Shiftlist")
    steps = np.array([shift.row_values(r)[:2] for r in range(3, shift.nrows)], float)
    sheet = book.sheet_by_name("Exported Data")
    header = sheet.row_values(0)
    rows = np.array([[c if c != "" else np.nan for c in sheet.row_values(r)]
                     for r in range(2, sheet.nrows)], float)
    col = {name: i for i, name in enumerate(header)}
    rows = rows[np.argsort(rows[:, col["Time"]], kind="stable")]  # measurement order
    log_f = np.log10(rows[:, col["f"]])
    grid = np.log10(0.1) + np.arange(10) / 3.0  # 0.1-100 Hz, 3 per decade (Data header)
    cand = log_f[:, None] - steps[None, :, 1]
    dist = np.min(np.abs(cand[:, :, None] - grid[None, None, :]), axis=2)
    best = np.argmin(dist, axis=1)
    second = np.sort(dist, axis=1)[:, 1]
    print(f"largest distance to the grid {dist[np.arange(len(best)), best].max():.2e} decades, "
          f"smallest to the next-best step {second.min():.4f}")
    assert dist[np.arange(len(best)), best].max() < 1e-5 and second.min() > 1e-3
    runs = np.flatnonzero(np.diff(best)) + 1
    assert len(runs) + 1 == np.unique(best).size, "a step's rows are not contiguous in time"
    f_raw = 10.0 ** (log_f - steps[best, 1])
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["Nr", "Time", "f", "T", "G'", "G''"])
        w.writerow(["-", "s", "Hz", "C", "MPa", "MPa"])
        for r, f, t in zip(rows, f_raw, steps[best, 0]):
            w.writerow([int(r[col["Nr"]]), f"{r[col['Time']]:.6g}", f"{f:.6g}", f"{t:.7g}",
                        repr(float(r[col["G'"]])), repr(float(r[col["G''"]]))])
    print(f"wrote {len(rows)} rows, {np.unique(best).size} temperature steps to {out}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
