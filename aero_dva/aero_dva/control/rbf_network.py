"""Gaussian RBF network trained by orthogonal least squares (Zhang (2006) eq. 7.4-7.5).

Hidden neuron ``j`` responds to an input ``p`` with ``a_j = exp(-(b ||w_j - p||)^2)``
(eq. 7.4 with the transfer function of eq. 7.5); the output layer is linear with a bias,
``y = sum_j LW_j a_j + b2`` (fig. 7.10). All neurons share ``b = sqrt(ln 2) / spread``, so a
neuron's response falls to 1/2 at distance ``spread`` from its centre (the convention of the
radial basis tools the study cites). Distances are measured between *scaled* inputs,
``(x - input_offset) / input_scale``, because the 33 inputs mix scaled spectra (order 0.1)
with the damper coefficient (order 10^3 N s/m).

Training follows Chen, Cowan & Grant (1991), "Orthogonal least squares learning algorithm for
radial basis function networks", IEEE Trans. Neural Networks 2(2):302-309: the candidate
centres are the training inputs; each step orthogonalises the remaining candidate regressors
against the ones already chosen (Gram-Schmidt) and picks the candidate with the largest error
reduction ratio; selection stops when the unexplained fraction of the target falls below a
tolerance or at a maximum number of neurons. The constant (bias) regressor is always chosen
first and the ratios are taken relative to the target's variance about its mean, so the
tolerance means the same thing whatever the target's offset.

Inputs are rows: arrays of shape (n_samples, input_dim), one sample per row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from aero_dva.control.spectrum import DEFAULT_FREQUENCIES

__all__ = [
    "SPECTRUM_INPUT_DIM",
    "InputScaling",
    "OLSTrainingResult",
    "RBFNetwork",
    "SpreadSelection",
    "fit_input_scaling",
    "select_spread",
    "spectrum_input_names",
    "spectrum_input_vector",
    "train_rbf_ols",
]

#: Inputs of the study's network: 2 channels x 16 scaled spectrum values (5..20 Hz) + current c2.
SPECTRUM_INPUT_DIM = 33

_LN2_SQRT = float(np.sqrt(np.log(2.0)))


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def _as_matrix(x, name: str, input_dim: int | None = None) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{name} must have shape (n_samples, input_dim), got {arr.shape}")
    if input_dim is not None and arr.shape[1] != input_dim:
        raise ValueError(f"{name} must have {input_dim} columns, got {arr.shape[1]}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (found NaN or inf)")
    return arr


def _as_targets(y, name: str, n: int) -> np.ndarray:
    arr = np.asarray(y, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (found NaN or inf)")
    return arr


def _positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value)
    if not np.isfinite(value) or value <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {value}")
    return value


@dataclass(frozen=True)
class InputScaling:
    """Affine input scaling ``x_scaled = (x - offset) / scale``.

    Attributes
    ----------
    offset : ndarray, shape (input_dim,)
        Per-input offset, in the input's unit.
    scale : ndarray, shape (input_dim,)
        Per-input scale (> 0), in the input's unit.
    """

    offset: np.ndarray
    scale: np.ndarray

    def __post_init__(self):
        offset = np.array(self.offset, dtype=float, ndmin=1)
        scale = np.array(self.scale, dtype=float, ndmin=1)
        if offset.ndim != 1 or scale.shape != offset.shape:
            raise ValueError(
                f"offset and scale must be 1-D of equal length, got {offset.shape}, {scale.shape}"
            )
        if not (np.all(np.isfinite(offset)) and np.all(np.isfinite(scale))):
            raise ValueError("offset and scale must be finite")
        if np.any(scale <= 0.0):
            raise ValueError("scale must be > 0 for every input")
        object.__setattr__(self, "offset", _frozen(offset))
        object.__setattr__(self, "scale", _frozen(scale))

    @property
    def input_dim(self) -> int:
        """Number of inputs."""
        return self.offset.size

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Scale inputs of shape (..., input_dim)."""
        return (x - self.offset) / self.scale


