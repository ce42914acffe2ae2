"""Files of the RBF training: the fig. 7.11 plot (PNG) of optimal versus network c2."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["plot_network_c2"]


def plot_network_c2(path, airspeed_ratio, optimal_c2, network_c2, validation_mask,
                    window_ratio=None, window_c2=None) -> Path:
    """Optimal c2 of the experiment and the network's c2 versus airspeed (seed fig. 7.11).

    Parameters
    ----------
    path : path-like
        PNG file to write.
    airspeed_ratio : (n,) U/U_cr of each airspeed
    optimal_c2 : (n,) [N s/m] c2 of the lowest measured RMS (the labels)
    network_c2 : (n,) [N s/m] network output, mean over the airspeed's windows
    validation_mask : (n,) bool, airspeeds held out of training
    window_ratio, window_c2 : (m,), optional
        Network output of every window, drawn as small dots.
    """
    path = Path(path)
    ratio = np.asarray(airspeed_ratio, dtype=float)
    held = np.asarray(validation_mask, dtype=bool)
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    if window_ratio is not None:
        ax.plot(window_ratio, window_c2, ".", ms=2, color="0.7",
                label="network, each window")
    ax.plot(ratio, optimal_c2, "o", ms=3, mfc="none", color="C0",
            label="optimal c2 from the experiment (lowest measured RMS)")
    ax.plot(ratio, network_c2, "-", color="C1", label="network (mean over the c2 windows)")
    ax.plot(ratio[held], np.asarray(network_c2)[held], "x", color="C3",
            label="held-out airspeeds (validation)")
    ax.set_xlabel("airspeed U / U_cr")
    ax.set_ylabel("c2 [N s/m]")
    ax.set_title("Optimal c2 and RBF network c2 (cf. seed fig. 7.11)")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
