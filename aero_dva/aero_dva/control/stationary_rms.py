"""Exact stationary RMS response of the wing to white-noise aileron force (the study's sec. 7.1.1).

The study's control objective is the RMS of the vibration response, which it estimated from
long simulations. For a linear model driven by white noise the stationary RMS has an exact
value; this module computes it in two settings.

Sampled system (``method="discrete"``), exactly as :mod:`aero_dva.flight.batch_simulator` simulates
-------------------------------------------------------------------------------------------
The aileron force is held over each sample of ``dt = 1 / sample_rate`` (zero-order hold) and
is independent from sample to sample with standard deviation ``sigma = force_std`` [N]. With
the exact ZOH discretisation of eq. 6.7-6.9, ``x[k+1] = Phi x[k] + Gamma f[k]``, the stationary
state covariance solves the discrete Lyapunov equation::

    P = Phi P Phi^T + sigma^2 Gamma Gamma^T

The displacements are ``y[k] = C x[k]`` (the state at the sample instant, before ``f[k]``
acts), so their variances are ``diag(C P C^T)``; the accelerations carry the force directly,
``a[k] = C_a x[k] + D_a f[k]``, so their variances are ``diag(C_a P C_a^T) + sigma^2 D_a^2``.

Continuous limit (``method="continuous"``)
------------------------------------------
As ``dt -> 0`` at fixed force intensity ``q = sigma^2 dt`` [N^2 s] (two-sided spectral density
``q / (2 pi)`` per rad/s), the held force tends to white noise with ``E f(t) f(s) = q
delta(t - s)`` and the covariance solves the continuous Lyapunov equation::

    A P + P A^T + q B B^T = 0

The displacement variances of the two settings differ by ``O(dt)`` relative (in practice
``O(dt^2)``: the held force's spectrum differs from white by ``sinc^2(f dt)``); for the reference
wing the difference at 1 kHz is about 1e-4 (``tests/unit/aero_dva/control/test_stationary_rms.py``,
``docs/control.md``). The accelerations have a white component in the continuous limit, so their
variance is infinite there and only the sampled setting reports them.

How the equations are solved
----------------------------
Both equations are solved in the modal coordinates of ``A = V diag(lambda) V^-1``, which makes
them diagonal, for many systems at once (one batched eigen-decomposition)::

    sampled:     P~_ij = sigma^2 g_i conj(g_j) h_i conj(h_j) / (1 - mu_i conj(mu_j)),
                 mu_i = exp(lambda_i dt),  h_i = (mu_i - 1) / lambda_i
    continuous:  P~_ij = -q g_i conj(g_j) / (lambda_i + conj lambda_j)

with ``g = V^-1 B`` and ``P = V P~ V^H``; ``h_i`` is the exact ZOH input factor of mode ``i``
(so ``Phi = V diag(mu) V^-1`` and ``Gamma = V diag(h) g``, eq. 6.8-6.9). With ``em_i = mu_i -
1`` from ``expm1``, ``1 - mu_i conj(mu_j) = -(em_i + conj em_j + em_i conj em_j)``, so slow
modes lose no digits to cancellation. The RMS of an output row ``c`` is then
``sqrt(Re sum_ij (c V)_i P~_ij conj((c V)_j))``. Where the
eigenvector matrix is ill-conditioned (near-coalescing eigenvalues; 1-norm condition number
above :data:`CONDITION_LIMIT`) the system is solved instead by the vectorised Kronecker form
of the Lyapunov equation restricted to symmetric ``P`` (``n (n + 1) / 2`` unknowns), with
``Phi`` and ``Gamma`` from :func:`aero_dva.flight.discretize.zoh`.

Stability
---------
The RMS is ``inf`` (never a number from an invalid solution) unless every eigenvalue of ``A``
has a negative real part. Exactly neutral eigenvalues (``|lambda| <``
:data:`aero_dva.wing.flutter.NEUTRAL`, e.g. the free integrator of a locked Maxwell damper,
``c2 = inf``) are ignored when the force does not excite them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aero_dva.flight.discretize import zoh
from aero_dva.wing.checks import non_negative, positive
from aero_dva.wing.flutter import NEUTRAL
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES, AeroelasticModel

__all__ = [
    "CONDITION_LIMIT",
    "METHODS",
    "StationaryRMS",
    "solve_continuous_lyapunov_batch",
    "solve_discrete_lyapunov_batch",
    "stationary_covariance",
    "stationary_rms",
]

METHODS = ("discrete", "continuous")

CONDITION_LIMIT = 1.0e5
"""1-norm condition number of the eigenvector matrix above which a system is solved by the
Kronecker form instead of in modal coordinates (modal round-off grows like its square)."""

_CHUNK = 4096  # systems per batch in the Kronecker solver (bounds memory: 4096 x 45^2 doubles)


# -- Kronecker solvers --------------------------------------------------------------------------

def _sym_index(n: int):
    """Index arrays of the symmetric (upper-triangle) reduction of an n x n Lyapunov operator."""
    i, j = np.triu_indices(n)
    ir, jr = i[:, None], j[:, None]
    kc, lc = i[None, :], j[None, :]
    return i, j, ir, jr, kc, lc, (kc < lc)


def _check_square(m, name: str) -> np.ndarray:
    m = np.asarray(m, dtype=float)
    if m.ndim < 2 or m.shape[-1] != m.shape[-2]:
        raise ValueError(f"{name} must have shape (..., n, n), got {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError(f"{name} must be finite")
    return m


def _solve_sym(op_builder, m: np.ndarray, q: np.ndarray, sign: float) -> np.ndarray:
    """Solve ``L(P) = sign * Q`` for symmetric P; ``op_builder`` gives L on the upper triangle."""
    shape = np.broadcast_shapes(m.shape[:-2], q.shape[:-2])
    n = m.shape[-1]
    m = np.broadcast_to(m, shape + (n, n)).reshape(-1, n, n)
    q = np.broadcast_to(q, shape + (n, n)).reshape(-1, n, n)
    i, j = np.triu_indices(n)
    out = np.empty_like(m)
    for s in range(0, m.shape[0], _CHUNK):
        sl = slice(s, s + _CHUNK)
        op = op_builder(m[sl])
        rhs = sign * 0.5 * (q[sl][:, i, j] + q[sl][:, j, i])
        try:
            p = np.linalg.solve(op, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular operator: solve one by one, NaN for those
            p = np.full(rhs.shape, np.nan)
            for k in range(op.shape[0]):
                try:
                    p[k] = np.linalg.solve(op[k], rhs[k])
                except np.linalg.LinAlgError:
                    pass
        block = out[sl]
        block[:, i, j] = p
        block[:, j, i] = p
    return out.reshape(shape + (n, n))


def _discrete_operator(phi: np.ndarray) -> np.ndarray:
    """``I - (Phi (x) Phi)`` on the symmetric unknowns (b, m, m)."""
    n = phi.shape[-1]
    _, _, ir, jr, kc, lc, off = _sym_index(n)
    flat = phi.reshape(phi.shape[0], n * n)

    def g(r, c):
        return np.take(flat, r * n + c, axis=1)

    op = g(ir, kc) * g(jr, lc)
    op += np.where(off, g(ir, lc) * g(jr, kc), 0.0)
    return np.eye(op.shape[-1]) - op


def _continuous_operator(a: np.ndarray) -> np.ndarray:
    """``P -> A P + P A^T`` on the symmetric unknowns (b, m, m)."""
    n = a.shape[-1]
    _, _, ir, jr, kc, lc, off = _sym_index(n)
    flat = a.reshape(a.shape[0], n * n)

    def g(r, c):
        return np.take(flat, r * n + c, axis=1)

    op = g(ir, kc) * (jr == lc) + (ir == kc) * g(jr, lc)
    op += np.where(off, g(ir, lc) * (jr == kc) + (ir == lc) * g(jr, kc), 0.0)
    return op


def solve_discrete_lyapunov_batch(phi, q) -> np.ndarray:
    """Solve ``P = Phi P Phi^T + Q`` for many systems at once (Kronecker form).

    Parameters
    ----------
    phi : array_like, shape (..., n, n)
        Transition matrices; the solution is unique when no product of two eigenvalues is 1
        (and is the stationary covariance when all ``|eig| < 1``).
    q : array_like, shape (..., n, n)
        Symmetric right-hand sides (only the symmetric part is used).

    Returns
    -------
    ndarray, shape (..., n, n)
        Symmetric solutions (NaN for a system whose operator is singular).
    """
    phi = _check_square(phi, "phi")
    q = _check_square(q, "q")
    if q.shape[-1] != phi.shape[-1]:
        raise ValueError(f"q must have shape (..., {phi.shape[-1]}, {phi.shape[-1]})")
    return _solve_sym(_discrete_operator, phi, q, 1.0)


def solve_continuous_lyapunov_batch(a, q) -> np.ndarray:
    """Solve ``A P + P A^T + Q = 0`` for many systems at once (Kronecker form).

    Parameters
    ----------
    a : array_like, shape (..., n, n)
        System matrices; unique solution when no two eigenvalues sum to 0.
    q : array_like, shape (..., n, n)
        Symmetric right-hand sides.

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    a = _check_square(a, "a")
    q = _check_square(q, "q")
    if q.shape[-1] != a.shape[-1]:
        raise ValueError(f"q must have shape (..., {a.shape[-1]}, {a.shape[-1]})")
    return _solve_sym(_continuous_operator, a, q, -1.0)


