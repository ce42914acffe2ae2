"""Prints the model-free numbers behind each expected verdict in README.md.

Run from this folder: python expected_evidence.py   (numpy and scipy only)
- hammer hits: resonance frequencies per hit (parabola through log|H| at the peak line);
- jointed beam: a one-mode accelerance model (f_n, zeta, real modal constant, complex
  residual) fitted to each sweep alone, RMS relative error over all its points;
- melt: horizontal shift of each sweep onto its colder neighbour (log G', log G'' over the
  overlap), their sum relative to -35 C, and WLF / Arrhenius laws fitted to it.
"""
import numpy as np
from scipy.optimize import least_squares, minimize_scalar


def load(name):
    return np.genfromtxt(name, delimiter=",", names=True)


def hammer_hits():
    r = load("impact_hits_pyfrf.csv")
    for hit in np.unique(r["hit"]):
        m = r["hit"] == hit
        f, mag = r["frequency_hz"][m], np.log(np.abs(r["real"][m] + 1j * r["imag"][m]))
        peaks = []
        for lo, hi in ((800, 820), (845, 860), (890, 910)):
            k = np.flatnonzero((f >= lo) & (f <= hi))
            i = k[np.argmax(mag[k])]
            y0, y1, y2 = mag[i - 1:i + 2]
            peaks.append(f[i] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * (f[i + 1] - f[i]))
        print(f"hit {int(hit)}: peak force {r['force_peak_n'][m][0]:.1f} N, resonances "
              + ", ".join(f"{p:.2f}" for p in peaks) + " Hz")


def one_mode_fit(f, h):
    w = 2 * np.pi * f

    def res(p):
        wn = 2 * np.pi * p[0]
        e = (-w**2 * p[2] / (wn**2 - w**2 + 2j * p[1] * wn * w) + p[3] + 1j * p[4] - h) / abs(h)
        return np.r_[e.real, e.imag]

    k = np.argmax(abs(h))
    fit = least_squares(res, [f[k], 0.003, -abs(h[k]) * 0.006, 0, 0],
                        x_scale=[1, 1e-3, 1e-2, 1, 1])
    return fit.x[0], fit.x[1], np.sqrt(np.mean(res(fit.x) ** 2) * 2)


def jointed_beam():
    for name, cov in (("brb_response_control.csv", "response_amplitude_ms2"),
                      ("brb_force_control.csv", "force_n")):
        r = load(name)
        for level in np.unique(r["level"]):
            m = r["level"] == level
            fn, zeta, err = one_mode_fit(r["frequency_hz"][m], r["real"][m] + 1j * r["imag"][m])
            print(f"{name} level {int(level)}: mean {cov} {r[cov][m].mean():.3g}, "
                  f"f_n {fn:.3f} Hz, zeta {zeta:.5f}, RMS relative error {err:.4f}")


def melt():
    r = np.genfromtxt("pi88k_melt_reptate.csv", delimiter=",", skip_header=2)
    temps = np.unique(r[:, 4])
    steps = []
    for cold, warm in zip(temps, temps[1:]):
        a, b = r[r[:, 4] == cold], r[r[:, 4] == warm]
        xa = np.log10(a[:, 0])
        order = np.argsort(xa)

        def cost(s, a=a, b=b, xa=xa, order=order):
            x = np.log10(b[:, 0]) + s
            m = (x > xa.min()) & (x < xa.max())
            if m.sum() < 4:
                return 1e3
            return sum(np.mean((np.log10(b[m, c])
                                - np.interp(x[m], xa[order], np.log10(a[order, c]))) ** 2)
                       for c in (1, 2))

        s = minimize_scalar(cost, bounds=(-3, 0.5), method="bounded")
        steps.append(s.x)
        print(f"{cold:g} -> {warm:g} C: shift {s.x:.3f} decades, "
              f"misfit {np.sqrt(s.fun / 2):.3f} decade RMS")
    log_at = np.r_[0, np.cumsum(steps)]
    log_at -= np.interp(-35.0, temps, log_at)
    print("log10 a_T relative to -35 C: "
          + ", ".join(f"{t:g} C {v:.3f}" for t, v in zip(temps, log_at)))
    wlf = least_squares(lambda p: log_at - (-p[0] * (temps + 35) / (p[1] + temps + 35) + p[2]),
                        [9, 100, 0])
    print(f"WLF (T0 = -35 C): C1 {wlf.x[0]:.2f}, C2 {wlf.x[1]:.1f} K, "
          f"RMS {np.sqrt(np.mean(wlf.fun ** 2)):.3f} decade")
    design = np.c_[1 / (temps + 273.15), np.ones_like(temps)]
    coef, *_ = np.linalg.lstsq(design, log_at, rcond=None)
    rms = np.sqrt(np.mean((log_at - design @ coef) ** 2))
    print(f"Arrhenius: E_a {coef[0] * 8.314 * np.log(10) / 1e3:.0f} kJ/mol, "
          f"RMS {rms:.3f} decade")


if __name__ == "__main__":
    hammer_hits()
    jointed_beam()
    melt()