def fit_input_scaling(inputs) -> InputScaling:
    """Min-max scaling that maps each input's training range onto [0, 1].

    Parameters
    ----------
    inputs : array_like, shape (n_samples, input_dim)
        Training inputs.

    Returns
    -------
    InputScaling
        ``offset`` = column minimum, ``scale`` = column range; a constant column gets scale 1
        (it then contributes nothing to distances).
    """
    x = _as_matrix(inputs, "inputs")
    lo = x.min(axis=0)
    span = x.max(axis=0) - lo
    return InputScaling(lo, np.where(span > 0.0, span, 1.0))


@dataclass(frozen=True)
class RBFNetwork:
    """Two-layer Gaussian RBF network with a linear output (Zhang (2006) eq. 7.4-7.5, fig. 7.10).

    Attributes
    ----------
    centres : ndarray, shape (n_neurons, input_dim)
        Hidden-layer weight vectors ``w_j`` (IW), in scaled input space.
    output_weights : ndarray, shape (n_neurons,)
        Output-layer weights (LW), in the output's unit.
    output_bias : float
        Output-layer bias ``b2``, in the output's unit.
    spread : float
        [1, scaled input space] distance at which a neuron's response is 1/2.
    scaling : InputScaling
        Input scaling applied before distances are taken.
    input_names : tuple of str
        One name per input.
    input_units : tuple of str
        One unit per input ("1" for dimensionless).
    output_name, output_unit : str
        Name and unit of the output (default damper coefficient c2 in N s/m).
    """

    centres: np.ndarray
    output_weights: np.ndarray
    output_bias: float
    spread: float
    scaling: InputScaling
    input_names: tuple[str, ...] = field(default=())
    input_units: tuple[str, ...] = field(default=())
    output_name: str = "damping"
    output_unit: str = "N s/m"

    def __post_init__(self):
        centres = np.array(self.centres, dtype=float)
        weights = np.array(self.output_weights, dtype=float, ndmin=1)
        if centres.ndim != 2:
            raise ValueError(
                f"centres must have shape (n_neurons, input_dim), got {centres.shape}"
            )
        if weights.shape != (centres.shape[0],):
            raise ValueError(
                f"output_weights must have shape ({centres.shape[0]},), got {weights.shape}"
            )
        if not isinstance(self.scaling, InputScaling):
            raise TypeError("scaling must be an InputScaling")
        if self.scaling.input_dim != centres.shape[1]:
            raise ValueError(
                f"scaling has {self.scaling.input_dim} inputs but centres have {centres.shape[1]}"
            )
        if not (np.all(np.isfinite(centres)) and np.all(np.isfinite(weights))):
            raise ValueError("centres and output_weights must be finite")
        bias = float(self.output_bias)
        if not np.isfinite(bias):
            raise ValueError("output_bias must be finite")
        spread = _positive(self.spread, "spread")
        dim = centres.shape[1]
        names = tuple(self.input_names) or tuple(f"x{i}" for i in range(dim))
        units = tuple(self.input_units) or ("1",) * dim
        for label, values in (("input_names", names), ("input_units", units)):
            if len(values) != dim or not all(isinstance(v, str) for v in values):
                raise ValueError(f"{label} must be {dim} strings, got {len(values)}")
        object.__setattr__(self, "centres", _frozen(centres))
        object.__setattr__(self, "output_weights", _frozen(weights))
        object.__setattr__(self, "output_bias", bias)
        object.__setattr__(self, "spread", spread)
        object.__setattr__(self, "input_names", names)
        object.__setattr__(self, "input_units", units)

    @property
    def input_dim(self) -> int:
        """Number of inputs."""
        return self.centres.shape[1]

    @property
    def n_neurons(self) -> int:
        """Number of hidden neurons ``S_1``."""
        return self.centres.shape[0]

    @property
    def width_factor(self) -> float:
        """The bias ``b`` of eq. 7.4, ``sqrt(ln 2) / spread``, in 1 / (scaled input unit)."""
        return _LN2_SQRT / self.spread

    def hidden(self, inputs) -> np.ndarray:
        """Hidden-layer outputs ``a`` (eq. 7.4-7.5), shape (n_samples, n_neurons)."""
        x = self.scaling.apply(_as_matrix(np.atleast_2d(inputs), "inputs", self.input_dim))
        return _gaussian(x, self.centres, self.width_factor)

    def predict(self, inputs):
        """Network output.

        Parameters
        ----------
        inputs : array_like, shape (n_samples, input_dim) or (input_dim,)
            Unscaled inputs in their own units.

        Returns
        -------
        ndarray of shape (n_samples,), or float for a 1-D input
            Output in ``output_unit`` (N s/m for c2).
        """
        single = np.ndim(inputs) == 1
        y = self.hidden(inputs) @ self.output_weights + self.output_bias
        return float(y[0]) if single else y


