"""The wing simulated along a logged flight in modal form: the discrepancy loop's simulator.

The flight-log domain of the discrepancy loop (:mod:`dva_offline.discrepancy.flight_domain`)
drives candidate models with the logged force at the logged conditions, one condition per
block of samples (the :class:`~aero_dva.flight.discrete_model.DiscreteWing`'s hold), hundreds
of times per fit. Here the sampled wing of each distinct condition k is the exact ZOH in modal
coordinates: the continuous model x' = A x + B f, y = C x + D f is diagonalised
(A = V diag(s) V^-1, lambda = e^{s dt}), so a block is a few scalar recursions
z[i+1] = lambda z[i] + g f[i] (one per real mode and per conjugate pair), run as one compiled
pass over the samples (:mod:`.modal_kernel`). ``A`` and ``B`` are passed in (a candidate
may alter them, e.g. a drifting stiffness); ``C``, ``D``, the sample interval and the output
names come from the discrete wing (:meth:`ModalBlocks.of`). Pure numerics.
"""
from __future__ import annotations

import numpy as np

from aero_dva.flight.discrete_model import DiscreteWing
from aero_dva.flight.modal_kernel import run_modal

__all__ = ["ModalBlocks", "simulate", "simulate_vectorised"]


class ModalBlocks:
    """Modal form of K conditions (exact ZOH of the force over one sample).

    The model is real, so its complex modes come in conjugate pairs with conjugate states:
    only one of each pair is kept, with weight 2 (real modes weight 1; conditions with fewer
    kept modes are padded with silent ones), which nearly halves the work.

    Parameters
    ----------
    a : (K, n, n) continuous state matrices
    b : (K, n) force input vectors
    c_out : (K, p, n), d_out : (K, p) output matrices
    dt : float [s]
    hold : int, optional
        [samples] per block, the default of :func:`simulate`.
    """

    def __init__(self, a, b, c_out, d_out, dt: float, hold: int | None = None):
        s, v = np.linalg.eig(a)
        vinv = np.linalg.inv(v)
        # kept: imag > 0 (weight 2) and real (weight 1), first; the imag < 0 twins dropped
        drop = s.imag < 0
        order = np.argsort(drop, axis=-1, kind="stable")
        m = int((~drop).sum(-1).max())
        keep = order[..., :m]  # (K, m)
        k_idx = np.arange(s.shape[0])[:, None]
        weight = np.where(s.imag > 0, 2.0, np.where(drop, 0.0, 1.0))[k_idx, keep]
        s = s[k_idx, keep]
        self.vinv = vinv[k_idx, keep, :]  # (K, m, n): z = vinv x
        self.v_out = v[k_idx, :, keep].transpose(0, 2, 1) * weight[:, None, :]  # x = Re(v_out z)
        sdt = s * dt
        small = np.abs(sdt) < 1e-8
        gain = np.where(small, dt, (np.exp(sdt) - 1.0) / np.where(small, 1.0, s))
        self._gain = np.where(weight > 0, gain, 0.0)  # padded modes stay silent
        self.g = self._gain * (self.vinv @ b[..., None].astype(complex))[..., 0]  # (K, m)
        self.lam = np.where(weight > 0, np.exp(sdt), 0.0)  # z[i+1] = lam z[i] + g f[i]
        self.cm = c_out @ self.v_out  # (K, p, m): y[i] = Re(cm z[i]) + d f[i]
        self.d = np.asarray(d_out, dtype=float)
        self.hold = hold  # [samples] per block, the default of simulate()

    @classmethod
    def of(cls, wing: DiscreteWing, a, b, outputs) -> ModalBlocks:
        """The modal form of ``wing`` at K conditions given by their ``A`` (K, n, n) and
        ``B`` (K, n), with the named ``outputs`` (of
        :data:`~aero_dva.flight.discrete_model.OUTPUT_NAMES`) and the wing's sample
        interval and hold (the samples per block)."""
        c, d = wing.output_matrices(a, b)
        rows = wing.output_index(outputs)
        return cls(a, b, c[:, rows], d[:, rows], wing.dt, wing.hold)

    def with_input(self, b, d_out) -> ModalBlocks:
        """The same modes driven by another input (columns ``b`` (K, n), feedthrough
        ``d_out`` (K, p)), without a second eigendecomposition."""
        other = object.__new__(ModalBlocks)
        other.__dict__.update(self.__dict__)
        other.g = self._gain * (self.vinv @ b[..., None].astype(complex))[..., 0]
        other.d = np.asarray(d_out, dtype=float)
        return other


