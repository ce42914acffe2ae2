"""Five impact-hammer hits of pyFRF (ladisk/pyFRF, data/measurements_1..5.npy) as FRFs per hit.

Run once: python convert_pyfrf_impacts.py DIR_WITH_NPY OUT.csv  (PYTHONPATH=offline)
Each .npy holds rows (time [s], force [N], acceleration [m/s^2]), 25 600 samples at 25.6 kHz.
The FRF of each hit is the project's own H1 estimator (dva_offline.isolator.frf_estimation,
as `dva isolator estimate` uses it) on the whole 1 s record: one segment, no window (the
response decays by about 60 dB within the record, peak against the RMS of its last 40 ms, so
leakage is small), 1 Hz lines. Kept: 760-960 Hz (four modes near 810, 824, 851 and 900 Hz;
the hammer's force spectrum there is within 1.1 dB of its value at 10 Hz), every second line
(2 Hz). The covariate force_peak_n is the hit's peak force.
"""
import csv
import hashlib
import sys
from pathlib import Path

import numpy as np

from dva_offline.isolator.frf_estimation import estimate_frf

FS = 25600.0
BAND_HZ = (760.0, 960.0)
EVERY = 2


def main(src, out):
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frequency_hz", "real", "imag", "force_peak_n", "hit"])
        for hit in range(1, 6):
            path = Path(src) / f"measurements_{hit}.npy"
            print(path.name, hashlib.sha256(path.read_bytes()).hexdigest())
            t, force, acc = np.load(path)
            assert np.allclose(np.diff(t), 1 / FS, rtol=1e-6), "sampling rate is not 25.6 kHz"
            est = estimate_frf(force, acc, fs=FS, nfft=t.size, window="boxcar")
            keep = np.flatnonzero((est.frequency_hz >= BAND_HZ[0])
                                  & (est.frequency_hz <= BAND_HZ[1]))[::EVERY]
            peak = float(np.max(np.abs(force)))
            for f, h in zip(est.frequency_hz[keep], est.h1[keep]):
                w.writerow([f"{f:.6g}", f"{h.real:.9g}", f"{h.imag:.9g}", f"{peak:.6g}", hit])
            print(f"hit {hit}: peak force {peak:.3f} N, {keep.size} lines")


if __name__ == "__main__":
    main(*sys.argv[1:3])
