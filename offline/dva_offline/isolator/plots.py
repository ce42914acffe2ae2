"""PNG figures: FRF comparisons and the parametric studies of chapter 3 (Figs. 3.2-3.11).

matplotlib with the Agg backend; imported only by the CLI and tests that ask for plots.
The seed does not print the k_1 / c_1 values of its curve families; we use the nominal M-V
model of Table 3.1 (m = 1 kg, k = 12 kN/m, c = 40 N s/m) and families around k_1 = 12 kN/m,
c_1 = 40 N s/m.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dva_offline.isolator.maxwell_model import MaxwellModel, frf  # noqa: E402
from dva_offline.isolator.mv_curves import modal_grid, modal_pairs  # noqa: E402

NOMINAL = dict(mass=1.0, k=12e3, c=40.0)
K1_FAMILY = (3e3, 6e3, 12e3, 24e3, 48e3)  # N/m
C1_FAMILY = (10.0, 20.0, 40.0, 80.0, 160.0)  # N s/m


def plot_frf(path, curves, quantity: str = "receptance", title: str = "") -> Path:
    """Magnitude and phase of several FRFs.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    curves : list of (label, frequency_hz (N,), h (N,) complex, style str)
    """
    fig, (ax_m, ax_p) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for label, f, h, style in curves:
        ax_m.semilogy(f, np.abs(h), style, label=label)
        ax_p.plot(f, np.degrees(np.angle(h)), style, label=label)
    ax_m.set_ylabel(f"|{quantity}|")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.legend(fontsize=8)
    ax_m.set_title(title)
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _tau_curves(ax, mass, k, c, family, fixed, what):
    tau = np.logspace(-4, 1, 300)
    for value in family:
        if fixed == "k1":
            omega, zeta = modal_pairs(mass, k, c, np.full_like(tau, value), tau * value)
            label = f"k1 = {value / 1e3:g} kN/m"
        else:
            omega, zeta = modal_pairs(mass, k, c, value / tau, np.full_like(tau, value))
            label = f"c1 = {value:g} N s/m"
        ax.semilogx(tau, omega if what == "omega" else zeta, label=label)
    w_v = np.sqrt(k / mass)
    ax.axhline(w_v if what == "omega" else c / (2 * np.sqrt(k * mass)), color="k", ls=":",
               label="Voigt")
    ax.set_xlabel("tau_1 [s]")
    ax.set_ylabel("omega_mv [rad/s]" if what == "omega" else "zeta_mv")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)


def _contours(ax, mass, k, c, what, levels):
    k1 = np.logspace(1, 6, 160)
    c1 = np.logspace(-1, 4, 160)
    omega, zeta = modal_grid(mass, k, c, k1, c1)
    field = omega if what == "omega" else zeta
    cs = ax.contour(k1 / 1e3, c1, field, levels=levels)
    ax.clabel(cs, fontsize=7)
    for tau in (1e-3, 1e-2, 1e-1):
        ax.loglog(k1 / 1e3, tau * k1, "k:", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(k1[0] / 1e3, k1[-1] / 1e3)
    ax.set_ylim(c1[0], c1[-1])
    ax.set_xlabel("k_1 [kN/m]")
    ax.set_ylabel("c_1 [N s/m]")


def parametric_study_figures(out_dir) -> list[Path]:
    """Write Figs. 3.2-3.11 of the seed as PNGs into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m, k, c = NOMINAL["mass"], NOMINAL["k"], NOMINAL["c"]
    paths = []

    def save(fig, name, title):
        fig.suptitle(title, fontsize=10)
        fig.subplots_adjust(left=0.14, right=0.97, bottom=0.13, top=0.9)  # tight_layout is slow
        path = out / name
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)

    specs = [
        ("fig3_02_omega_const_k1.png", "Fig. 3.2 influence of k1 and tau1 on omega_mv",
         (m, k, c), K1_FAMILY, "k1", "omega"),
        ("fig3_03_omega_const_k1_k200.png", "Fig. 3.3 same, k = 200 kN/m, c = 300 N s/m",
         (m, 200e3, 300.0), tuple(16 * v for v in K1_FAMILY), "k1", "omega"),
        ("fig3_04_omega_const_c1.png", "Fig. 3.4 influence of c1 and tau1 on omega_mv",
         (m, k, c), C1_FAMILY, "c1", "omega"),
        ("fig3_06_zeta_const_k1.png", "Fig. 3.6 influence of k1 and tau1 on zeta_mv",
         (m, k, c), K1_FAMILY, "k1", "zeta"),
        ("fig3_07_zeta_const_c1.png", "Fig. 3.7 influence of c1 and tau1 on zeta_mv",
         (m, k, c), C1_FAMILY, "c1", "zeta"),
    ]
    for name, title, params, family, fixed, what in specs:
        fig, ax = plt.subplots(figsize=(6, 4))
        _tau_curves(ax, *params, family, fixed, what)
        save(fig, name, title)

    fig, ax = plt.subplots(figsize=(6, 4.5))
    _contours(ax, m, k, c, "omega", [120, 130, 140, 150, 160])
    save(fig, "fig3_05_const_omega.png", "Fig. 3.5 curves of constant omega_mv [rad/s]")
    fig, ax = plt.subplots(figsize=(6, 4.5))
    _contours(ax, m, k, c, "zeta", [0.1, 0.15, 0.2, 0.3, 0.4, 0.5])
    save(fig, "fig3_08_const_zeta.png", "Fig. 3.8 curves of constant zeta_mv")

    f_hz = np.linspace(0.1, 60, 600)
    w = 2 * np.pi * f_hz
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, (kv, cv) in {"I": (12e3, 40), "II": (12e3, 80), "III": (24e3, 40)}.items():
        ax.semilogy(f_hz, np.abs(frf(MaxwellModel(m, kv, cv), w)), label=f"Voigt {name}")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|receptance| [m/N]")
    ax.legend()
    save(fig, "fig3_09_voigt_models.png", "Fig. 3.9 Voigt models of Table 3.2")

    fig, ax = plt.subplots(figsize=(6, 4))
    for tau in (0.001, 0.005, 0.01, 0.05, 0.5):
        model = MaxwellModel(m, k, c, (40.0 / tau,), (40.0,))
        ax.semilogy(f_hz, np.abs(frf(model, w)), label=f"tau1 = {tau:g} s")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|receptance| [m/N]")
    ax.legend(fontsize=7)
    save(fig, "fig3_10_tau_const_c1.png", "Fig. 3.10 influence of tau1 (c1 = 40 N s/m)")

    fig, ax = plt.subplots(figsize=(6, 4))
    for tau in (0.0005, 0.002, 0.005, 0.02, 0.1, 5.0):
        model = MaxwellModel(m, k, c, (12e3,), (12e3 * tau,))
        ax.semilogy(f_hz, np.abs(frf(model, w)), label=f"tau1 = {tau:g} s")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|receptance| [m/N]")
    ax.legend(fontsize=7)
    save(fig, "fig3_11_tau_const_k1.png", "Fig. 3.11 influence of tau1 (k1 = 12 kN/m)")
    return paths