# -- modal solution -----------------------------------------------------------------------------

@dataclass(frozen=True)
class _Modal:
    lam: np.ndarray      # (B, n) eigenvalues [rad/s]
    v: np.ndarray        # (B, n, n) eigenvectors
    g: np.ndarray        # (B, n) modal input per newton (neutral undriven modes zeroed)
    stable: np.ndarray   # (B,)
    growth: np.ndarray   # (B,) [1/s] largest real part of the non-neutral eigenvalues
    modal_ok: np.ndarray  # (B,) eigenvector matrix well conditioned


def _modal(a: np.ndarray, b: np.ndarray) -> _Modal:
    lam, v = np.linalg.eig(a)
    try:
        vi = np.linalg.inv(v)
        ok = np.ones(lam.shape[0], dtype=bool)
    except np.linalg.LinAlgError:
        vi = np.zeros_like(v)
        ok = np.ones(lam.shape[0], dtype=bool)
        for k in range(v.shape[0]):
            try:
                vi[k] = np.linalg.inv(v[k])
            except np.linalg.LinAlgError:
                ok[k] = False
    cond = np.abs(v).sum(axis=-2).max(axis=-1) * np.abs(vi).sum(axis=-2).max(axis=-1)
    ok &= np.isfinite(cond) & (cond <= CONDITION_LIMIT)
    g = np.einsum("bij,bj->bi", vi, b)
    neutral = np.abs(lam) < NEUTRAL
    scale = np.abs(g).max(axis=-1, keepdims=True)
    driven_neutral = neutral & (np.abs(g) > 1e-9 * scale)
    g = np.where(neutral, 0.0, g)
    growth = np.where(neutral, -np.inf, lam.real).max(axis=-1)
    stable = (growth < 0.0) & ~driven_neutral.any(axis=-1)
    return _Modal(lam, v, g, stable, growth, ok)


