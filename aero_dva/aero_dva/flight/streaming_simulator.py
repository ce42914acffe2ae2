"""One flight of the wing streamed block by block: the simulator node's simulator.

::

    sim = StreamingSimulator(wing, absorber, sample_rate=1000.0, aero=None, x0=None)
    out = sim.advance(force, airspeed, density, damping=None)  # FlightSamples of the block
    out.time            # (n,) [s] sample times, first_sample_index / sample_rate onward
    out.displacements   # (4, n) plunge [m], pitch [rad], leading_edge [m], absorber_stroke [m]
    out.accelerations   # (3, n) plunge [m/s^2], pitch [rad/s^2], leading_edge [m/s^2]
    out.diverged        # bool, sticky since the last reset
    sim.state           # (n_states,) state after the last sample
    sim.reset(x0=None)  # back to sample 0 with state x0 (zeros by default)

``force`` (n,) [N] is the aileron force, held constant over each sample (zero-order hold).
``airspeed`` [m/s], ``density`` [kg/m^3] and ``damping`` [N s/m] (``c2`` of a Maxwell
absorber, ``c1`` of a passive one; ``None`` keeps the absorber's own value) are scalars or (n,)
arrays. Sample ``i`` of a block is the state at ``time[i]`` and the acceleration there with the
force ``force[i]`` acting.

The wing is the :class:`~aero_dva.flight.discrete_model.DiscreteWing` with its parameter hold:
airspeed, density and damping are sampled on a global grid of ``hold`` samples since the last
reset and held (with hysteresis ``quantum``), so the result does not depend on how a run is cut
into ``advance`` calls. Short calls (up to :data:`STREAM_MAX_PERIODS` hold periods, such as the
simulator node's blocks) step the flight one hold period at a time with the discrete wing's
cached per-condition maps, or, with ``compiled=True``, sample by sample in the compiled loop of
:mod:`~aero_dva.flight.held_kernel` with its compiled exponential (about ten times faster per
block; :meth:`StreamingSimulator.prepare` loads it ahead); longer calls take the batch
simulator's :class:`~aero_dva.flight.batch_simulator.BatchStepper`. All give the same run up to
rounding.
"""

from __future__ import annotations

import math

import numpy as np

from aero_dva.flight.batch_simulator import BatchStepper
from aero_dva.flight.discrete_model import (
    DEFAULT_HOLD,
    N_DISPLACEMENTS,
    N_OUTPUTS,
    OUTPUT_NAMES,
    DiscreteWing,
)
from aero_dva.flight.discretize import zoh
from aero_dva.flight.samples import FlightSamples
from aero_dva.wing.checks import positive, real_array
from aero_dva.wing.model import AeroelasticModel

__all__ = ["STREAM_MAX_PERIODS", "StreamingSimulator"]

LEADING_EDGE = OUTPUT_NAMES.index("leading_edge")
#: The most states the compiled route's stacked maps take
#: (:data:`aero_dva.flight.held_kernel.STACK_STATES`; not imported from there, which imports
#: numba).
STACK_STATES = 7

STREAM_MAX_PERIODS = 128
""":meth:`StreamingSimulator.advance` calls spanning at most this many hold periods step the
flight period by period; longer calls take the batch machinery, whose vectorised carry across
periods is cheaper from a few hundred periods on."""


def _input(value, name: str, allow_inf: bool = False):
    """A flight input as a float (scalar) or a 1-D float array, checked as
    :meth:`DiscreteWing.checked_inputs` checks it.

    A float or a float 1-D array that passes is returned after one comparison (NaN fails it:
    the flight runtime's inputs, every block); anything else is checked in full, for the
    error that names what is wrong."""
    if type(value) is float:
        if value >= 0.0 and (allow_inf or value < math.inf):
            return value
    elif type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 1 \
            and value.size:
        if value.min() >= 0.0 and (allow_inf or value.max() < math.inf):
            return value
    arr = real_array(value, name, allow_inf=allow_inf)
    if arr.ndim == 0:
        x = float(arr)
        if x < 0:
            raise ValueError(f"{name} must be >= 0")
        return x
    if arr.size and arr.min() < 0:
        raise ValueError(f"{name} must be >= 0")
    return arr


