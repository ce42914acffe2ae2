"""PNG figures: FRF comparisons, the modal estimate of stepped-sine data, and the parametric
studies of chapter 3 (Figs. 3.2-3.11).

matplotlib with the Agg backend; imported only by the CLI and tests that ask for plots.
The study does not print the k_1 / c_1 values of its curve families; we use the nominal M-V
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
from dva_offline.plotting import unwrapped_phase_deg  # noqa: E402

NOMINAL = dict(mass=1.0, k=12e3, c=40.0)
K1_FAMILY = (3e3, 6e3, 12e3, 24e3, 48e3)  # N/m
C1_FAMILY = (10.0, 20.0, 40.0, 80.0, 160.0)  # N s/m
# quantity -> (axis name, SI unit)
QUANTITY_LABELS = {
    "receptance": ("receptance", "m/N"),
    "accelerance": ("accelerance", "(m/s²)/N"),
    "stiffness": ("dynamic stiffness", "N/m"),
    "transmissibility": ("transmissibility", "-"),
}
W_MV = "ωₘᵥ"
Z_MV = "ζₘᵥ"
TAU_1 = "τ₁"


def _params_text(mass, k, c) -> str:
    return f"m = {mass:g} kg, k = {k / 1e3:g} kN/m, c = {c:g} N s/m"


def _magnitude_label(quantity: str) -> str:
    name, unit = QUANTITY_LABELS.get(quantity, (quantity, None))
    return f"|{name}|" + (f" [{unit}]" if unit else "")


def plot_frf(path, curves, quantity: str = "receptance", title: str = "") -> Path:
    """Magnitude (log axis) and phase of several FRFs.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    curves : list of (label, frequency_hz (N,), h (N,) complex, style str)
        Styles without a line (e.g. ``"k."``) are drawn as small markers under the lines.
    quantity : str
        ``receptance``, ``accelerance``, ``stiffness`` or ``transmissibility``; sets the axis
        label and its SI unit (other text is used as the label as given).
    title : str
    """
    fig, (ax_m, ax_p) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for label, f, h, style in curves:
        kw = dict(lw=1.5, zorder=2) if "-" in style else dict(ms=3, zorder=1)
        ax_m.semilogy(f, np.abs(h), style, label=label, **kw)
        ax_p.plot(f, unwrapped_phase_deg(h, frequency=f), style, label=label, **kw)
    ax_m.set_ylabel(_magnitude_label(quantity))
    ax_p.set_ylabel("phase [deg], unwrapped")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.legend(fontsize=8)
    ax_m.set_title(title, fontsize=10)
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_modal_estimate(path, frequency_hz, receptance, estimate, title: str = "") -> Path:
    """Stepped-sine modal estimate (Table 5.2 method): |H| with the half-power points, Re(H)
    with its zero crossing.

    Parameters
    ----------
    path : str or Path
        Output PNG.
    frequency_hz : array_like, shape (N,)
        Step frequencies [Hz].
    receptance : array_like, shape (N,), complex
        Receptance at the steps [m/N].
    estimate : ModalEstimate
        From :func:`dva_offline.isolator.frf_data.estimate_modal` (rad/s).
    title : str
    """
    f = np.asarray(frequency_hz, dtype=float)
    h = np.asarray(receptance, dtype=complex)
    fn = estimate.natural_frequency_rad_s / (2 * np.pi)
    f1 = estimate.half_power_lower_rad_s / (2 * np.pi)
    f2 = estimate.half_power_upper_rad_s / (2 * np.pi)
    peak = np.max(np.abs(h))
    fig, (ax_m, ax_r) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    ax_m.semilogy(f, np.abs(h), "k.-", ms=3, lw=0.8, label="steps")
    ax_m.axhline(peak / np.sqrt(2), color="tab:blue", ls="--", lw=1,
                 label="half power (peak / √2)")
    ax_m.axvspan(f1, f2, color="tab:blue", alpha=0.15,
                 label=f"f₁ = {f1:.2f} Hz, f₂ = {f2:.2f} Hz")
    ax_m.set_ylabel(_magnitude_label("receptance"))
    ax_m.legend(fontsize=8, title=f"ζ = (f₂ - f₁) / (2 fₙ) = "
                                  f"{estimate.damping_ratio:.4f}", title_fontsize=8)
    ax_r.plot(f, h.real, "k.-", ms=3, lw=0.8, label="Re(receptance)")
    ax_r.axhline(0.0, color="0.5", lw=0.8)
    ax_r.axvline(fn, color="tab:red", ls="--", lw=1,
                 label=f"zero crossing fₙ = {fn:.3f} Hz "
                       f"({estimate.natural_frequency_rad_s:.2f} rad/s)")
    ax_r.set_ylabel("Re(receptance) [m/N]")
    ax_r.set_xlabel("frequency [Hz]")
    ax_r.legend(fontsize=8)
    ax_m.set_title(title, fontsize=10)
    for ax in (ax_m, ax_r):
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _tau_curves(ax, mass, k, c, family, fixed, what):
    tau = np.logspace(-4, 1, 300)
    gap = False
    for value in family:
        if fixed == "k1":
            omega, zeta = modal_pairs(mass, k, c, np.full_like(tau, value), tau * value)
            label = f"k₁ = {value / 1e3:g} kN/m"
        else:
            omega, zeta = modal_pairs(mass, k, c, value / tau, np.full_like(tau, value))
            label = f"c₁ = {value:g} N s/m"
        y = omega if what == "omega" else zeta
        gap |= bool(np.any(np.isnan(y)))
        ax.semilogx(tau, y, label=label)
    w_v = np.sqrt(k / mass)
    ax.axhline(w_v if what == "omega" else c / (2 * np.sqrt(k * mass)), color="k", ls=":",
               label="Voigt (ωᵥ)" if what == "omega" else "Voigt (ζᵥ)")
    ax.set_xlabel(f"{TAU_1} = c₁/k₁ [s]")
    ax.set_ylabel(f"{W_MV} [rad/s]" if what == "omega" else f"{Z_MV} [-]")
    if gap:
        ax.plot([], [], " ", label="gap: overdamped,\nno complex pair")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)


def _contours(ax, mass, k, c, what, levels):
    k1 = np.logspace(1, 6, 160)
    c1 = np.logspace(-1, 4, 160)
    omega, zeta = modal_grid(mass, k, c, k1, c1)
    field = omega if what == "omega" else zeta
    cs = ax.contour(k1 / 1e3, c1, field, levels=levels)
    ax.clabel(cs, fontsize=7, fmt="%g")
    overdamped = np.isnan(field).astype(float)
    if overdamped.any():
        ax.contourf(k1 / 1e3, c1, overdamped, levels=[0.5, 1.5], colors=["0.85"])
        ax.text(0.97, 0.03, "grey: no complex eigenvalue pair", transform=ax.transAxes,
                ha="right", fontsize=7, color="0.3")
    for tau in (1e-3, 1e-2, 1e-1):
        ax.loglog(k1 / 1e3, tau * k1, "k:", lw=0.8)
        # label near the lower left end of the line, inside the axes
        x = max(1.5 * k1[0], 3 * c1[0] / tau)
        ax.text(x / 1e3, 1.8 * tau * x, f"{TAU_1} = {tau * 1e3:g} ms", fontsize=7,
                rotation=33, color="0.3")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(k1[0] / 1e3, k1[-1] / 1e3)
    ax.set_ylim(c1[0], c1[-1])
    ax.set_xlabel("k₁ [kN/m]")
    ax.set_ylabel("c₁ [N s/m]")


def parametric_study_figures(out_dir) -> list[Path]:
    """Write Figs. 3.2-3.11 of the study as PNGs into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m, k, c = NOMINAL["mass"], NOMINAL["k"], NOMINAL["c"]
    paths = []

    def save(fig, name, title, params=(m, k, c)):
        fig.suptitle(f"{title}\n{_params_text(*params)}", fontsize=10)
        fig.subplots_adjust(left=0.14, right=0.97, bottom=0.13, top=0.86)  # tight_layout is slow
        path = out / name
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)

    specs = [
        ("fig3_02_omega_const_k1.png", f"Fig. 3.2 influence of k₁ and {TAU_1} on {W_MV}",
         (m, k, c), K1_FAMILY, "k1", "omega"),
        ("fig3_03_omega_const_k1_k200.png", f"Fig. 3.3 influence of k₁ and {TAU_1} on {W_MV}",
         (m, 200e3, 300.0), tuple(16 * v for v in K1_FAMILY), "k1", "omega"),
        ("fig3_04_omega_const_c1.png", f"Fig. 3.4 influence of c₁ and {TAU_1} on {W_MV}",
         (m, k, c), C1_FAMILY, "c1", "omega"),
        ("fig3_06_zeta_const_k1.png", f"Fig. 3.6 influence of k₁ and {TAU_1} on {Z_MV}",
         (m, k, c), K1_FAMILY, "k1", "zeta"),
        ("fig3_07_zeta_const_c1.png", f"Fig. 3.7 influence of c₁ and {TAU_1} on {Z_MV}",
         (m, k, c), C1_FAMILY, "c1", "zeta"),
    ]
    for name, title, params, family, fixed, what in specs:
        fig, ax = plt.subplots(figsize=(6, 4))
        _tau_curves(ax, *params, family, fixed, what)
        save(fig, name, title, params)

    fig, ax = plt.subplots(figsize=(6, 4.5))
    _contours(ax, m, k, c, "omega", [120, 130, 140, 150, 160])
    save(fig, "fig3_05_const_omega.png", f"Fig. 3.5 curves of constant {W_MV} [rad/s]")
    fig, ax = plt.subplots(figsize=(6, 4.5))
    _contours(ax, m, k, c, "zeta", [0.1, 0.15, 0.2, 0.3, 0.4, 0.5])
    save(fig, "fig3_08_const_zeta.png", f"Fig. 3.8 curves of constant {Z_MV}")

    f_hz = np.linspace(0.1, 60, 600)
    w = 2 * np.pi * f_hz
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, (kv, cv) in {"I": (12e3, 40), "II": (12e3, 80), "III": (24e3, 40)}.items():
        ax.semilogy(f_hz, np.abs(frf(MaxwellModel(m, kv, cv), w)),
                    label=f"Model {name}: kᵥ = {kv / 1e3:g} kN/m, cᵥ = {cv:g} N s/m")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_magnitude_label("receptance"))
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Fig. 3.9 Voigt models of Table 3.2\nm = 1 kg", fontsize=10)
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.13, top=0.86)
    fig.savefig(out / "fig3_09_voigt_models.png", dpi=100)
    plt.close(fig)
    paths.append(out / "fig3_09_voigt_models.png")

    fig, ax = plt.subplots(figsize=(6, 4))
    for tau in (0.001, 0.005, 0.01, 0.05, 0.5):
        model = MaxwellModel(m, k, c, (40.0 / tau,), (40.0,))
        ax.semilogy(f_hz, np.abs(frf(model, w)),
                    label=f"{TAU_1} = {tau:g} s (k₁ = {40.0 / tau / 1e3:g} kN/m)")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_magnitude_label("receptance"))
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save(fig, "fig3_10_tau_const_c1.png", f"Fig. 3.10 influence of {TAU_1} (c₁ = 40 N s/m)")

    fig, ax = plt.subplots(figsize=(6, 4))
    for tau in (0.0005, 0.002, 0.005, 0.02, 0.1, 5.0):
        model = MaxwellModel(m, k, c, (12e3,), (12e3 * tau,))
        ax.semilogy(f_hz, np.abs(frf(model, w)),
                    label=f"{TAU_1} = {tau:g} s (c₁ = {12e3 * tau:g} N s/m)")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_magnitude_label("receptance"))
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save(fig, "fig3_11_tau_const_k1.png", f"Fig. 3.11 influence of {TAU_1} (k₁ = 12 kN/m)")
    return paths