def _one_minus_exp(z: np.ndarray) -> np.ndarray:
    """``1 - exp(z)`` for complex ``z`` without cancellation near 0 (real arithmetic)."""
    x, y = z.real, z.imag
    s = np.sin(0.5 * y)
    re = -(np.expm1(x) * np.cos(y) - 2.0 * s * s)
    return re - 1j * (np.exp(x) * np.sin(y))


def _inverse_denominators(lam: np.ndarray, em: np.ndarray | None) -> np.ndarray:
    """``1 / (1 - mu_i conj(mu_j))`` (sampled, ``mu = exp(lambda dt)``) or ``-1 / (lambda_i +
    conj lambda_j)`` (continuous, ``em`` None), shape (B, n, n).

    With ``em = exp(lambda dt) - 1`` from ``expm1``, ``1 - mu_i conj(mu_j) = -(em_i +
    conj(em_j) + em_i conj(em_j))`` keeps its digits for slow modes without evaluating an
    exponential per pair. Pairs with a neutral mode give 0 (they are not excited).
    """
    if em is None:
        den = -(lam[:, :, None] + lam.conj()[:, None, :])
    else:
        emc = em.conj()[:, None, :]
        den = -(em[:, :, None] + emc + em[:, :, None] * emc)
    zero = den == 0
    return np.where(zero, 0.0, 1.0 / np.where(zero, 1.0, den))