def simulate(modes: ModalBlocks, condition: np.ndarray, force: np.ndarray,
             block: int | None = None) -> np.ndarray:
    """Outputs (p, n_samples) of the model from rest, block ``i`` held at ``condition[i]``.

    One compiled pass over the samples (:func:`aero_dva.flight.modal_kernel.run_modal`);
    :func:`simulate_vectorised` is the same recursion in NumPy, the reference.

    Parameters
    ----------
    modes : ModalBlocks
    condition : (B,) int
        Index into the K conditions of ``modes`` per block; B = ceil(n_samples / block).
    force : (n_samples,) [N]
    block : int, optional
        [samples] block length (default: the hold of ``modes``).
    """
    block, n, _ = _checked(modes, condition, force, block)
    out = np.empty((modes.cm.shape[1], n))
    if n == 0:
        return out
    return run_modal(modes.lam, modes.g, modes.cm, modes.d, modes.vinv, modes.v_out,
                     np.ascontiguousarray(condition, dtype=np.int64),
                     np.ascontiguousarray(force, dtype=float), int(block), out)


def _checked(modes: ModalBlocks, condition, force, block) -> tuple[int, int, int]:
    block = modes.hold if block is None else block
    if block is None:
        raise ValueError("block must be given for modes without a hold")
    n = force.size
    nb = -(-n // block)
    if condition.shape != (nb,):
        raise ValueError(f"condition must have one entry per block ({nb}), got "
                         f"{condition.shape}")
    return block, n, nb


def simulate_vectorised(modes: ModalBlocks, condition: np.ndarray, force: np.ndarray,
                        block: int | None = None) -> np.ndarray:
    """:func:`simulate` in NumPy: the modal states stepped sample by sample within the
    blocks, vectorised over all blocks at once (twice: from rest for the block-end states,
    then from the true initial states), and carried from block to block in physical
    coordinates where the condition changes (a short loop over blocks)."""
    block, n, nb = _checked(modes, condition, force, block)
    u = np.zeros(nb * block)
    u[:n] = force
    u = u.reshape(nb, block)
    lam, g = modes.lam[condition], modes.g[condition]  # (B, n)
    with np.errstate(over="ignore", invalid="ignore"):
        z = np.zeros(lam.shape, dtype=complex)
        for i in range(block):  # forced end state of every block from rest
            z = lam * z + g * u[:, i, None]
        ends = z
        # initial modal state of every block (sequential over blocks, few operations each)
        z0 = np.empty_like(ends)
        lam_block = modes.lam ** block
        z = np.zeros(ends.shape[1], dtype=complex)
        cond = condition.tolist()
        prev = cond[0]
        for i, k in enumerate(cond):
            if k != prev:  # through the physical state into the new condition's modes
                z = modes.vinv[k] @ (modes.v_out[prev] @ z).real
                prev = k
            z0[i] = z
            z = lam_block[k] * z + ends[i]
        states = np.empty((block, nb, lam.shape[1]), dtype=complex)  # contiguous per step
        z = z0
        for i in range(block):
            states[i] = z
            z = lam * z + g * u[:, i, None]
        y = (modes.cm[condition] @ states.transpose(1, 2, 0)).real
        y += modes.d[condition][..., None] * u[:, None, :]
    return y.transpose(1, 0, 2).reshape(-1, nb * block)[:, :n]

