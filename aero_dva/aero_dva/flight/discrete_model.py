"""The wing sampled in time: one discrete model that every simulator of the flight layer uses.

:class:`DiscreteWing` holds, for one :class:`~aero_dva.wing.model.AeroelasticModel` and one
sample interval ``dt``, the exact zero-order-hold model of each flight condition (airspeed
``U``, density ``rho``, damper setting ``c2``; Zhang (2006) eq. 6.7-6.9)::

    x[i+1] = Ad x[i] + Bd u[i]        y[i] = C x[i] + D u[i]

with the inputs ``u`` = the aileron force (and, for the hidden plant's cubic spring, a pitch
moment) held over each sample, and the outputs :data:`OUTPUT_NAMES` (4 displacements, then 3
accelerations). It also holds the *parameter hold* every simulator shares: ``U``, ``rho`` and
``c2`` are sampled once every ``hold`` samples and a held value is only replaced when its
input moved by more than ``quantum`` (relative, :func:`next_held`), so a flight needs a few
hundred discretisations, each cached by its exact condition.

Users: the streaming simulator (:mod:`.streaming_simulator`, the simulator node's), the
batch simulator of many whole flights (:mod:`.batch_simulator`), the parallel-in-time sweep
(:mod:`.sweep_simulator`), the hidden plant (:mod:`.hidden_plant`) and the modal simulator of
a logged flight (:mod:`.modal_simulator`, the discrepancy loop's). Pure numerics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from aero_dva.flight.discretize import check_sampling, zoh
from aero_dva.wing.checks import positive, real_array
from aero_dva.wing.model import ACCELERATION_NAMES, DISPLACEMENT_NAMES, AeroelasticModel

__all__ = [
    "ACCELERATION_OUTPUTS",
    "DEFAULT_HOLD",
    "DISPLACEMENT_OUTPUTS",
    "FLIGHT_QUANTUM",
    "INPUT_NAMES",
    "N_DISPLACEMENTS",
    "N_OUTPUTS",
    "OUTPUT_NAMES",
    "DiscreteCondition",
    "DiscreteMatrices",
    "DiscreteWing",
    "held_values",
    "moment_probe",
    "next_held",
    "pitch_moment_input",
]

DISPLACEMENT_OUTPUTS = DISPLACEMENT_NAMES
ACCELERATION_OUTPUTS = tuple(f"{name}_acceleration" for name in ACCELERATION_NAMES)
#: The sampled outputs, rows of ``C`` and ``D``: plunge [m], pitch [rad], leading edge [m],
#: absorber stroke [m], then the plunge [m/s^2], pitch [rad/s^2] and leading-edge [m/s^2]
#: accelerations.
OUTPUT_NAMES = DISPLACEMENT_OUTPUTS + ACCELERATION_OUTPUTS
N_DISPLACEMENTS = len(DISPLACEMENT_OUTPUTS)
N_OUTPUTS = len(OUTPUT_NAMES)
#: Inputs a discrete model can take, in this order: the aileron force [N] and a pitch moment
#: [N m] about the gravity centre (the hidden plant's cubic spring enters through it).
INPUT_NAMES = ("force", "pitch_moment")

DEFAULT_HOLD = 10
"""[samples] between updates of the held airspeed, density and damper setting."""
FLIGHT_QUANTUM = 1e-3
"""Relative change of a held input below which a flown scenario keeps the held value (the
flight runtime's, the sweep's and the hidden plant's): eigenvalue shifts of about 1e-3
relative, far below the model's accuracy, and a ramp reuses each discretisation."""


# -- the parameter hold --------------------------------------------------------------------
def next_held(raw, held, quanta) -> tuple:
    """The held values after a grid sample of the inputs ``raw`` (a tuple).

    Each input replaces its held value (``held``; NaN: none yet) only when it differs from it
    by more than its quantum (relative, ``quanta`` one per input); so constant inputs stay
    exact and a ramp reuses each value for a few hold periods.
    """
    return tuple(cur if abs(v - cur) <= q * abs(cur) else v
                 for v, cur, q in zip(raw, held, quanta))


def held_values(raw: np.ndarray, held: np.ndarray, quantum: float) -> np.ndarray:
    """:func:`next_held` over successive hold periods of many flights, one quantum.

    ``raw`` (F, P, k) are the inputs at the periods' first samples and ``held`` (F, k) the
    values in force before (NaN: none). Returns the values in force (F, P, k).
    """
    if quantum == 0.0 or raw.shape[1] == 0:
        return raw.copy()
    out = np.empty_like(raw)
    for f in range(raw.shape[0]):
        for j in range(raw.shape[2]):
            col = raw[f, :, j]
            cur = float(held[f, j])
            if col[0] == col[-1] and np.all(col == col[0]):  # constant: at most one change
                keep = abs(col[0] - cur) <= quantum * abs(cur)
                out[f, :, j] = cur if keep else col[0]
                continue
            vals = col.tolist()
            for p, v in enumerate(vals):
                if not abs(v - cur) <= quantum * abs(cur):  # also true when cur is NaN
                    cur = v
                vals[p] = cur
            out[f, :, j] = vals
    return out


# -- the pitch-moment input ----------------------------------------------------------------
def pitch_moment_input(model: AeroelasticModel, airspeed, density, damping,
                       other: AeroelasticModel | None = None) -> np.ndarray:
    """State-space input vector of a unit pitch moment [N m] at the given conditions.

    ``B`` of the aileron force at x is M^-1 [1, -x, ...] on the velocity rows, linear in x, so
    a pitch moment's column is (B(x_2) - B(x_1)) / (x_1 - x_2) (public API only). ``other``
    (optional, for speed) is :func:`moment_probe` of ``model``.
    """
    other = moment_probe(model) if other is None else other
    x1, x2 = model.wing.aileron_position, other.wing.aileron_position
    _, b1 = model.matrices(airspeed, density, damping)
    _, b2 = other.matrices(airspeed, density, damping)
    return (b2 - b1) / (x1 - x2)


def moment_probe(model: AeroelasticModel) -> AeroelasticModel:
    """``model`` with the aileron force moved along the chord (see :func:`pitch_moment_input`)."""
    wing = model.wing
    x2 = wing.leading_edge
    if math.isclose(wing.aileron_position, x2):
        x2 = wing.trailing_edge
    return AeroelasticModel(wing.replace(aileron_position=x2), model.absorber, model.aero)


# -- the discrete model --------------------------------------------------------------------
@dataclass(frozen=True)
class DiscreteMatrices:
    """The sampled model of ``K`` conditions (one input: ``bd`` (K, n), ``d`` (K, p)).

    Attributes
    ----------
    ad : (K, n, n)
    bd : (K, n, m) or (K, n)
    c : (K, p, n)
        Rows :data:`OUTPUT_NAMES`.
    d : (K, p, m) or (K, p)
    """

    ad: np.ndarray
    bd: np.ndarray
    c: np.ndarray
    d: np.ndarray


class DiscreteCondition(NamedTuple):
    """One held condition as the maps a stepping simulator applies to ``[state; inputs]``.

    Attributes
    ----------
    step : (n + p, n + m)
        One sample: ``[x[i+1]; y[i]] = step @ [x[i]; u[i]]``, i.e. ``[[Ad, Bd], [C, D]]``.
    period : (n + p h, n + h)
        A whole hold period driven by the first input alone: ``[x[h]; y] = period @ [x[0];
        u_0[0..h-1]]``, output ``o`` at sample ``j`` in row ``n + o h + j``.
    """

    step: np.ndarray
    period: np.ndarray

    @property
    def n_states(self) -> int:
        return self.step.shape[0] - N_OUTPUTS

    @property
    def ad(self) -> np.ndarray:
        return self.step[:self.n_states, :self.n_states]

    @property
    def bd(self) -> np.ndarray:
        return self.step[:self.n_states, self.n_states:]

    @property
    def c(self) -> np.ndarray:
        return self.step[self.n_states:, :self.n_states]

    @property
    def d(self) -> np.ndarray:
        return self.step[self.n_states:, self.n_states:]


class DiscreteWing:
    """The wing of ``model`` sampled at ``sample_rate`` (module docstring).

    Parameters
    ----------
    model : AeroelasticModel
    sample_rate : float
        [Hz], > 0.
    hold : int
        [samples] between updates of the held airspeed, density and damper setting, >= 1.
    quantum : float
        Relative change of an input below which the held value is kept, in [0, 0.1).
    inputs : tuple of str
        Among :data:`INPUT_NAMES`, the force first.
    max_conditions : int
        Discretised conditions kept before the cache starts afresh (~11 kB each).
    """

    def __init__(self, model: AeroelasticModel, sample_rate: float, *,
                 hold: int = DEFAULT_HOLD, quantum: float = 0.0, inputs=("force",),
                 max_conditions: int = 2048):
        if not isinstance(model, AeroelasticModel):
            raise TypeError(f"model must be an AeroelasticModel, got {type(model).__name__}")
        self.model = model
        self.n_states = model.n_states
        self.sample_rate = positive(sample_rate, "sample_rate")
        self.dt = 1.0 / self.sample_rate
        if isinstance(hold, bool) or int(hold) != hold or int(hold) < 1:
            raise ValueError(f"hold must be an integer >= 1, got {hold}")
        self.hold = int(hold)
        quantum = float(quantum)
        if not 0.0 <= quantum < 0.1:
            raise ValueError(f"quantum must be in [0, 0.1), got {quantum}")
        self.quantum = quantum
        inputs = tuple(inputs)
        if not inputs or inputs[0] != "force" or len(set(inputs)) != len(inputs) or any(
                i not in INPUT_NAMES for i in inputs):
            raise ValueError(f"inputs must start with 'force' and be among {INPUT_NAMES}, "
                             f"got {inputs}")
        self.inputs = inputs
        self.max_conditions = int(max_conditions)
        self._probe = moment_probe(model) if "pitch_moment" in inputs else None
        self._conditions: dict[tuple, DiscreteCondition] = {}
        self._identity = np.eye(self.n_states)
        self._sampling_passed: set[tuple] = set()

    # -- what it is ------------------------------------------------------------------------
    output_names = OUTPUT_NAMES
    n_outputs = N_OUTPUTS

    @property
    def n_inputs(self) -> int:
        return len(self.inputs)

    @property
    def state_names(self) -> tuple:
        return self.model.state_names

    @staticmethod
    def output_index(names) -> list[int]:
        """Rows of ``C`` and ``D`` of the named outputs; ValueError naming an unknown one."""
        unknown = [n for n in names if n not in OUTPUT_NAMES]
        if unknown:
            raise ValueError(f"unknown outputs {unknown}; known: {list(OUTPUT_NAMES)}")
        return [OUTPUT_NAMES.index(n) for n in names]

    # -- inputs ----------------------------------------------------------------------------
    def default_damping(self) -> float:
        """The damper setting when none is given: the absorber's own (0 without one)."""
        ab = self.model.absorber
        return 0.0 if ab is None else ab.damping

    def checked_inputs(self, airspeed, density, damping, shape):
        """Airspeed, density and damping broadcast to ``shape`` and checked (>= 0, no NaN;
        the damping may be inf, ``None``: :meth:`default_damping`)."""
        if damping is None:
            damping = self.default_damping()
        u = real_array(airspeed, "airspeed")
        rho = real_array(density, "density")
        c = real_array(damping, "damping", allow_inf=True)
        for name, v in (("airspeed", u), ("density", rho), ("damping", c)):
            if np.any(v < 0):  # checked before broadcasting: a scalar once, not per sample
                raise ValueError(f"{name} must be >= 0")
        return tuple(np.broadcast_to(v, shape) for v in (u, rho, c))

    def check_sampling(self, airspeed: float, density: float, damping: float) -> None:
        """ValueError if a mode at this condition is at or above the Nyquist frequency
        (conditions that passed are remembered: repeated flights start at the same one)."""
        key = (float(airspeed), float(density), float(damping))
        if key in self._sampling_passed:
            return
        a, _ = self.model.matrices(airspeed, density,
                                   damping if self.model.absorber is not None else None)
        check_sampling(a, self.dt)
        if len(self._sampling_passed) >= 1024:
            self._sampling_passed.clear()
        self._sampling_passed.add(key)

    def held_sequence(self, raws, held: tuple) -> list[tuple]:
        """:func:`next_held` with this model's quantum over successive grid samples ``raws``
        (tuples), from ``held``: the held values of each period. (The rule inlined: the
        streaming simulator's hot path.)"""
        q = self.quantum
        if q == 0.0:
            return [tuple(raw) for raw in raws]
        out = []
        if len(held) == 3:  # (U, rho, damping), unrolled
            u0, r0, c0 = held
            for u, r, c in raws:
                if not abs(u - u0) <= q * abs(u0):  # also true when the held value is NaN
                    u0 = u
                if not abs(r - r0) <= q * abs(r0):
                    r0 = r
                if not abs(c - c0) <= q * abs(c0):
                    c0 = c
                out.append((u0, r0, c0))
            return out
        for raw in raws:
            held = tuple(cur if abs(v - cur) <= q * abs(cur) else v for v, cur in zip(raw, held))
            out.append(held)
        return out

    # -- matrices --------------------------------------------------------------------------
    def continuous(self, params: np.ndarray):
        """``A`` (K, n, n) and ``B`` (K, n[, m]) at checked conditions ``params`` (K, 3) =
        [U, rho, damping] (B a vector per condition when the force is the only input)."""
        model = self.model
        damping = params[:, 2] if model.absorber is not None else None
        a, b = model.matrices_unchecked(params[:, 0], params[:, 1], damping)
        if self._probe is None:
            return a, b
        bm = pitch_moment_input(model, params[:, 0], params[:, 1], damping, self._probe)
        return a, np.stack([b, bm], axis=-1)

    def output_matrices(self, a: np.ndarray, b: np.ndarray):
        """``C`` (K, p, n) and ``D`` (K, p[, m]) of :data:`OUTPUT_NAMES` from ``A``, ``B``."""
        model = self.model
        k, n = a.shape[0], a.shape[-1]
        columns = b[..., None] if b.ndim == a.ndim - 1 else b
        cacc, dacc = model.acceleration_output(a, columns[..., 0])
        c = np.concatenate([np.broadcast_to(model.c_displacement, (k, N_DISPLACEMENTS, n)),
                            cacc], axis=1)
        d = np.zeros((k, N_OUTPUTS, columns.shape[-1]))
        d[:, N_DISPLACEMENTS:, 0] = dacc
        for i in range(1, columns.shape[-1]):
            d[:, N_DISPLACEMENTS:, i] = model.acceleration_output(a, columns[..., i])[1]
        return c, (d[..., 0] if b.ndim == a.ndim - 1 else d)

    def discretise(self, params, expm=None) -> DiscreteMatrices:
        """The sampled model of the checked conditions ``params`` (K, 3), in one batch
        (``expm``: the matrix exponential of a stack, as for :func:`zoh`)."""
        params = np.asarray(params, dtype=float).reshape(-1, 3)
        a, b = self.continuous(params)
        ad, bd = zoh(a, b, self.dt, expm)
        c, d = self.output_matrices(a, b)
        return DiscreteMatrices(ad=ad, bd=bd, c=c, d=d)

    # -- held conditions, cached -------------------------------------------------------------
    def at(self, airspeed: float, density: float, damping: float) -> DiscreteCondition:
        """The sampled model of one held condition (cached: rebuilt only when it changes)."""
        return self.conditions([(float(airspeed), float(density), float(damping))])[0]

    def conditions(self, keys: list) -> list[DiscreteCondition]:
        """The maps of the held conditions ``keys`` (tuples (U, rho, damping)); those not yet
        cached are discretised together, in one batch."""
        cache = self._conditions
        missing = [k for k in keys if k not in cache]
        if missing:
            missing = list(dict.fromkeys(missing))
            if len(cache) + len(missing) > self.max_conditions:
                cache.clear()  # then every key of this call is missing, not only the new ones
                missing = list(dict.fromkeys(keys))
            for key, condition in zip(missing, self._maps(missing)):
                cache[key] = condition
        return [cache[k] for k in keys]

    @property
    def cached(self) -> int:
        """Number of conditions in the cache."""
        return len(self._conditions)

    def _maps(self, keys: list) -> list[DiscreteCondition]:
        # The streaming simulator's hot path (a few new conditions per 50-sample block): the
        # one-sample map is filled straight from the parts rather than via discretise().
        model = self.model
        if self._probe is None:
            a, b = model.matrices_of(keys)
        else:
            a, b = self.continuous(np.array(keys, dtype=float))
        ad, bd = zoh(a, b, self.dt)
        h, ns, k, p, nd = self.hold, self.n_states, len(keys), N_OUTPUTS, N_DISPLACEMENTS
        ni = self.n_inputs
        step = np.zeros((k, ns + p, ns + ni))
        step[:, :ns, :ns] = ad
        step[:, ns:ns + nd, :ns] = model.c_displacement
        if ni == 1:
            step[:, :ns, ns] = bd
            step[:, ns + nd:, :ns], step[:, ns + nd:, ns] = model.acceleration_output(a, b)
        else:
            step[:, :ns, ns:] = bd
            step[:, ns + nd:, :ns], step[:, ns + nd:, ns] = model.acceleration_output(
                a, b[..., 0])
            for i in range(1, ni):
                step[:, ns + nd:, ns + i] = model.acceleration_output(a, b[..., i])[1]
        # The period map is h steps of the one-sample map applied to [state; forces] as a
        # linear function of (start state, the period's h forces): ``x`` holds the state's
        # map and, in its last row, the selector of the force acting at that sample. The
        # outputs go straight into their rows of the period map (a view of them by output
        # and sample), the state's map into its first rows at the end.
        force_step = step if ni == 1 else step[:, :, :ns + 1]
        period = np.empty((k, ns + p * h, ns + h))
        outputs = period[:, ns:].reshape(k, p, h, ns + h)
        x = np.zeros((k, ns + 1, ns + h))
        state, selector = x[:, :ns], x[:, ns]
        state[:, :, :ns] = self._identity
        for j in range(h):
            if j:
                selector[:, ns + j - 1] = 0.0
            selector[:, ns + j] = 1.0
            r = force_step @ x
            outputs[:, :, j] = r[:, ns:]
            state[...] = r[:, :ns]
        period[:, :ns] = state
        return [DiscreteCondition(step=step[i], period=period[i]) for i in range(k)]