def _modal_inputs(mod: _Modal, dt: float | None, em: np.ndarray | None) -> np.ndarray:
    """Modal input per newton of force, (B, n): ``g`` (continuous) or ``h g`` (sampled) with
    ``h_i = (exp(lambda_i dt) - 1) / lambda_i`` [s] the exact ZOH input factor of mode i."""
    if em is None:
        return mod.g
    zero = mod.lam == 0
    h = np.where(zero, dt, em / np.where(zero, 1.0, mod.lam))
    return h * mod.g


def _output_variance(alpha: np.ndarray, inv_den: np.ndarray) -> np.ndarray:
    """``Re sum_ij alpha_ki conj(alpha_kj) inv_den_ij`` for alpha (B, k, n) -> (B, k)."""
    return np.sum((alpha @ inv_den) * np.conj(alpha), axis=-1).real


def _correlation_sum(alpha: np.ndarray, inv_den: np.ndarray, em: np.ndarray, scale: float,
                     feedthrough: np.ndarray, var: np.ndarray) -> np.ndarray:
    """``sum over all lags of R(tau)^2 / R(0)^2`` [samples] per output row, (B, k).

    An output ``y[k] = c x[k] + d f[k]`` has, for ``tau >= 1``, ``R(tau) = c Phi^(tau-1)
    (Phi P c^T + sigma^2 Gamma d)``. In modal form ``R(tau) = sum_i beta_i mu_i^(tau-1)`` with
    ``mu_i = exp(lambda_i dt) = 1 + em_i``, ``beta_i = a_i mu_i + sigma^2 d alpha_i``, ``a_i =
    (c V)_i (P~ (c V)^H)_i`` and ``alpha_i = (c V)_i h_i g_i``; hence ``sum_{tau >= 1} R^2 =
    sum_ij beta_i beta_j / (1 - mu_i mu_j)``, and the two-sided sum adds ``R(0)^2 = var``
    once.
    """
    amp = scale * alpha * (np.conj(alpha) @ inv_den.transpose(0, 2, 1))  # (B, k, n)
    beta = amp * (1.0 + em)[:, None, :] + scale * feedthrough[..., None] * alpha
    den = -(em[:, :, None] + em[:, None, :] + em[:, :, None] * em[:, None, :])
    zero = den == 0
    inv2 = np.where(zero, 0.0, 1.0 / np.where(zero, 1.0, den))
    tail = np.sum((beta @ inv2) * beta, axis=-1).real
    with np.errstate(divide="ignore", invalid="ignore"):
        return (var**2 + 2.0 * tail) / var**2


# -- Kronecker fallback for ill-conditioned eigenvectors ----------------------------------------

