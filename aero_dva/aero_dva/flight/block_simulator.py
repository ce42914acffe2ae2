"""Fast time simulation of the wing with time-varying airspeed, density and damper setting.

Streaming API (for the simulator node)
--------------------------------------
::

    sim = BlockSimulator(wing, absorber, sample_rate=1000.0, aero=None, x0=None)
    out = sim.advance(force, airspeed, density, damping=None)
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

Parameter hold
--------------
Airspeed, density and damping change slowly compared with the wing's dynamics, so they are
sampled once every ``hold`` samples (on a global grid: samples ``0, hold, 2 hold, ...`` since
the last reset) and held until the next grid sample, like a controller's update rate; within
that, the discretisation is the exact ZOH of the held system (eq. 6.7-6.9). The result does not
depend on how a run is cut into ``advance`` calls. With ``quantum > 0`` a held value is only
replaced when the input has moved by more than ``quantum`` (relative) from it, so that a ramp
needs a few hundred cached discretisations instead of one per hold period, while constant
inputs stay exact; ``quantum = 0`` takes every new value.

Short calls (up to :data:`STREAM_MAX_PERIODS` hold periods, such as the simulator node's
blocks) step the flight one hold period at a time with matrices cached per held condition;
longer calls take the batch machinery below. Both give the same run up to rounding.

Whole flights
-------------
:func:`simulate_flights` runs a batch of flights at once (vectorised across flights and across
hold periods; only a short loop over hold periods remains sequential), and
:func:`divergence_airspeed` reads off where a ramp flight diverged. When all flights share one
schedule, the held conditions of the whole flight are found first and discretised in one
vectorised call (:meth:`_Engine.prefetch`); then the states at the period boundaries are
carried across periods, and the outputs follow either by stepping all periods' samples in
parallel (few flights) or by one period map per hold period applied to all flights (eight or
more, :data:`BATCH_COLUMNS`).

The definition of divergence:

    *A flight has diverged at airspeed* ``U_d`` *when the RMS of the leading-edge displacement
    over consecutive windows (1 s by default) exceeds* ``factor`` *(10) times its median over the
    first* ``baseline_fraction`` *(10 %) of the flight, and stays above it for every later
    window;* ``U_d`` *is the airspeed at the end of the first such window.* A flight that never
    does gives NaN. This is insensitive to single random bursts (they do not stay above) and to
    the excitation level (the threshold is relative), and it lags the eigenvalue critical
    airspeed by the time the growing mode needs to grow tenfold, as the seed's simulated
    divergence airspeeds do (sections 6.2.4, 6.3.3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aero_dva.flight.discretize import check_sampling, zoh
from aero_dva.wing.checks import positive, real_array
from aero_dva.wing.model import AeroelasticModel

__all__ = [
    "BlockSimulator",
    "FlightTraces",
    "SimulationBlock",
    "divergence_airspeed",
    "ramp_airspeed",
    "simulate_flights",
]

DEFAULT_HOLD = 10


@dataclass(frozen=True)
class SimulationBlock:
    """Outputs of one :meth:`BlockSimulator.advance` call (time on the last axis)."""

    time: np.ndarray
    displacements: np.ndarray
    accelerations: np.ndarray
    diverged: bool


@dataclass(frozen=True)
class FlightTraces:
    """Outputs of :func:`simulate_flights` for ``F`` flights of ``N`` samples.

    Attributes
    ----------
    time : (N,) [s]
    airspeed, density, damping, force : (F, N) the inputs as applied (held)
    displacements : (F, 4, N) plunge [m], pitch [rad], leading_edge [m], absorber_stroke [m]
    accelerations : (F, 3, N) plunge [m/s^2], pitch [rad/s^2], leading_edge [m/s^2]
    final_state : (F, n_states)

    ``displacements`` and ``accelerations`` are views of one sample-major (F, N, 7) buffer
    (each hold period's outputs are computed as one contiguous block); use
    ``np.ascontiguousarray`` where a channel-major copy is needed.
    """

    time: np.ndarray
    airspeed: np.ndarray
    density: np.ndarray
    damping: np.ndarray
    force: np.ndarray
    displacements: np.ndarray
    accelerations: np.ndarray
    final_state: np.ndarray


def _hold_values(raw: np.ndarray, held: np.ndarray, quantum: float) -> np.ndarray:
    """Parameters in force for successive hold periods, with relative hysteresis.

    ``raw`` (F, P, 3) are the inputs at the periods' first samples and ``held`` (F, 3) the
    values in force before (NaN: none). A value is taken over only when it differs from the
    one in force by more than ``quantum`` relative (``quantum = 0``: always), so constant
    inputs stay exact and a ramp reuses each value for a few periods.
    """
    if quantum == 0.0 or raw.shape[1] == 0:
        return raw.copy()
    out = np.empty_like(raw)
    for f in range(raw.shape[0]):
        for j in range(3):
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


class _DiscreteCache:
    """Per-condition discrete matrices, computed in batches and kept by exact key.

    Three levels, each computed only when first needed: ``basic`` (one-sample ZOH ``phi``,
    ``gam`` and the acceleration output), ``carry`` (``phi^h`` and the forced state at the end
    of a hold period) and ``period`` (all outputs of a hold period as one matrix, rows in
    sample-major order ``j * 7 + o`` so that a period's outputs land contiguously in an
    (N, 7) buffer).
    """

    LEVELS = {"basic": ("phi", "gam", "cacc", "dacc"), "carry": ("phih", "ctrb"),
              "period": ("period",)}

    def __init__(self, model: AeroelasticModel, dt: float, hold: int, max_size: int = 4096):
        self.model, self.dt, self.hold, self.max_size = model, dt, hold, max_size
        self.clear()

    def clear(self):
        n, h = self.model.n_states, self.hold
        self.index: dict[tuple, int] = {}
        self.size = 0
        shapes = {"phi": (n, n), "gam": (n,), "cacc": (3, n), "dacc": (3,), "phih": (n, n),
                  "ctrb": (n, h), "period": (7 * h, n + h)}
        self.arr = {name: np.zeros((16,) + shape) for name, shape in shapes.items()}
        self.done = {level: np.zeros(16, dtype=bool) for level in self.LEVELS}

    def lookup(self, params: np.ndarray, level: str = "basic") -> np.ndarray:
        """Indices (K,) of the rows of ``params`` (K, 3) = [U, rho, damping], computed to
        ``level`` ("basic", "carry" or "period"; each includes the previous)."""
        params = np.asarray(params, dtype=float).reshape(-1, 3)
        # Held parameters come in runs: deduplicate the runs first (cheap), then the rest.
        new_run = np.ones(len(params), dtype=bool)
        new_run[1:] = np.any(params[1:] != params[:-1], axis=1)
        starts = np.flatnonzero(new_run)
        keys = [tuple(row) for row in params[starts].tolist()]
        index = self.index
        missing = list(dict.fromkeys(k for k in keys if k not in index))
        if missing:
            self._add_basic(np.array(missing, dtype=float))
            for k in missing:
                index[k] = len(index)
        idx = np.fromiter((index[k] for k in keys), dtype=np.intp, count=len(keys))
        if level in ("carry", "period"):
            todo = np.unique(idx[~self.done["carry"][idx]])
            if todo.size:
                self._add_carry(todo)
        if level == "period":
            todo = np.unique(idx[~self.done["period"][idx]])
            if todo.size:
                self._add_period(todo)
        return np.repeat(idx, np.diff(np.r_[starts, len(params)]))

    def _grow(self, size):
        cap = len(self.done["basic"])
        if size <= cap:
            return
        grow = max(size, 2 * cap)
        for name, arr in self.arr.items():
            bigger = np.zeros((grow,) + arr.shape[1:])
            bigger[:cap] = arr
            self.arr[name] = bigger
        for name, flags in self.done.items():
            self.done[name] = np.concatenate([flags, np.zeros(grow - cap, dtype=bool)])

    def _add_basic(self, p: np.ndarray):
        model = self.model
        damping = p[:, 2] if model.absorber is not None else None
        # The parameters were checked where they entered (_Engine.params, _input).
        a, b = model.matrices_unchecked(p[:, 0], p[:, 1], damping)
        phi, gam = zoh(a, b, self.dt)
        cacc, dacc = model.acceleration_output(a, b)
        k0, k1 = self.size, self.size + len(p)
        self._grow(k1)
        for name, value in (("phi", phi), ("gam", gam), ("cacc", cacc), ("dacc", dacc)):
            self.arr[name][k0:k1] = value
        self.done["basic"][k0:k1] = True
        self.size = k1

    def _add_carry(self, idx):
        h = self.hold
        phi, gam = self.arr["phi"][idx], self.arr["gam"][idx][..., None]
        # Forced state at the end of a period from the force at sample j: phi^(h-1-j) gamma
        # (a Krylov sequence, matrix-vector products only).
        ctrb = np.empty(gam.shape[:-1] + (h,))
        v = gam
        for j in range(h - 1, -1, -1):
            ctrb[..., j] = v[..., 0]
            if j:
                v = phi @ v
        self.arr["ctrb"][idx] = ctrb
        self.arr["phih"][idx] = _matrix_power(phi, h)
        self.done["carry"][idx] = True

    def _add_period(self, idx):
        h, model = self.hold, self.model
        phi, gam = self.arr["phi"][idx], self.arr["gam"][idx]
        cacc, dacc = self.arr["cacc"][idx], self.arr["dacc"][idx]
        k, n = gam.shape
        # Outputs over one hold period as one linear map of (start state, forces):
        # output o at sample j = obs[j, o] x0 + sum_i toep[j, o, i] u_i.
        period = np.zeros((k, h, 7, n + h))
        obs = period[..., :n]
        rows = np.concatenate([np.broadcast_to(model.c_displacement, (k, 4, n)), cacc], axis=1)
        for j in range(h):  # C phi^j, by products from the left
            obs[:, j] = rows
            if j < h - 1:
                rows = rows @ phi
        markov = (obs @ gam[:, None, :, None])[..., 0]  # (k, h, 7): C phi^j gamma
        toep = period[..., n:]
        for j in range(1, h):
            toep[:, j, :, :j] = markov[:, j - 1::-1].transpose(0, 2, 1)
        toep[:, np.arange(h), 4:, np.arange(h)] = dacc[None]
        self.arr["period"][idx] = period.reshape(k, 7 * h, n + h)
        self.done["period"][idx] = True


def _matrix_power(m: np.ndarray, power: int) -> np.ndarray:
    """``m ** power`` for a stack of square matrices (..., n, n), by repeated squaring."""
    out = None
    while power:
        if power & 1:
            out = m if out is None else out @ m
        power >>= 1
        if power:
            m = m @ m
    return out


_TALL_ROWS = 4096
"""Row block of :func:`_tall_product`: each block stays below OpenBLAS's threshold for
multithreading a product (m n k < 262144), because on a shared, busy machine a threaded
product of this size waits for the second core far longer than it computes."""


def _tall_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for a tall ``a`` (M, k) and a small ``b`` (k, m), in row blocks."""
    out = np.empty((a.shape[0], b.shape[1]))
    for i in range(0, a.shape[0], _TALL_ROWS):
        np.matmul(a[i:i + _TALL_ROWS], b, out=out[i:i + _TALL_ROWS])
    return out


def _run_partial(cache, y, keys, u, out):
    """Step ``L`` samples with one key per flight: y (F, n), keys (F,), u (F, L).

    Writes outputs into ``out`` (F, L, 7); returns the final state (F, n).
    """
    arr = cache.arr
    phi, gam = arr["phi"][keys], arr["gam"][keys]
    cacc, dacc = arr["cacc"][keys], arr["dacc"][keys]
    c_disp = cache.model.c_displacement
    for j in range(u.shape[1]):
        out[:, j, :4] = y @ c_disp.T
        out[:, j, 4:] = np.einsum("fon,fn->fo", cacc, y) + dacc * u[:, j, None]
        y = np.einsum("fij,fj->fi", phi, y) + gam * u[:, j, None]
    return y


def _carry(p: np.ndarray, g: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Start states of the recurrence ``y[i+1] = p[i] @ y[i] + g[i]`` (column layout).

    ``p`` (..., B, n, n), ``g`` (..., B, n, m), ``y`` (..., n, m) the first start; returns
    (..., B + 1, n, m). Two levels of about ``sqrt(B)`` periods keep the Python loop short:
    compose the maps within groups (vectorised over groups), carry the state across groups,
    then fill in each group (vectorised over groups).
    """
    nb, n = g.shape[-3], g.shape[-2]
    size = max(1, int(np.sqrt(nb / 2.0)))
    ng = -(-nb // size)
    pad = ng * size - nb
    if pad:
        eye = np.broadcast_to(np.eye(n), p.shape[:-3] + (pad, n, n))
        p = np.concatenate([p, eye], axis=-3)
        g = np.concatenate([g, np.zeros(g.shape[:-3] + (pad,) + g.shape[-2:])], axis=-3)
    p = p.reshape(p.shape[:-3] + (ng, size, n, n))
    g = g.reshape(g.shape[:-3] + (ng, size) + g.shape[-2:])
    pc = np.broadcast_to(np.eye(n), p.shape[:-4] + (ng, n, n))
    gc = np.zeros(g.shape[:-4] + (ng,) + g.shape[-2:])
    for s in range(size):
        ps = p[..., s, :, :]
        pc = ps @ pc
        gc = ps @ gc + g[..., s, :, :]
    starts = np.empty(np.broadcast_shapes(gc.shape, y.shape[:-2] + (1,) + y.shape[-2:])[:-3]
                      + (ng,) + gc.shape[-2:])
    for k in range(ng):
        starts[..., k, :, :] = y
        y = pc[..., k, :, :] @ y + gc[..., k, :, :]
    out = np.empty(starts.shape[:-3] + (ng, size) + starts.shape[-2:])
    x = starts
    for s in range(size):
        out[..., s, :, :] = x
        x = p[..., s, :, :] @ x + g[..., s, :, :]
    out = out.reshape(out.shape[:-4] + (ng * size,) + out.shape[-2:])[..., :nb, :, :]
    return np.concatenate([out, y[..., None, :, :]], axis=-3)


def _period_outputs(period, keys, x, out):
    """Outputs of every hold period from its start state and forces.

    ``x`` (F, B, n + h) holds, per flight and period, the start state and the ``h`` forces;
    ``keys`` (B,) the period's discretisation (shared by all flights). Writes
    ``out[f, b] = period[keys[b]] @ x[f, b]`` into ``out`` (F, B, 7 h), a period's outputs in
    sample-major order. Periods that share a key are done as one matrix product; with mostly
    distinct keys a gathered batched product (written in place, no copy) is cheaper.
    """
    nb = x.shape[1]
    uniq, inverse = np.unique(keys, return_inverse=True)
    if len(uniq) * 4 > nb:
        np.matmul(x.transpose(1, 0, 2), period[keys].transpose(0, 2, 1),
                  out=out.transpose(1, 0, 2))
        return
    order = np.argsort(inverse, kind="stable")
    bounds = np.searchsorted(inverse[order], np.arange(len(uniq) + 1))
    for g, key in enumerate(uniq):
        idx = order[bounds[g]:bounds[g + 1]]
        if idx[-1] - idx[0] + 1 == len(idx):  # consecutive periods: write in place
            sl = slice(idx[0], idx[-1] + 1)
            np.matmul(x[:, sl], period[key].T, out=out[:, sl])
        else:
            out[:, idx] = x[:, idx] @ period[key].T


BATCH_COLUMNS = 8
"""From this many flights sharing one schedule on, whole hold periods are computed as one matrix
product each (:func:`_period_outputs`); fewer flights step the samples of all periods in
parallel, which needs no per-condition period map."""


def _run_full(cache, y, rows, u, out):
    """Full hold periods: y (F, n), parameter rows (F, B, 3), u (F, B, h).

    Writes displacements and accelerations into ``out`` (F, B, h, 7); returns the final
    state. The forced response at the end of each period from rest is computed for all periods
    at once, then the states at the period boundaries (:func:`_carry`), then the outputs of all
    periods at once. Flights that share one parameter schedule share the matrices.
    """
    f, nb, h = u.shape
    arr = cache.arr
    shared = f == 1 or bool(np.all(rows == rows[:1]))
    if shared:
        k = cache.lookup(rows[0], "carry")
        level = "period" if f >= BATCH_COLUMNS or 8 * len(np.unique(k)) <= nb else "carry"
        if level == "period":
            k = cache.lookup(rows[0], "period")
        g = arr["ctrb"][k] @ u.transpose(1, 2, 0)  # (B, n, F)
        starts = _carry(arr["phih"][k], g, y.T)  # (B + 1, n, F)
        if level == "period":
            x = np.concatenate([starts[:-1].transpose(2, 0, 1), u], axis=2)
            _period_outputs(arr["period"], k, x, out.reshape(f, nb, -1))
            return starts[-1].T
        # Few flights, mostly distinct keys: step every period's samples in parallel, keep
        # the states, then form all outputs with a few large products.
        phi_t = arr["phi"][k].transpose(0, 2, 1)  # row states: x @ phi^T
        ut = u.transpose(1, 2, 0)[..., None]  # (B, h, F, 1)
        forced = ut * arr["gam"][k][:, None, None, :]  # (B, h, F, n): gamma u_j
        n = phi_t.shape[-1]
        rows_t = np.empty((nb, h, f, n))
        x = starts[:-1].transpose(0, 2, 1)  # (B, F, n)
        for j in range(h):
            rows_t[:, j] = x
            x = x @ phi_t
            x += forced[:, j]
        outs = out.transpose(1, 2, 0, 3)  # (B, h, F, 7) view of out
        outs[..., :4] = _tall_product(rows_t.reshape(-1, n),
                                      cache.model.c_displacement.T).reshape(nb, h, f, 4)
        acc = rows_t.reshape(nb, h * f, n) @ arr["cacc"][k].transpose(0, 2, 1)
        outs[..., 4:] = acc.reshape(nb, h, f, 3) + arr["dacc"][k][:, None, None, :] * ut
        return starts[-1].T
    keys = cache.lookup(rows.reshape(-1, 3), "period").reshape(f, nb)
    g = np.einsum("fbnj,fbj->fbn", arr["ctrb"][keys], u)[..., None]
    starts = _carry(arr["phih"][keys], g, y[..., None])[..., 0]  # (F, B + 1, n)
    x = np.concatenate([starts[:, :-1], u], axis=2)
    np.einsum("fbi,fboi->fbo", x, arr["period"][keys], out=out.reshape(f, nb, -1))
    return starts[:, -1]


class _Engine:
    """Shared machinery of the streaming and batch simulators."""

    def __init__(self, model, sample_rate, hold, quantum):
        self.model = model
        self.sample_rate = positive(sample_rate, "sample_rate")
        self.dt = 1.0 / self.sample_rate
        if isinstance(hold, bool) or int(hold) != hold or int(hold) < 1:
            raise ValueError(f"hold must be an integer >= 1, got {hold}")
        hold = int(hold)
        quantum = float(quantum)
        if not 0.0 <= quantum < 0.1:
            raise ValueError(f"quantum must be in [0, 0.1), got {quantum}")
        self.hold, self.quantum = hold, quantum
        self.cache = _DiscreteCache(model, self.dt, hold)

    def params(self, airspeed, density, damping, shape):
        """Broadcast inputs to ``shape`` (F, N) and check them."""
        u = np.broadcast_to(real_array(airspeed, "airspeed"), shape)
        rho = np.broadcast_to(real_array(density, "density"), shape)
        if damping is None:
            ab = self.model.absorber
            damping = 0.0 if ab is None else ab.damping
        c = np.broadcast_to(real_array(damping, "damping", allow_inf=True), shape)
        if np.any(u < 0):
            raise ValueError("airspeed must be >= 0")
        if np.any(rho < 0):
            raise ValueError("density must be >= 0")
        if np.any(c < 0):
            raise ValueError("damping must be >= 0")
        return u, rho, c

    def prefetch(self, u, rho, c, level):
        """Held conditions of a whole flight from sample 0, discretised in one batch.

        ``u``, ``rho``, ``c`` (N,) are the flight's checked inputs. Returns the held rows
        (1, P, 3) of its hold periods, the rule of :meth:`run`, to pass on to :meth:`run`:
        its lookups then find everything cached (one vectorised matrix exponential for the
        whole flight instead of one per chunk).
        """
        raw = np.stack([u[::self.hold], rho[::self.hold], c[::self.hold]], axis=-1)[None]
        rows = _hold_values(raw, np.full((1, 3), np.nan), self.quantum)
        if rows.shape[1] <= self.cache.max_size:
            self.cache.lookup(rows[0], level)
        return rows

    def run(self, y, start, force, u, rho, c, held, out, applied, shared=False, rows=None):
        """Simulate samples ``start .. start + L - 1``; y (F, n), inputs (F, L).

        ``held`` (F, 3) are the parameters in force before ``start`` (NaN: none). Writes the
        outputs into ``out`` (F, L, 7) (displacements then accelerations) and the applied
        parameters into ``applied`` (F', L, 3) (F' = 1 when all flights share their inputs,
        ``shared``). ``rows`` (F', P, 3), if given, are the held values of the hold periods
        starting in this call (from :meth:`prefetch`). Returns (y_end, held_end).
        """
        f, total = force.shape
        h = self.hold
        if shared:  # the parameters of the first flight serve all
            u, rho, c = u[:1], rho[:1], c[:1]
        if self.cache.size > self.cache.max_size:
            self.cache.clear()
        first = min((h - start % h) % h, total)  # samples left in the current hold period
        idx = np.arange(first, total, h)  # first samples of the new hold periods
        if rows is None:
            raw = np.stack([u[:, idx], rho[:, idx], c[:, idx]], axis=-1)
            rows = _hold_values(raw, held[: raw.shape[0]], self.quantum)  # (F', P, 3)
        nf = applied.shape[0]
        if first:
            y = self._partial(y, held, force, out, applied, 0, first)
        n_full = (total - first) // h
        if n_full and total >= 4 * h:
            sl = slice(first, first + n_full * h)
            pb = np.broadcast_to(rows[:, :n_full], (f, n_full, 3))
            fb = force[:, sl].reshape(f, n_full, h)
            y = _run_full(self.cache, y, pb, fb, out[:, sl].reshape(f, n_full, h, 7))
            applied[:, sl] = np.repeat(rows[:nf, :n_full], h, axis=1)
            done = n_full
        else:
            done = 0
        for p in range(done, len(idx)):  # short calls and the last, partial period
            a = first + p * h
            b = min(a + h, total)
            y = self._partial(y, rows[:, p], force, out, applied, a, b)
        held_end = rows[:, -1] if len(idx) else held
        return y, np.broadcast_to(held_end, (f, 3)).copy()

    def _partial(self, y, params, force, out, applied, a, b):
        """Samples ``a:b`` within one hold period with ``params`` (F' or F, 3)."""
        f = force.shape[0]
        keys = self.cache.lookup(np.ascontiguousarray(params))
        keys = np.broadcast_to(keys, (f,)) if keys.size == 1 else keys
        applied[:, a:b] = params[: applied.shape[0], None, :]
        return _run_partial(self.cache, y, keys, force[:, a:b], out[:, a:b])


STREAM_MAX_PERIODS = 128
""":meth:`BlockSimulator.advance` calls spanning at most this many hold periods step the flight
period by period (:class:`_Stream`); longer calls take the batch machinery, whose vectorised
carry across periods is cheaper from a few hundred periods on."""


def _input(value, name: str, allow_inf: bool = False):
    """A flight input as a float (scalar) or a 1-D float array, checked as :meth:`_Engine.params`
    checks it."""
    arr = real_array(value, name, allow_inf=allow_inf)
    if arr.ndim == 0:
        x = float(arr)
        if x < 0:
            raise ValueError(f"{name} must be >= 0")
        return x
    if arr.size and arr.min() < 0:
        raise ValueError(f"{name} must be >= 0")
    return arr


class _Stream:
    """One flight advanced in short calls: the streaming path of :class:`BlockSimulator`.

    For a 50-sample block the batch machinery (deduplicating parameter rows with np.unique,
    gathering and broadcasting per-condition matrices) costs far more than the arithmetic.
    Here a held condition is looked up by its exact parameter tuple in a dict that holds, per
    condition, two matrices acting on ``[state; forces]``:

    - ``step`` (n + 7, n + 1): one sample, giving ``[next state; 7 outputs]``;
    - ``period`` (n + 7 h, n + h): a whole hold period, giving ``[end state; outputs]`` with
      output ``o`` at sample ``j`` in row ``n + o h + j``;

    so a full hold period is one matrix-vector product. Conditions first met in a call are
    discretised together (one vectorised call for all of them). The hold rule is the batch
    path's (:func:`_hold_values`), so both give the same run up to rounding.
    """

    def __init__(self, model: AeroelasticModel, dt: float, hold: int, quantum: float,
                 max_size: int = 2048):
        self.model, self.dt, self.hold, self.quantum = model, dt, hold, quantum
        self.max_size = max_size  # ~11 kB per condition
        self.maps: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

    def run(self, y, start, force, airspeed, density, damping, held):
        """Simulate samples ``start .. start + len(force) - 1``.

        ``y`` (n_states,) is the state at ``start``; ``airspeed``, ``density``, ``damping``
        are floats or (len(force),) arrays; ``held`` the (airspeed, density, damping) in force
        before ``start`` (NaN: none). Returns the outputs (7, len(force)), the end state and
        the parameters in force at the end.
        """
        total, h, ns = force.size, self.hold, self.model.n_states
        first = min((h - start % h) % h, total)  # samples left in the current hold period
        count = len(range(first, total, h))
        values = [v[first::h].tolist() if isinstance(v, np.ndarray) else [v] * count
                  for v in (airspeed, density, damping)]
        segments = [(0, first, held)] if first else []
        quantum = self.quantum
        for p, raw in enumerate(zip(*values)):
            if quantum == 0.0:
                held = raw
            else:  # keep a value until its input moves by more than quantum (relative)
                held = tuple(cur if abs(v - cur) <= quantum * abs(cur) else v
                             for v, cur in zip(raw, held))
            a = first + p * h
            segments.append((a, min(a + h, total), held))
        if len(self.maps) > self.max_size:
            self.maps.clear()
        missing = list(dict.fromkeys(key for _, _, key in segments if key not in self.maps))
        if missing:
            self._discretise(missing)
        out = np.empty((7, total))
        for a, b, key in segments:
            step, period = self.maps[key]
            if b - a == h:
                r = period @ np.concatenate((y, force[a:b]))
                y = r[:ns]
                out[:, a:b] = r[ns:].reshape(7, h)
                continue
            x = np.empty(ns + 1)
            for j in range(a, b):
                x[:ns] = y
                x[ns] = force[j]
                r = step @ x
                y = r[:ns]
                out[:, j] = r[ns:]
        return out, np.array(y), held

    def _discretise(self, keys: list) -> None:
        """Add the ``step`` and ``period`` matrices of the conditions ``keys``."""
        model, h, ns, k = self.model, self.hold, self.model.n_states, len(keys)
        p = np.array(keys, dtype=float)
        a, b = model.matrices_unchecked(p[:, 0], p[:, 1],
                                        p[:, 2] if model.absorber is not None else None)
        phi, gam = zoh(a, b, self.dt)
        cacc, dacc = model.acceleration_output(a, b)
        step = np.zeros((k, ns + 7, ns + 1))
        step[:, :ns, :ns], step[:, :ns, ns] = phi, gam
        step[:, ns:ns + 4, :ns] = model.c_displacement
        step[:, ns + 4:, :ns], step[:, ns + 4:, ns] = cacc, dacc
        # The period map is h steps of the one-sample map applied to [state; forces] as a
        # linear function of (start state, the period's h forces): ``x`` holds the state's
        # map and, in its last row, the selector of the force acting at that sample.
        outputs = np.empty((k, 7, h, ns + h))
        x = np.zeros((k, ns + 1, ns + h))
        x[:, :ns, :ns] = np.eye(ns)
        for j in range(h):
            x[:, ns] = 0.0
            x[:, ns, ns + j] = 1.0
            r = step @ x
            outputs[:, :, j] = r[:, ns:]
            x[:, :ns] = r[:, :ns]
        period = np.concatenate([x[:, :ns], outputs.reshape(k, 7 * h, ns + h)], axis=1)
        for i, key in enumerate(keys):
            self.maps[key] = (step[i], period[i])


class BlockSimulator:
    """Streaming simulator of the wing (see the module docstring for the contract).

    Parameters
    ----------
    wing : WingParameters
    absorber : PassiveAbsorber or MaxwellAbsorber or None
    sample_rate : float
        [Hz], > 0; every oscillatory mode at the first condition must be below Nyquist.
    aero : QuasiSteadyAero or WagnerAero, optional
        Default quasi-steady (the seed's).
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
                 hold: int = DEFAULT_HOLD, quantum: float = 0.0, divergence_limit=None):
        self.model = AeroelasticModel(wing, absorber, aero)
        self._engine = _Engine(self.model, sample_rate, hold, quantum)
        self._stream = _Stream(self.model, self._engine.dt, self._engine.hold,
                               self._engine.quantum)
        if divergence_limit is None:
            divergence_limit = 0.5 * wing.chord
        self.divergence_limit = positive(divergence_limit, "divergence_limit")
        self._checked = False
        self.reset(x0)

    @property
    def sample_rate(self) -> float:
        """[Hz]"""
        return self._engine.sample_rate

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

    def advance(self, force, airspeed, density, damping=None) -> SimulationBlock:
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
        eng = self._engine
        if damping is None:
            damping = 0.0 if self.model.absorber is None else self.model.absorber.damping
        u, rho = _input(airspeed, "airspeed"), _input(density, "density")
        c = _input(damping, "damping", allow_inf=True)
        if not self._checked and n:
            u0, rho0, c0 = (float(v) if np.ndim(v) == 0 else float(v[0]) for v in (u, rho, c))
            a, _ = self.model.matrices(u0, rho0, c0 if self.model.absorber is not None else None)
            check_sampling(a, eng.dt)
            self._checked = True
        if -(-n // eng.hold) <= STREAM_MAX_PERIODS:
            out, y, self._held = self._stream.run(self._y[0], self._index, f, u, rho, c,
                                                  self._held)
            self._y = y[None, :]
        else:
            out = np.empty((1, n, 7))
            shape = (1, n)
            y, held = eng.run(self._y, self._index, f[None, :], np.broadcast_to(u, shape),
                              np.broadcast_to(rho, shape), np.broadcast_to(c, shape),
                              np.array([self._held]), out, np.empty((1, n, 3)))
            self._y, self._held, out = y, tuple(held[0].tolist()), out[0].T
        disp, acc = out[:4], out[4:]
        time = (self._index + np.arange(n)) / eng.sample_rate
        self._index += n
        if not self._diverged:
            self._diverged = bool(
                not np.all(np.isfinite(self._y))
                or not np.all(np.isfinite(disp))
                or (n and np.max(np.abs(disp[2])) > self.divergence_limit)
            )
        return SimulationBlock(time=time, displacements=disp, accelerations=acc,
                               diverged=self._diverged)


def simulate_flights(wing, absorber=None, *, force, airspeed, density, damping=None,
                     sample_rate: float = 1000.0, aero=None, x0=None,
                     hold: int = DEFAULT_HOLD, quantum: float = 2e-3,
                     chunk: int | None = None) -> FlightTraces:
    """Simulate a batch of whole flights at once.

    Parameters
    ----------
    wing, absorber, aero
        As for :class:`BlockSimulator`.
    force : array_like, shape (F, N) or (N,)
        Aileron force [N] per flight and sample.
    airspeed, density, damping : array_like
        Broadcastable to (F, N): [m/s], [kg/m^3], [N s/m] (``None``: the absorber's value).
    sample_rate : float
        [Hz]
    x0 : array_like, shape (n_states,) or (F, n_states), optional
    hold, quantum : see the module docstring. ``quantum`` (default 2e-3) lets a held value
        lag its input by up to 0.2 % (0.2 m/s at 100 m/s) in exchange for speed.
    chunk : int, optional
        Hold periods processed together (bounds memory; default about 65536 / F).

    Returns
    -------
    FlightTraces
    """
    model = AeroelasticModel(wing, absorber, aero)
    eng = _Engine(model, sample_rate, hold, quantum)
    f = real_array(force, "force")
    if f.ndim == 1:
        f = f[None, :]
    if f.ndim != 2:
        raise ValueError(f"force must have shape (F, N) or (N,), got {f.shape}")
    nf, total = f.shape
    u, rho, c = eng.params(airspeed, density, damping, (nf, total))
    n = model.n_states
    y = np.zeros((nf, n)) if x0 is None else np.broadcast_to(real_array(x0, "x0"), (nf, n))
    y = np.array(y, dtype=float)
    a, _ = model.matrices(u[0, 0], rho[0, 0], c[0, 0] if absorber is not None else None)
    check_sampling(a, eng.dt)
    shared = all(np.ndim(v) <= 1 for v in (airspeed, density, damping))
    rows = None
    if shared and total >= 4 * eng.hold:
        rows = eng.prefetch(u[0], rho[0], c[0], "period" if nf >= BATCH_COLUMNS else "carry")
    out = np.empty((nf, total, 7))  # sample-major: each hold period's outputs are contiguous
    applied = np.empty((1 if shared else nf, total, 3))
    held = np.full((nf, 3), np.nan)
    periods = int(np.clip(65536 // nf, 32, 4096)) if chunk is None else max(1, int(chunk))
    if not shared:  # per-flight matrices are gathered: bound that memory (~32 MB)
        periods = max(8, min(periods, int(4e6 // (nf * 7 * eng.hold * (n + eng.hold)))))
    step = periods * eng.hold
    for s in range(0, total, step):
        sl = slice(s, min(s + step, total))
        part = None if rows is None else rows[:, s // eng.hold:-(-sl.stop // eng.hold)]
        y, held = eng.run(y, s, f[:, sl], u[:, sl], rho[:, sl], c[:, sl], held, out[:, sl],
                          applied[:, sl], shared, part)
    applied = np.broadcast_to(applied, (nf, total, 3))
    return FlightTraces(
        time=np.arange(total) / eng.sample_rate,
        airspeed=applied[..., 0],
        density=applied[..., 1],
        damping=applied[..., 2],
        force=f,
        displacements=out.transpose(0, 2, 1)[:, :4],
        accelerations=out.transpose(0, 2, 1)[:, 4:],
        final_state=y,
    )


def ramp_airspeed(critical_airspeed: float, start: float = 0.8, stop: float = 1.2,
                  duration: float = 30.0, sample_rate: float = 1000.0) -> np.ndarray:
    """Linear airspeed ramp [m/s] from ``start`` to ``stop`` times ``critical_airspeed``.

    The seed's flight (sections 6.1.3, 6.2.4, 6.3.3, 7.1.2): 0.8 -> 1.2 U_cr in 30 s.
    Returns shape (round(duration * sample_rate),).
    """
    u_cr = positive(critical_airspeed, "critical_airspeed")
    n = int(round(positive(duration, "duration") * positive(sample_rate, "sample_rate")))
    return u_cr * (start + (stop - start) * np.arange(n) / n)


def divergence_airspeed(airspeed, response, sample_rate: float = 1000.0, window: float = 1.0,
                        factor: float = 10.0, baseline_fraction: float = 0.1):
    """Airspeed at which a ramp flight diverged (definition in the module docstring).

    Parameters
    ----------
    airspeed : array_like, shape (N,) or (F, N)
        [m/s]
    response : array_like, shape (N,) or (F, N)
        The leading-edge displacement [m] (any response works; the test is relative).
    sample_rate : float
        [Hz]
    window : float
        [s] RMS window.
    factor : float
        Threshold relative to the baseline RMS, > 1.
    baseline_fraction : float
        Leading fraction of the flight used for the baseline, in (0, 1).

    Returns
    -------
    float or ndarray (F,)
        [m/s], NaN where the flight did not diverge.
    """
    x = real_array(response, "response", allow_inf=True)
    x = np.where(np.isfinite(x), x, np.finfo(float).max ** 0.25)
    single = x.ndim == 1
    x = np.atleast_2d(x)
    speed = np.broadcast_to(real_array(airspeed, "airspeed"), x.shape)
    if positive(factor, "factor") <= 1:
        raise ValueError("factor must be > 1")
    if not 0 < baseline_fraction < 1:
        raise ValueError("baseline_fraction must be in (0, 1)")
    w = int(round(positive(window, "window") * positive(sample_rate, "sample_rate")))
    nw = x.shape[1] // w
    if w < 1 or nw < 3:
        raise ValueError("the flight must span at least three windows")
    rms = np.sqrt(np.mean(x[:, : nw * w].reshape(x.shape[0], nw, w) ** 2, axis=2))
    nb = max(1, int(baseline_fraction * nw))
    base = np.median(rms[:, :nb], axis=1)
    above = rms > factor * base[:, None]
    # "stays above": all windows from i onward are above.
    stays = np.flip(np.logical_and.accumulate(np.flip(above, axis=1), axis=1), axis=1)
    out = np.full(x.shape[0], np.nan)
    for i in range(x.shape[0]):
        idx = np.flatnonzero(stays[i])
        if idx.size:
            out[i] = speed[i, (idx[0] + 1) * w - 1]
    return float(out[0]) if single else out
