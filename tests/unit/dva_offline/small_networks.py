"""A small RBF network on spectrum-shaped inputs, for tests that replay or fly a controller."""
from __future__ import annotations

import numpy as np

from aero_dva.control.rbf_io import save_rbf_network
from aero_dva.control.rbf_network import spectrum_input_names, train_rbf_ols


def small_spectrum_network(path, slope: float):
    """Train a 15-neuron network whose c2 rises with the 8th spectrum line and with the applied
    c2 (``slope``); save it to ``path``. Returns (the saved path, the network)."""
    rng = np.random.default_rng(0)
    n = 60
    mags = rng.dirichlet(np.ones(16), size=(n, 2))
    damping = rng.uniform(300.0, 1500.0, n)
    inputs = np.column_stack([mags.reshape(n, 32), damping])
    targets = 400.0 + 3000.0 * mags[:, 0, 7] + slope * damping
    names, units = spectrum_input_names()
    network = train_rbf_ols(inputs, targets, spread=2.0, max_neurons=15, input_names=names,
                            input_units=units).network
    return save_rbf_network(network, path), network