def _kron_covariance(a, b, dt, force_std):
    if dt is None:
        q = np.einsum("bi,bj->bij", b, b)  # intensity applied by the caller
        return solve_continuous_lyapunov_batch(a, q)
    phi, gam = zoh(a, b, dt)
    return solve_discrete_lyapunov_batch(phi, force_std**2 * np.einsum("bi,bj->bij", gam, gam))


def _kron_correlation_sum(a, b, p, rows, feedthrough, dt, sigma):
    """As :func:`_correlation_sum` by Kronecker solves: ``sum_{tau >= 1} R^2 = c X c^T`` with
    ``X = Phi X Phi^T + v v^T``, ``v = Phi P c^T + sigma^2 Gamma d``; rows (B, k, n)."""
    phi, gam = zoh(a, b, dt)
    out = np.empty(rows.shape[:2])
    for k in range(rows.shape[1]):
        c = rows[:, k]
        v = np.einsum("bij,bjk,bk->bi", phi, p, c) + sigma**2 * feedthrough[:, k, None] * gam
        x = solve_discrete_lyapunov_batch(phi, np.einsum("bi,bj->bij", v, v))
        tail = np.einsum("bi,bij,bj->b", c, x, c)
        var = np.einsum("bi,bij,bj->b", c, p, c) + sigma**2 * feedthrough[:, k] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            out[:, k] = (var**2 + 2.0 * tail) / var**2
    return out


# -- public API ---------------------------------------------------------------------------------

def _method(method: str) -> str:
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    return method


def stationary_covariance(a, b, *, force_std: float = 1000.0, sample_rate: float = 1000.0,
                          method: str = "discrete") -> np.ndarray:
    """Stationary state covariance under white-noise force (see the module docstring).

    Parameters
    ----------
    a : array_like, shape (..., n, n)
        System matrices [1/s].
    b : array_like, shape (..., n)
        Input vectors of the force [per N].
    force_std : float
        ``sigma`` [N], standard deviation of the force per sample (>= 0).
    sample_rate : float
        [Hz] ``1 / dt``; the continuous setting uses it for the intensity ``sigma^2 dt``.
    method : {"discrete", "continuous"}

    Returns
    -------
    ndarray, shape (..., n, n)
        ``P`` in state units squared; all ``inf`` for an unstable system.
    """
    method = _method(method)
    a = _check_square(a, "a")
    b = np.asarray(b, dtype=float)
    if b.shape[-1:] != a.shape[-1:]:
        raise ValueError(f"b must have shape (..., {a.shape[-1]}), got {b.shape}")
    sigma = non_negative(force_std, "force_std")
    dt = 1.0 / positive(sample_rate, "sample_rate")
    shape = np.broadcast_shapes(a.shape[:-2], b.shape[:-1])
    n = a.shape[-1]
    a = np.broadcast_to(a, shape + (n, n)).reshape(-1, n, n)
    b = np.broadcast_to(b, shape + (n,)).reshape(-1, n)
    mod = _modal(a, b)
    step = dt if method == "discrete" else None
    scale = sigma**2 if method == "discrete" else sigma**2 * dt
    with np.errstate(all="ignore"):
        em = None if step is None else -_one_minus_exp(mod.lam * dt)
        gt = _modal_inputs(mod, step, em)
        pt = scale * gt[:, :, None] * gt.conj()[:, None, :] * _inverse_denominators(mod.lam, em)
        p = (mod.v @ pt @ np.conj(mod.v).transpose(0, 2, 1)).real
    redo = mod.stable & ~mod.modal_ok
    if np.any(redo):
        pk = _kron_covariance(a[redo], b[redo], dt if method == "discrete" else None, sigma)
        p[redo] = pk if method == "discrete" else scale * pk
    p[~mod.stable] = np.inf
    return p.reshape(shape + (n, n))


