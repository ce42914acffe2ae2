"""Files of the RBF training: the fig. 7.11 plot (PNG) of the optimal versus the network's c2."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["plot_network_c2"]


def plot_network_c2(path, airspeed_ratio, density, optimal_c2, network_c2, validation_mask,
                    method: str = "exact") -> Path:
    """Optimal c2 (the labels) and the network's c2 versus airspeed, per density (fig. 7.11).

    Parameters
    ----------
    path : path-like
        PNG file to write.
    airspeed_ratio, density : (n,) U/U_cr and rho [kg/m^3] of each condition
    optimal_c2 : (n,) [N s/m] the label of each condition
    network_c2 : (n,) [N s/m] network output, mean over the condition's windows (its c2 values)
    validation_mask : (n,) bool, conditions at airspeeds held out of training
    method : str
        How the labels were made (legend text).
    """
    path = Path(path)
    ratio = np.asarray(airspeed_ratio, dtype=float)
    rho = np.asarray(density, dtype=float)
    held = np.asarray(validation_mask, dtype=bool)
    optimal = np.asarray(optimal_c2, dtype=float)
    network = np.asarray(network_c2, dtype=float)
    label = {"exact": "optimal c2 (exact stationary RMS)",
             "measured-argmin": "c2 of the lowest measured RMS (label)"}.get(method, method)
    fig, ax = plt.subplots(figsize=(8, 5))
    for k, value in enumerate(np.unique(rho)):
        on = rho == value
        color = f"C{k}"
        ax.plot(ratio[on], optimal[on], "-", color=color, lw=1.2,
                label=f"{label}, rho = {value:.3g} kg/m^3")
        ax.plot(ratio[on & ~held], network[on & ~held], ".", color=color, ms=3)
        ax.plot(ratio[on & held], network[on & held], "x", color=color, ms=5)
    ax.plot([], [], "k.", ms=3, label="network (mean over the c2 windows), training airspeeds")
    ax.plot([], [], "kx", ms=5, label="network, held-out airspeeds (validation)")
    ax.set_xlabel("airspeed U / U_cr [-]")
    ax.set_ylabel("c2 [N s/m]")
    ax.set_title("Optimal c2 and RBF network c2 (cf. Zhang (2006) fig. 7.11)")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
