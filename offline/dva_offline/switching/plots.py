"""Figure of `dva switching plot`: one seed's ramp flight with the best constant c2 and with
the switching law, and a quarter second of the law at 1.1 U_cr (c2 and damper force)."""
from __future__ import annotations

import numpy as np

from aero_dva.flight.divergence import ramp_airspeed
from aero_dva.flight.per_sample.flight import fly_switched
from dva_offline.switching.study import FORCE_STD, RAMP, SAMPLE_RATE, fixed_law

__all__ = ["plot_switching"]


def plot_switching(model, gains, u_cr: float, fixed_c2: float, path, seed: int = 0) -> None:
    """Write the figure to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    start, stop, duration = RAMP
    u = ramp_airspeed(u_cr, start, stop, duration, SAMPLE_RATE)
    force = np.random.default_rng(seed).normal(0.0, FORCE_STD, u.size)
    rho, tau = gains.density, gains.time_constant
    fixed = fly_switched(model, fixed_law(model, fixed_c2), u, rho, force, time_constant=0.0,
                         initial_damping=fixed_c2)
    switched = fly_switched(model, gains.law, u, rho, force, time_constant=tau)
    n = int(2.0 * SAMPLE_RATE)
    at = fly_switched(model, gains.law, 1.1 * u_cr, rho, force[:n], time_constant=tau)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7))
    for flight, label in ((fixed, f"best constant c2 = {fixed_c2:.0f} N s/m"),
                          (switched, f"switching law, {tau * 1e3:g} ms lag")):
        le = np.clip(np.abs(flight.leading_edge), 1e-6, 1.0)
        ax1.semilogy(u / u_cr, le, lw=0.4, label=label)
    ax1.set_xlabel("airspeed U / U_cr [-] (ramp 0.8 -> 1.4 in 45 s)")
    ax1.set_ylabel("|leading edge| [m] (clipped at 1 m)")
    ax1.legend(loc="upper left")
    ax1.grid(True, which="both", alpha=0.3)
    t = np.arange(n) / SAMPLE_RATE
    w = slice(n - 250, n)
    k2 = model.absorber.series_stiffness
    force_d = np.sqrt(at.damper_power * at.damping)  # |F| = sqrt(P c2)
    ax2.plot(t[w], at.damping[w], color="C1", label="c2 applied [N s/m]")
    ax2.set_xlabel("time [s] at 1.1 U_cr")
    ax2.set_ylabel("c2 [N s/m]")
    ax3 = ax2.twinx()
    ax3.plot(t[w], at.leading_edge[w] * 1e3, color="C0", lw=0.8, label="leading edge [mm]")
    ax3.plot(t[w], force_d[w] / k2 * 1e3, color="C2", lw=0.8,
             label="|damper force| / k2 [mm]")
    ax3.set_ylabel("leading edge, |damper force| / k2 [mm]")
    lines = ax2.get_lines() + ax3.get_lines()
    ax2.legend(lines, [ln.get_label() for ln in lines], loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