@dataclass(frozen=True)
class StationaryRMS:
    """Stationary RMS responses at many conditions (leading axes ``...`` of the inputs).

    Attributes
    ----------
    displacement : ndarray, shape (..., 4)
        RMS of plunge [m], pitch [rad], leading edge [m], absorber stroke [m]
        (:data:`~aero_dva.wing.model.DISPLACEMENT_NAMES`); ``inf`` where unstable.
    acceleration : ndarray, shape (..., 3) or None
        RMS of plunge [m/s^2], pitch [rad/s^2], leading-edge [m/s^2] acceleration
        (sampled setting only; None for the continuous limit, where it is infinite).
    growth_rate : ndarray, shape (...)
        [1/s] Largest real part of the (non-neutral) eigenvalues.
    stable : ndarray of bool, shape (...)
    correlation_samples : ndarray, shape (..., 7) or None
        ``sum over all lags tau of rho(tau)^2`` [samples] of the four displacements then the
        three accelerations, with ``rho`` the autocorrelation coefficient in the sampled
        system (when requested). It sets the sampling error of an RMS estimated from samples:
        see :meth:`relative_standard_error`.
    method : str
        ``"discrete"`` or ``"continuous"``.
    force_std : float
        [N] standard deviation of the force per sample.
    sample_rate : float
        [Hz]
    """

    displacement: np.ndarray
    acceleration: np.ndarray | None
    growth_rate: np.ndarray
    stable: np.ndarray
    correlation_samples: np.ndarray | None
    method: str
    force_std: float
    sample_rate: float

    def output(self, name: str) -> np.ndarray:
        """RMS (...) of one displacement output by name (``plunge``, ``pitch``, ...)."""
        if name not in DISPLACEMENT_NAMES:
            raise ValueError(f"name must be one of {DISPLACEMENT_NAMES}, got {name!r}")
        return self.displacement[..., DISPLACEMENT_NAMES.index(name)]

    def relative_standard_error(self, n_samples: int, n_records: int = 1,
                                kind: str = "displacement") -> np.ndarray:
        """Expected relative standard error of an RMS estimated from samples.

        For a zero-mean Gaussian stationary sequence the mean of ``x^2`` over ``N`` samples
        has variance ``(2 R(0)^2 / N) sum_tau rho(tau)^2`` (``N`` much longer than the
        correlation time), and the RMS, its square root, has half its relative error::

            SE(RMS) / RMS = sqrt(correlation_samples / (2 N M))

        for ``M`` independent records of ``N`` samples each (mean squares pooled).
        ``N / correlation_samples`` is the effective number of independent samples.

        Parameters
        ----------
        n_samples : int
            ``N`` samples per record (after any settling time is discarded).
        n_records : int
            ``M`` independent records.
        kind : {"displacement", "acceleration"}

        Returns
        -------
        ndarray, shape (..., 4) for displacements or (..., 3) for accelerations
        """
        if self.correlation_samples is None:
            raise ValueError("computed without correlation=True (sampled setting only)")
        if kind not in ("displacement", "acceleration"):
            raise ValueError(f"kind must be 'displacement' or 'acceleration', got {kind!r}")
        n = positive(n_samples, "n_samples")
        m = positive(n_records, "n_records")
        n_d = len(DISPLACEMENT_NAMES)
        corr = (self.correlation_samples[..., :n_d] if kind == "displacement"
                else self.correlation_samples[..., n_d:])
        return np.sqrt(corr / (2.0 * n * m))