def _per_sample(value, n: int) -> np.ndarray:
    """A checked input (a float or an (n,) array) as a read-only (n,) array, as
    ``np.broadcast_to`` gives it (a view of an array; for a scalar, its own copy)."""
    if isinstance(value, np.ndarray) and value.shape == (n,):
        out = value.view()
    else:
        out = np.full(n, value, dtype=float)
    out.flags.writeable = False
    return out


class StreamingSimulator:
    """Streaming simulator of the wing (see the module docstring for the contract).

    Parameters
    ----------
    wing : WingParameters
    absorber : PassiveAbsorber or MaxwellAbsorber or None
    sample_rate : float
        [Hz], > 0; every oscillatory mode at the first condition must be below Nyquist.
    aero : QuasiSteadyAero or WagnerAero, optional
        Default quasi-steady (the study's).
    x0 : array_like, shape (n_states,), optional
        Initial state (default zeros).
    hold : int
        Samples between updates of airspeed, density and damping.
    quantum : float
        Relative change of an input below which the held value is kept (0 = exact).
    divergence_limit : float, optional
        [m] ``diverged`` becomes true once the leading-edge displacement exceeds this in
        magnitude or a value is not finite (default: half the chord, far outside the range of
        the linear model).
    """

    def __init__(self, wing, absorber=None, sample_rate: float = 1000.0, aero=None, x0=None,
                 hold: int = DEFAULT_HOLD, quantum: float = 0.0, divergence_limit=None,
                 compiled: bool = False):
        self.model = AeroelasticModel(wing, absorber, aero)
        self.discrete = DiscreteWing(self.model, sample_rate, hold=hold, quantum=quantum)
        self._batch = BatchStepper(self.discrete)
        # the compiled route takes the models its stacked maps fit (every wing without the
        # finite-state Wagner lag, force input only); the others step in NumPy
        self.compiled = bool(compiled) and self.model.n_states <= STACK_STATES \
            and self.discrete.n_inputs == 1
        self._maps = _StackedMaps(self.discrete) if self.compiled else None
        if divergence_limit is None:
            divergence_limit = 0.5 * wing.chord
        self.divergence_limit = positive(divergence_limit, "divergence_limit")
        self._checked = False
        self.reset(x0)

    @property
    def sample_rate(self) -> float:
        """[Hz]"""
        return self.discrete.sample_rate

    @property
    def n_states(self) -> int:
        return self.model.n_states

    @property
    def state_names(self) -> tuple:
        return self.model.state_names

    @property
    def state(self) -> np.ndarray:
        """(n_states,) State after the last simulated sample (a copy)."""
        return self._y[0].copy()

    @property
    def sample_index(self) -> int:
        """Index of the next sample since the last reset."""
        return self._index

    @property
    def diverged(self) -> bool:
        return self._diverged

    def reset(self, x0=None) -> None:
        """Restart at sample 0 with state ``x0`` (zeros by default)."""
        n = self.model.n_states
        if x0 is None:
            y = np.zeros(n)
        else:
            y = real_array(x0, "x0")
            if y.shape != (n,):
                raise ValueError(f"x0 must have shape ({n},), got {y.shape}")
        self._y = y[None, :].copy()
        self._index = 0
        self._held = (np.nan, np.nan, np.nan)  # (airspeed, density, damping) in force
        self._diverged = False

    def continue_from(self, state, samples: int, diverged: bool) -> None:
        """Go on after ``samples`` samples flown outside this simulator (the switching law's
        damper path, :mod:`aero_dva.flight.per_sample.stream`) that ended in ``state``;
        ``diverged`` is sticky as here."""
        y = real_array(state, "state", allow_inf=True)
        if y.shape != (self.model.n_states,):
            raise ValueError(f"state must have shape ({self.model.n_states},), got {y.shape}")
        self._y = y[None, :].copy()
        self._index += int(samples)
        self._diverged = self._diverged or bool(diverged)

    def advance(self, force, airspeed, density, damping=None) -> FlightSamples:
        """Simulate ``len(force)`` samples; see the module docstring.

        Raises
        ------
        ValueError
            Bad inputs (NaN, negative airspeed/density/damping, wrong lengths), or a sample
            rate below the Nyquist rate of the wing's modes at the first condition.
        """
        f = real_array(force, "force")
        if f.ndim != 1:
            raise ValueError(f"force must be 1-D (n,), got shape {f.shape}")
        n = f.size
        for name, v in (("airspeed", airspeed), ("density", density), ("damping", damping)):
            if v is not None and np.ndim(v) not in (0,) and np.shape(v) != (n,):
                raise ValueError(f"{name} must be a scalar or have shape ({n},), "
                                 f"got {np.shape(v)}")
        dw = self.discrete
        if damping is None:
            damping = dw.default_damping()
        u, rho = _input(airspeed, "airspeed"), _input(density, "density")
        c = _input(damping, "damping", allow_inf=True)
        if not self._checked and n:
            dw.check_sampling(*(float(v) if np.ndim(v) == 0 else float(v[0])
                                for v in (u, rho, c)))
            self._checked = True
        if -(-n // dw.hold) <= STREAM_MAX_PERIODS:
            stream = self._stream_compiled if self.compiled else self._stream
            out, y, self._held = stream(self._y[0], f, u, rho, c)
            self._y = y[None, :]
        else:
            out = np.empty((1, n, N_OUTPUTS))
            shape = (1, n)
            y, held = self._batch.run(self._y, self._index, f[None, :],
                                      np.broadcast_to(u, shape), np.broadcast_to(rho, shape),
                                      np.broadcast_to(c, shape), np.array([self._held]), out,
                                      np.empty((1, n, 3)))
            self._y, self._held, out = y, tuple(held[0].tolist()), out[0].T
        disp, acc = out[:N_DISPLACEMENTS], out[N_DISPLACEMENTS:]
        first = self._index
        self._index += n
        if not self._diverged:
            self._diverged = bool(
                not np.isfinite(self._y).all()
                or not np.isfinite(disp).all()
                or (n and np.abs(disp[LEADING_EDGE]).max() > self.divergence_limit)
            )
        return FlightSamples(first_index=first, sample_rate=dw.sample_rate,
                             airspeed=_per_sample(u, n), density=_per_sample(rho, n),
                             damping=_per_sample(c, n), force=f, displacements=disp,
                             accelerations=acc, diverged=self._diverged)

    def _segments(self, total: int, airspeed, density, damping):
        """The runs of samples ``index .. index + total - 1`` under one held condition:
        ([(first, end, (U, rho, damping)), ...], the condition in force at the end)."""
        dw = self.discrete
        h = dw.hold
        first = min((h - self._index % h) % h, total)  # samples left in the current period
        count = len(range(first, total, h))
        values = [v[first::h].tolist() if isinstance(v, np.ndarray) else [v] * count
                  for v in (airspeed, density, damping)]
        held = self._held
        segments = [(0, first, held)] if first else []
        for p, key in enumerate(dw.held_sequence(zip(*values), held)):
            a = first + p * h
            segments.append((a, min(a + h, total), key))
            held = key
        return segments, held

    def _stream(self, y, force, airspeed, density, damping):
        """Step samples ``index .. index + len(force) - 1`` hold period by hold period.

        For a 50-sample block the batch machinery (deduplicating parameter rows, gathering
        per-condition matrices) costs far more than the arithmetic: here each held condition's
        maps come from the discrete wing's cache by exact key, and a full hold period is one
        matrix-vector product. Returns the outputs (p, len(force)), the end state and the
        (airspeed, density, damping) in force at the end.
        """
        dw = self.discrete
        total, h, ns = force.size, dw.hold, dw.n_states
        segments, held = self._segments(total, airspeed, density, damping)
        maps = dw.conditions([key for _, _, key in segments])
        out = np.empty((N_OUTPUTS, total))
        for (a, b, _), cond in zip(segments, maps):
            if b - a == h:
                r = cond.period @ np.concatenate((y, force[a:b]))
                y = r[:ns]
                out[:, a:b] = r[ns:].reshape(N_OUTPUTS, h)
                continue
            x = np.empty(ns + 1)
            step = cond.step
            for j in range(a, b):
                x[:ns] = y
                x[ns] = force[j]
                r = step @ x
                y = r[:ns]
                out[:, j] = r[ns:]
        return out, np.array(y), held

    def _stream_compiled(self, y, force, airspeed, density, damping):
        """:meth:`_stream` by the compiled sample loop of the held flights
        (:func:`~aero_dva.flight.held_kernel.step_stacked`, one flight, each sample under its
        period's condition; the new conditions discretised by its compiled exponential)."""
        from aero_dva.flight.held_kernel import step_stacked  # numba: loaded by prepare()

        total = force.size
        segments, held = self._segments(total, airspeed, density, damping)
        keys = np.repeat(self._maps.rows([key for _, _, key in segments]),
                         [b - a for a, b, _ in segments])
        start = np.zeros((1, self._maps.stack.shape[1] - 1))
        start[0, :y.size] = y
        out = np.empty((1, total, N_OUTPUTS))
        end = step_stacked(self._maps.stack, keys, 1, start, force[None, :], out)
        return out[0].T, end[0, :y.size], held

    def prepare(self, airspeed: float, density: float, damping: float | None = None) -> None:
        """With ``compiled``: load the compiled loop and exponential now (numba's import and
        its cached code, about a second of CPU) rather than at the first block. The
        condition (``airspeed``, ``density``, ``damping``: the flight's first) is discretised
        into the cache and one sample is stepped from rest; the flight's state is untouched."""
        if not self.compiled:
            return
        from aero_dva.flight.held_kernel import step_stacked

        if damping is None:
            damping = self.discrete.default_damping()
        rows = self._maps.rows([(float(airspeed), float(density), float(damping))])
        step_stacked(self._maps.stack, np.array(rows), 1, np.zeros((1, STACK_STATES)),
                     np.zeros((1, 1)), np.empty((1, 1, N_OUTPUTS)))


class _StackedMaps:
    """The compiled loop's stacked one-sample maps of a streamed flight's held conditions,
    kept by exact key (:func:`~aero_dva.flight.held_kernel.stack_maps`), each discretised by
    the compiled exponential when first flown."""

    def __init__(self, discrete: DiscreteWing, max_conditions: int = 2048):
        from aero_dva.flight.held_kernel import STACK_ROWS

        self.discrete = discrete
        self.max_conditions = max_conditions
        self._rows: dict[tuple, int] = {}
        self.stack = np.zeros((64, STACK_STATES + 1, STACK_ROWS))

    def rows(self, keys: list[tuple]) -> list[int]:
        """The stack's row of each held condition (U, rho, damping) of ``keys``."""
        rows = self._rows
        missing = [k for k in dict.fromkeys(keys) if k not in rows]
        if missing:
            if len(rows) + len(missing) > self.max_conditions:
                rows.clear()  # start afresh, as the discrete wing's own cache does
                missing = list(dict.fromkeys(keys))
            self._add(missing)
        return [rows[k] for k in keys]

    def _add(self, keys: list[tuple]) -> None:
        from aero_dva.flight.held_kernel import compiled_expm, stack_maps

        dw, first = self.discrete, len(self._rows)
        a, b = dw.continuous(np.array(keys, dtype=float))
        ad, bd = zoh(a, b, dw.dt, compiled_expm)
        cacc, dacc = dw.model.acceleration_output(a, b)
        if first + len(keys) > len(self.stack):
            grown = np.zeros((2 * (first + len(keys)),) + self.stack.shape[1:])
            grown[:first] = self.stack[:first]
            self.stack = grown
        self.stack[first:first + len(keys)] = stack_maps(ad, bd, cacc, dacc,
                                                         dw.model.c_displacement)
        self._rows.update((key, first + i) for i, key in enumerate(keys))
