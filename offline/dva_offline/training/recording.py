"""The planned training dwells in time, each started from its own stationary state.

A dwell holds one (U, rho, c2) for ``window`` seconds. Its initial state is drawn from the
stationary state covariance of that condition, ``P = Phi P Phi^T + sigma^2 Gamma Gamma^T``
(:func:`aero_dva.control.stationary_rms.stationary_covariance`, the sampled system exactly as
simulated), and the held white aileron force of ``force_std`` drives it; so every window is a
sample of the stationary response whose RMS the labels minimise, with no transient from the
dwell before. The dwells are flown in batches by
:func:`aero_dva.flight.batch_simulator.simulate_flights` (exact zero-order hold, no rounding of
the held conditions).

Randomness: dwell ``k`` draws its initial state and then its force from
``numpy.random.default_rng((seed, k))``, so a dwell's data do not depend on the batch size
or on which dwells are recorded with it. Pure numerics (no files).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from aero_dva.control.stationary_rms import stationary_covariance
from aero_dva.flight.batch_simulator import simulate_flights
from aero_dva.wing.model import AeroelasticModel

__all__ = ["BATCH", "DwellBatch", "simulate_dwells", "stationary_draw"]

BATCH = 250  # dwells per batch: 250 x 2 s x 8 channels of float64 = 32 MB
#: Most samples of one batch (the default's 250 x 2000): longer windows fly fewer at a time.
BATCH_SAMPLES = 500_000


@dataclass(frozen=True)
class DwellBatch:
    """Consecutive dwells of the plan (time on the last axis).

    Attributes
    ----------
    first_dwell : int
        Index of the batch's first dwell in the plan.
    force : (k, N) [N]
    displacements : (k, 4, N) plunge [m], pitch [rad], leading edge [m], DVA stroke [m]
    accelerations : (k, 3, N) plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2]
    """

    first_dwell: int
    force: np.ndarray
    displacements: np.ndarray
    accelerations: np.ndarray

    @property
    def n_dwells(self) -> int:
        return int(self.force.shape[0])


def stationary_draw(covariance: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``x = V sqrt(max(w, 0)) V^T z`` for ``P = V diag(w) V^T``: a N(0, P) sample from a
    standard normal ``z`` (..., n). The symmetric square root tolerates the round-off
    negative eigenvalues of a nearly singular P (a slow Maxwell-node mode barely excited by
    the force), where a Cholesky factor would fail."""
    p = 0.5 * (covariance + np.swapaxes(covariance, -1, -2))
    w, v = np.linalg.eigh(p)
    root = (v * np.sqrt(np.clip(w, 0.0, None))[..., None, :]) @ np.swapaxes(v, -1, -2)
    return (root @ z[..., None])[..., 0]


def simulate_dwells(model: AeroelasticModel, plan, *, batch: int = BATCH,
                    dwells: slice | None = None) -> Iterator[DwellBatch]:
    """Yield the plan's dwells in order, in batches of ``batch``.

    Parameters
    ----------
    model : AeroelasticModel
        The wing with the tunable Maxwell DVA the plan was made for.
    plan : TrainingPlan
    batch : int
        Dwells simulated together (bounds memory; fewer when their samples would pass
        :data:`BATCH_SAMPLES`).
    dwells : slice, optional
        Only these dwells (default all); each is the same data as in the whole flight.

    Raises
    ------
    ValueError
        A dwell is unstable (no stationary state) or its response is not finite.
    """
    if model.absorber is None:
        raise ValueError("model has no absorber: a training sweep tunes the DVA's c2")
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise ValueError(f"batch must be a positive integer, got {batch!r}")
    s = plan.settings
    n = s.window_samples
    batch = max(1, min(batch, BATCH_SAMPLES // n))  # a dwell's data do not depend on it
    index = np.arange(plan.n_dwells)[dwells if dwells is not None else slice(None)]
    for start in range(0, index.size, batch):
        k = index[start:start + batch]
        u, rho, c2 = plan.airspeed[k], plan.density[k], plan.damping[k]
        a, b = model.matrices(u, rho, c2)
        cov = stationary_covariance(a, b, force_std=s.force_std, sample_rate=s.sample_rate)
        if not np.all(np.isfinite(cov)):
            bad = int(k[np.flatnonzero(~np.isfinite(cov).all(axis=(1, 2)))[0]])
            raise ValueError(f"dwell {bad} (U = {plan.airspeed[bad]:.3f} m/s, rho = "
                             f"{plan.density[bad]:.4g} kg/m^3, c2 = {plan.damping[bad]:.1f} "
                             "N s/m) is unstable: it has no stationary state")
        z = np.empty((k.size, model.n_states))
        force = np.empty((k.size, n))
        for row, dwell in enumerate(k.tolist()):
            rng = np.random.default_rng((s.seed, dwell))
            z[row] = rng.standard_normal(model.n_states)
            force[row] = s.force_std * rng.standard_normal(n)
        traces = simulate_flights(model.wing, model.absorber, force=force,
                                  airspeed=u[:, None], density=rho[:, None],
                                  damping=c2[:, None], sample_rate=s.sample_rate,
                                  aero=model.aero, x0=stationary_draw(cov, z), quantum=0.0)
        if not (np.all(np.isfinite(traces.displacements))
                and np.all(np.isfinite(traces.accelerations))):
            raise ValueError(f"dwells {int(k[0])}..{int(k[-1])}: the response is not finite")
        yield DwellBatch(first_dwell=int(k[0]), force=force,
                         displacements=np.ascontiguousarray(traces.displacements),
                         accelerations=np.ascontiguousarray(traces.accelerations))