def stationary_rms(model: AeroelasticModel, airspeed, density, damping=None, *,
                   force_std: float = 1000.0, sample_rate: float = 1000.0,
                   method: str = "discrete", correlation: bool = False) -> StationaryRMS:
    """Exact stationary RMS of the wing's responses to white-noise aileron force.

    Parameters
    ----------
    model : AeroelasticModel
        The wing, absorber and (time-domain) aerodynamics.
    airspeed : float or array_like
        ``U`` [m/s].
    density : float or array_like
        ``rho`` [kg/m^3].
    damping : float or array_like, optional
        Tunable damper [N s/m] (``c2`` of a Maxwell absorber, ``c1`` of a passive one);
        default the absorber's. ``airspeed``, ``density`` and ``damping`` broadcast together
        to the result's shape ``...``.
    force_std : float
        ``sigma`` [N], standard deviation of the force per sample (the seed: 1 kN).
    sample_rate : float
        [Hz] The simulator's sample rate (the seed: 1000 Hz).
    method : {"discrete", "continuous"}
        The sampled system as simulated, or its continuous limit (module docstring).
    correlation : bool
        Also compute :attr:`StationaryRMS.correlation_samples` (sampled setting only).

    Returns
    -------
    StationaryRMS
    """
    if not isinstance(model, AeroelasticModel):
        raise TypeError(f"model must be an AeroelasticModel, got {type(model).__name__}")
    method = _method(method)
    if correlation and method != "discrete":
        raise ValueError("correlation=True needs method='discrete'")
    sigma = non_negative(force_std, "force_std")
    rate = positive(sample_rate, "sample_rate")
    dt = 1.0 / rate
    a, b = model.matrices(airspeed, density, damping if model.absorber is not None else None)
    shape = a.shape[:-2]
    n = a.shape[-1]
    a = a.reshape(-1, n, n)
    b = b.reshape(-1, n)
    c_disp = model.c_displacement
    discrete = method == "discrete"
    step = dt if discrete else None
    scale = sigma**2 if discrete else sigma**2 * dt
    mod = _modal(a, b)
    n_d = len(DISPLACEMENT_NAMES)
    rows = np.broadcast_to(c_disp, (a.shape[0],) + c_disp.shape)
    if discrete:
        c_acc, d_acc = model.acceleration_output(a, b)
        rows = np.concatenate([rows, c_acc], axis=1)
    var_a = corr = None
    with np.errstate(all="ignore"):
        em = None if step is None else -_one_minus_exp(mod.lam * dt)
        alpha = (rows @ mod.v) * _modal_inputs(mod, step, em)[:, None, :]
        inv_den = _inverse_denominators(mod.lam, em)
        var = scale * _output_variance(alpha, inv_den)
        var_d = var[:, :n_d]
        if discrete:
            var_a = var[:, n_d:] + sigma**2 * d_acc**2
            if correlation:
                feed = np.concatenate([np.zeros((a.shape[0], n_d)), d_acc], axis=1)
                corr = _correlation_sum(alpha, inv_den, em, scale, feed,
                                        np.concatenate([var_d, var_a], axis=1))
    redo = mod.stable & ~mod.modal_ok
    if np.any(redo):
        p = _kron_covariance(a[redo], b[redo], step, sigma)
        if not discrete:
            p = scale * p
        var_d[redo] = np.einsum("kn,bnm,km->bk", c_disp, p, c_disp)
        if discrete:
            var_a[redo] = (np.einsum("bkn,bnm,bkm->bk", c_acc[redo], p, c_acc[redo])
                           + sigma**2 * d_acc[redo] ** 2)
            if correlation:
                corr[redo] = _kron_correlation_sum(a[redo], b[redo], p, rows[redo],
                                                   feed[redo], dt, sigma)
    bad = ~mod.stable
    rms_d = np.sqrt(np.maximum(var_d, 0.0))
    rms_d[bad] = np.inf
    rms_a = None
    if var_a is not None:
        rms_a = np.sqrt(np.maximum(var_a, 0.0))
        rms_a[bad] = np.inf
        rms_a = rms_a.reshape(shape + (len(ACCELERATION_NAMES),))
    if corr is not None:
        corr[bad] = np.inf
        corr = corr.reshape(shape + (corr.shape[-1],))
    return StationaryRMS(
        displacement=rms_d.reshape(shape + (len(DISPLACEMENT_NAMES),)),
        acceleration=rms_a,
        growth_rate=mod.growth.reshape(shape),
        stable=mod.stable.reshape(shape),
        correlation_samples=corr,
        method=method,
        force_std=sigma,
        sample_rate=rate,
    )