def _gaussian(x_scaled: np.ndarray, centres: np.ndarray, b: float) -> np.ndarray:
    # ||x - c||^2 = |x|^2 + |c|^2 - 2 x.c, clipped at 0 against round-off.
    sq = (
        np.sum(x_scaled**2, axis=1)[:, None]
        + np.sum(centres**2, axis=1)[None, :]
        - 2.0 * x_scaled @ centres.T
    )
    return np.exp(-(b**2) * np.maximum(sq, 0.0))


@dataclass(frozen=True)
class OLSTrainingResult:
    """Outcome of :func:`train_rbf_ols`.

    Attributes
    ----------
    network : RBFNetwork
        The trained network.
    selected : ndarray of int, shape (n_neurons,)
        Indices into the candidate centres, in selection order.
    error_reduction_ratios : ndarray, shape (n_neurons,)
        Error reduction ratio of each selected neuron, as a fraction of the target's variance
        about its mean; their sum is the fraction the network explains on the training set.
    unexplained_fraction : float
        ``1 - sum(error_reduction_ratios)`` at the end of selection.
    training_rmse : float
        Root mean square training error, in the output's unit.
    stop_reason : str
        "tolerance", "max_neurons" or "no_candidates".
    """

    network: RBFNetwork
    selected: np.ndarray
    error_reduction_ratios: np.ndarray
    unexplained_fraction: float
    training_rmse: float
    stop_reason: str


