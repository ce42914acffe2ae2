"""PNG figures of the wing analyses (matplotlib, Agg backend)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["plot_flight", "plot_modal", "plot_tuned"]


def plot_modal(result, path, critical_airspeed=None) -> None:
    """Natural frequencies and damping ratios versus airspeed (Zhang (2006) fig. 6.2)."""
    fig, (ax_f, ax_z) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for i, label in enumerate(result.labels):
        style = "-" if label == "rotational" else "--"
        ax_f.plot(result.airspeed, result.frequency[i], style, label=label)
        ax_z.plot(result.airspeed, result.damping_ratio[i], style, label=label)
    ax_z.axhline(0.0, color="k", lw=0.5)
    if critical_airspeed:
        for ax in (ax_f, ax_z):
            ax.axvline(critical_airspeed, color="r", lw=0.5, ls=":")
    ax_f.set_ylabel("natural frequency [Hz]")
    ax_z.set_ylabel("damping ratio [-]")
    ax_z.set_xlabel("airspeed [m/s]")
    ax_f.legend()
    if critical_airspeed:
        ax_f.set_title(f"red dotted line: U_cr = {critical_airspeed:.2f} m/s without the DVA",
                       fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_tuned(curve, critical_airspeed, path) -> None:
    """Best minimum damping ratio and the tuned setting versus airspeed (fig. 6.11-6.12)."""
    u = np.array([c.airspeed for c in curve]) / critical_airspeed
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 7))
    axes[0].plot(u, [c.min_damping_ratio for c in curve])
    axes[0].axhline(0.0, color="k", lw=0.5)
    axes[0].set_ylabel("min damping ratio [-]")
    axes[1].plot(u, [c.stiffness / 1e3 for c in curve])
    axes[1].set_ylabel("k1 [N/mm]")
    axes[2].plot(u, [c.damping / 1e3 for c in curve])
    axes[2].set_ylabel("c1 [N s/mm]")
    axes[2].set_xlabel("U / U_cr [-]")
    axes[0].set_title("tuned passive DVA at the front tip (fig. 6.11-6.12)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_flight(traces, critical_airspeed, path, divergence_airspeed=None) -> None:
    """Plunge and pitch of the first flight versus airspeed (fig. 6.4, 6.14-6.17).

    The vertical range is 20 times the RMS of the first 10 % of the flight: the unstable linear
    model grows without bound and would otherwise flatten everything before it.
    """
    u = traces.airspeed[0] / critical_airspeed
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    n0 = max(1, u.size // 10)
    for ax, row, scale, label in ((axes[0], 0, 1e3, "plunge w [mm]"),
                                  (axes[1], 1, 1e3, "pitch alpha [mrad]")):
        x = traces.displacements[0, row] * scale
        ax.plot(u, x, lw=0.5)
        lim = 20.0 * np.sqrt(np.mean(x[:n0] ** 2))
        if np.isfinite(lim) and lim > 0:
            ax.set_ylim(-lim, lim)
        if divergence_airspeed is not None and np.isfinite(divergence_airspeed):
            ax.axvline(divergence_airspeed / critical_airspeed, color="r", lw=1.5, ls="--",
                       zorder=3)
        ax.set_ylabel(label)
    axes[1].set_xlabel("U / U_cr [-]")
    diverged = divergence_airspeed is not None and np.isfinite(divergence_airspeed)
    axes[0].set_title("first flight; red dashed line: " + (
        f"diverged at {divergence_airspeed / critical_airspeed:.3f} U_cr" if diverged
        else "no divergence") + "; vertical range 20 x the first 10 %'s RMS", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
