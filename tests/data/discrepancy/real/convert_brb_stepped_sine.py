"""Stepped-sine FRFs of the Brake-Reuss beam (mattiacenedese/BRBtesting) as CSV tables.

Run once: python convert_brb_stepped_sine.py ForcedFrequencyResponses.mat OUT_DIR
The .mat holds FRdata.ForceControl (4 sweeps, force held about constant) and
FRdata.ResponseControl (8 sweeps, acceleration amplitude held constant), each with
frequency [Hz], force [N], amplitude [m/s^2] and phase [rad] of the response relative to the
force at 41 steps near the first bending mode (79-81.2 Hz). The FRF of a step is
amplitude / force * exp(j phase) (accelerance, (m/s^2)/N), as dva_offline.isolator's
frf_from_amplitude_phase forms it; nothing else is changed. Per point the measured force and
response amplitude are kept as covariates; `level` numbers the sweeps in the file's order.
"""
import csv
import hashlib
import sys
from pathlib import Path

import numpy as np
from scipy.io import loadmat


def write(sweeps, out):
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frequency_hz", "real", "imag", "force_n", "response_amplitude_ms2",
                    "level"])
        for level, s in enumerate(sweeps, start=1):
            assert s.units.replace(" ", "") == "Hz,N,m/s^2,rad", s.units
            h = s.amplitude / s.force * np.exp(1j * s.phase)
            for f, hv, fn, a in zip(s.frequency, h, s.force, s.amplitude):
                w.writerow([f"{f:.6g}", f"{hv.real:.9g}", f"{hv.imag:.9g}", f"{fn:.6g}",
                            f"{a:.6g}", level])
            print(f"{Path(out).name} level {level}: force {s.force.min():.3g}-"
                  f"{s.force.max():.3g} N, response {s.amplitude.min():.3g}-"
                  f"{s.amplitude.max():.3g} m/s^2, {s.frequency.size} steps")


def main(mat, out_dir):
    print(Path(mat).name, hashlib.sha256(Path(mat).read_bytes()).hexdigest())
    d = loadmat(mat, squeeze_me=True, struct_as_record=False)["FRdata"]
    write(d.ForceControl, Path(out_dir) / "brb_force_control.csv")
    write(d.ResponseControl, Path(out_dir) / "brb_response_control.csv")


if __name__ == "__main__":
    main(*sys.argv[1:3])