def train_rbf_ols(
    inputs,
    targets,
    spread: float,
    *,
    tolerance: float = 1e-3,
    max_neurons: int = 100,
    scaling: InputScaling | None = None,
    candidates=None,
    input_names: Sequence[str] = (),
    input_units: Sequence[str] = (),
    output_name: str = "damping",
    output_unit: str = "N s/m",
) -> OLSTrainingResult:
    """Train an RBF network by orthogonal least squares forward selection.

    Parameters
    ----------
    inputs : array_like, shape (n_samples, input_dim)
        Training inputs in their own units.
    targets : array_like, shape (n_samples,)
        Training targets (e.g. optimal c2 [N s/m]).
    spread : float
        Neuron spread in scaled input space (response 1/2 at this distance).
    tolerance : float
        Stop when the unexplained fraction of the target variance is below this, in (0, 1).
    max_neurons : int
        Maximum number of hidden neurons.
    scaling : InputScaling, optional
        Input scaling; by default :func:`fit_input_scaling` of ``inputs``.
    candidates : array_like, shape (n_candidates, input_dim), optional
        Candidate centres in unscaled units; by default the training inputs.
    input_names, input_units : sequence of str
        Stored with the network.
    output_name, output_unit : str
        Stored with the network.

    Returns
    -------
    OLSTrainingResult
        The network, the selection order and the error reduction ratios.

    Notes
    -----
    With ``P`` the candidate regressor matrix (``P[i, j] = a_j(x_i)``), each step considers
    the part ``w`` of every remaining column orthogonal to the chosen ones (Gram-Schmidt) and
    picks the column maximising ``err = (w.d)^2 / ((w.w) (d.d))`` where ``d`` is the target
    minus its mean (Chen et al. 1991, error reduction ratio, with the bias regressor taken
    first). Columns whose orthogonal part has a squared norm below 1e-10 of the original are
    numerically dependent and are dropped. The output weights are then the least-squares
    solution on the selected columns and the bias. Cost: one pass over the
    (n_samples, n_candidates) matrix per selected neuron; memory: that matrix.
    """
    x = _as_matrix(inputs, "inputs")
    n, dim = x.shape
    d = _as_targets(targets, "targets", n)
    spread = _positive(spread, "spread")
    tolerance = _positive(tolerance, "tolerance")
    if tolerance >= 1.0:
        raise ValueError(f"tolerance must be < 1, got {tolerance}")
    if isinstance(max_neurons, bool) or not isinstance(max_neurons, (int, np.integer)):
        raise TypeError(f"max_neurons must be an integer, got {type(max_neurons).__name__}")
    if max_neurons < 1:
        raise ValueError(f"max_neurons must be >= 1, got {max_neurons}")
    if scaling is None:
        scaling = fit_input_scaling(x)
    elif not isinstance(scaling, InputScaling):
        raise TypeError("scaling must be an InputScaling")
    elif scaling.input_dim != dim:
        raise ValueError(f"scaling has {scaling.input_dim} inputs, inputs have {dim}")
    centres_all = x if candidates is None else _as_matrix(candidates, "candidates", dim)

    xs = scaling.apply(x)
    cs = scaling.apply(centres_all)
    b = _LN2_SQRT / spread
    p = _gaussian(xs, cs, b)  # candidate regressors, one column per candidate centre
    # The bias regressor goes first: removing the column means makes every column (and the
    # target) orthogonal to the constant.
    p -= p.mean(axis=0)
    dc = d - d.mean()
    dd = float(dc @ dc)
    norms0 = np.einsum("ij,ij->j", p, p)
    # Squared norms of, and target projections on, each column's part orthogonal to the
    # chosen ones, downdated as directions are added (one pass over P per step).
    norms = norms0.copy()
    proj = p.T @ dc
    alive = norms0 > 0.0
    basis = np.empty((n, min(max_neurons, p.shape[1])))  # orthonormal chosen directions

    selected: list[int] = []
    ratios: list[float] = []
    unexplained = 1.0
    stop_reason = "max_neurons"
    if dd == 0.0:
        stop_reason = "tolerance"  # a constant target: the bias alone fits it
    while len(selected) < max_neurons and stop_reason != "tolerance":
        # A column whose orthogonal part is this small is numerically dependent on the
        # chosen ones (the downdate's round-off is ~1e-16 of the norm, far below this).
        alive &= norms > 1e-10 * norms0
        if not np.any(alive):
            stop_reason = "no_candidates"
            break
        err = np.where(alive, proj**2 / np.where(alive, norms, 1.0), -1.0) / dd
        k = int(np.argmax(err))
        m = len(selected)
        selected.append(k)
        ratios.append(float(err[k]))
        unexplained -= float(err[k])
        alive[k] = False
        v = p[:, k].copy()
        for _ in range(2):  # Gram-Schmidt twice keeps the basis orthonormal to round-off
            v -= basis[:, :m] @ (basis[:, :m].T @ v)
        q = v / np.linalg.norm(v)
        basis[:, m] = q
        coupling = q @ p
        norms -= coupling**2
        proj -= coupling * (q @ dc)
        if unexplained < tolerance:
            stop_reason = "tolerance"

    sel = np.array(selected, dtype=int)
    centres = cs[sel]
    phi = np.hstack([_gaussian(xs, centres, b), np.ones((n, 1))])
    theta, *_ = np.linalg.lstsq(phi, d, rcond=None)
    network = RBFNetwork(
        centres=centres,
        output_weights=theta[:-1],
        output_bias=float(theta[-1]),
        spread=spread,
        scaling=scaling,
        input_names=tuple(input_names),
        input_units=tuple(input_units),
        output_name=output_name,
        output_unit=output_unit,
    )
    rmse = float(np.sqrt(np.mean((phi @ theta - d) ** 2)))
    return OLSTrainingResult(
        network=network,
        selected=_frozen(sel),
        error_reduction_ratios=_frozen(np.array(ratios)),
        unexplained_fraction=max(unexplained, 0.0),
        training_rmse=rmse,
        stop_reason=stop_reason,
    )


@dataclass(frozen=True)
class SpreadSelection:
    """Outcome of :func:`select_spread`.

    Attributes
    ----------
    spreads : ndarray, shape (n_spreads,)
        Spreads tried.
    training_rmse, validation_rmse : ndarray, shape (n_spreads,)
        RMS errors on the training and held-out sets, in the output's unit.
    best_index : int
        Index of the spread with the smallest validation RMS error.
    best : OLSTrainingResult
        Training result at that spread.
    """

    spreads: np.ndarray
    training_rmse: np.ndarray
    validation_rmse: np.ndarray
    best_index: int
    best: OLSTrainingResult

    @property
    def best_spread(self) -> float:
        """The chosen spread."""
        return float(self.spreads[self.best_index])


def select_spread(
    train_inputs, train_targets, validation_inputs, validation_targets, spreads, **train_kwargs
) -> SpreadSelection:
    """Choose the spread with the smallest RMS error on held-out data.

    Parameters
    ----------
    train_inputs : array_like, shape (n_train, input_dim)
    train_targets : array_like, shape (n_train,)
    validation_inputs : array_like, shape (n_val, input_dim)
    validation_targets : array_like, shape (n_val,)
    spreads : array_like, shape (n_spreads,)
        Candidate spreads (> 0) in scaled input space.
    **train_kwargs
        Passed to :func:`train_rbf_ols` (not ``spread``). Unless ``scaling`` is given, one
        scaling fitted on the training inputs is shared by all spreads.

    Returns
    -------
    SpreadSelection
    """
    x = _as_matrix(train_inputs, "train_inputs")
    y = _as_targets(train_targets, "train_targets", x.shape[0])
    xv = _as_matrix(validation_inputs, "validation_inputs", x.shape[1])
    yv = _as_targets(validation_targets, "validation_targets", xv.shape[0])
    grid = np.array(spreads, dtype=float, ndmin=1)
    if grid.ndim != 1 or grid.size == 0 or not np.all(np.isfinite(grid)) or np.any(grid <= 0):
        raise ValueError("spreads must be a non-empty 1-D sequence of finite values > 0")
    if "spread" in train_kwargs:
        raise TypeError("pass the candidate spreads as spreads, not spread")
    train_kwargs.setdefault("scaling", fit_input_scaling(x))
    results = [train_rbf_ols(x, y, float(s), **train_kwargs) for s in grid]
    train_rmse = np.array([r.training_rmse for r in results])
    val_rmse = np.array(
        [float(np.sqrt(np.mean((r.network.predict(xv) - yv) ** 2))) for r in results]
    )
    best = int(np.argmin(val_rmse))
    return SpreadSelection(
        spreads=_frozen(grid),
        training_rmse=_frozen(train_rmse),
        validation_rmse=_frozen(val_rmse),
        best_index=best,
        best=results[best],
    )


def spectrum_input_names(
    channel_names: Sequence[str] = ("plunge", "pitch"), frequencies=None
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Names and units of the spectrum-based network's inputs.

    Parameters
    ----------
    channel_names : sequence of str
        Spectrum channels, in the order of ``dva_msgs/ScaledSpectrum.channel_names``.
    frequencies : array_like, optional
        [Hz] spectrum frequencies; default 5..20 Hz in 1 Hz steps.

    Returns
    -------
    names, units : tuple of str
        ``"<channel>_<f>Hz"`` per channel and frequency (channel-major, unit "1"), then
        ``"damping"`` (unit "N s/m"): 33 entries for the study's network.
    """
    freqs = DEFAULT_FREQUENCIES if frequencies is None else np.asarray(frequencies, float)
    names = [f"{c}_{f:g}Hz" for c in channel_names for f in freqs] + ["damping"]
    units = ["1"] * (len(names) - 1) + ["N s/m"]
    return tuple(names), tuple(units)


def spectrum_input_vector(magnitudes, damping: float) -> np.ndarray:
    """Network input from scaled spectra and the current c2.

    Parameters
    ----------
    magnitudes : array_like, shape (channels, n_freq)
        Scaled magnitudes (eq. 7.3), each channel summing to 1.
    damping : float
        [N s/m] current damper coefficient c2.

    Returns
    -------
    ndarray, shape (channels * n_freq + 1,)
        Channel-major magnitudes followed by ``damping``, the order of
        :func:`spectrum_input_names`.
    """
    m = np.asarray(magnitudes, dtype=float)
    if m.ndim != 2:
        raise ValueError(f"magnitudes must have shape (channels, n_freq), got {m.shape}")
    return np.concatenate([m.ravel(), [float(damping)]])
