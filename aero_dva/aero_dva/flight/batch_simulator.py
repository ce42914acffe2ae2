"""Many whole flights of the wing at once: the batch simulator.

:func:`simulate_flights` runs a batch of flights vectorised across flights and across hold
periods (only a short loop over hold periods stays sequential), on the sampled wing of
:class:`~aero_dva.flight.discrete_model.DiscreteWing` with its parameter hold. When all flights
share one schedule, the held conditions of the whole flight are found first and discretised in
one vectorised call (:meth:`BatchStepper.prefetch`) and kept between calls for the same model
(repeated flights of a schedule skip the matrix exponentials). Such flights are then stepped
sample by sample in a compiled loop (:mod:`~aero_dva.flight.held_kernel`, which also
discretises them). Flights with schedules of their own carry the states at the period
boundaries across periods (a two-level carry) and form the outputs by one period map per
period. :class:`BatchStepper` also serves the streaming simulator's long calls, without the
compiled loop (a node process does not import numba in mid-flight): fewer than
:data:`BATCH_COLUMNS` flights there carry their period starts by one banded solve
(:mod:`~aero_dva.flight.period_carry`), more by the two-level carry and the period maps.
:func:`reference_simulate_flights` is the previous route, kept as a baseline. Pure numerics.
"""

from __future__ import annotations

import threading

import numpy as np

from aero_dva.flight.discrete_model import (
    DEFAULT_HOLD,
    N_DISPLACEMENTS,
    N_OUTPUTS,
    DiscreteWing,
    held_values,
)
from aero_dva.flight.kept import KeptByKey
from aero_dva.flight.period_carry import period_starts
from aero_dva.flight.samples import FlightSamples
from aero_dva.wing.checks import real_array
from aero_dva.wing.model import AeroelasticModel

__all__ = ["BATCH_COLUMNS", "BatchStepper", "forget_conditions",
           "reference_simulate_flights", "simulate_flights"]

_KEY = np.dtype((np.void, 3 * 8))
"""A condition [U, rho, damping] as one sortable item (its three floats' bytes)."""


class _DiscreteCache:
    """Per-condition discrete matrices, computed in batches and kept by exact key.

    Three levels, each computed only when first needed: ``basic`` (one-sample ZOH ``phi``,
    ``gam`` and the acceleration output, from :meth:`DiscreteWing.discretise`), ``carry``
    (``phi^h`` and the forced state at the end of a hold period) and ``period`` (all outputs of
    a hold period as one matrix, rows in sample-major order ``j * p + o`` so that a period's
    outputs land contiguously in an (N, p) buffer).
    """

    LEVELS = {"basic": ("phi", "gam", "cacc", "dacc"), "carry": ("phih", "ctrb"),
              "period": ("period",)}
    RANK = {"basic": 0, "carry": 1, "period": 2}

    def __init__(self, wing: DiscreteWing, max_size: int = 4096, compiled: bool = False,
                 stacked: bool = True):
        self.wing, self.model, self.hold, self.max_size = wing, wing.model, wing.hold, max_size
        self.compiled = compiled  # matrix exponentials by the compiled loop (held_kernel)
        self.stacked = stacked  # the compiled loop's stacked maps where the model fits them
        self.clear()

    def clear(self):
        n, h = self.model.n_states, self.hold
        self.keys = np.empty(0, dtype=_KEY)  # the kept conditions' bytes, sorted
        self.slots = np.empty(0, dtype=np.intp)  # their rows in the arrays below
        self.size = 0
        na = N_OUTPUTS - N_DISPLACEMENTS
        self.shapes = {"phi": (n, n), "gam": (n,), "cacc": (na, n), "dacc": (na,),
                       "phih": (n, n), "ctrb": (n, h), "period": (N_OUTPUTS * h, n + h)}
        if self.compiled:
            from aero_dva.flight.held_kernel import STACK_ROWS, STACK_STATES

            if n <= STACK_STATES and self.stacked:  # the maps of held_kernel.step_stacked
                self.shapes["stack"] = (STACK_STATES + 1, STACK_ROWS)
        # a level's arrays are made when first needed (the compiled loop needs "basic" only)
        self.arr = {name: np.zeros((16,) + shape) for name, shape in self.shapes.items()
                    if name not in self.LEVELS["carry"] + self.LEVELS["period"]}
        self.done = {level: np.zeros(16, dtype=bool) for level in self.LEVELS}
        self._last = None  # (params, level, indices) of the last lookup

    def lookup(self, params: np.ndarray, level: str = "basic") -> np.ndarray:
        """Indices (K,) of the rows of ``params`` (K, 3) = [U, rho, damping], computed to
        ``level`` ("basic", "carry" or "period"; each includes the previous)."""
        params = np.asarray(params, dtype=float).reshape(-1, 3)
        last = self._last  # a repeated flight asks for the same schedule again
        if (last is not None and last[1] >= self.RANK[level] and last[0].shape == params.shape
                and np.array_equal(last[0], params)):
            return last[2]
        idx = self._lookup(params, level)
        if len(params) > 1:  # a schedule, not the single condition of a partial period
            idx.flags.writeable = False  # handed out again on a repeat
            self._last = (params.copy(), self.RANK[level], idx)
        return idx

    def _lookup(self, params, level):
        # Held parameters come in runs: deduplicate the runs first (cheap), then find the
        # runs' conditions among the kept ones by their bytes (a sorted array searched in
        # one call: a dict of float tuples costs ~0.3 us a run in Python). Equal bytes are
        # equal floats; 0.0 and -0.0 would only take two slots for the same matrices.
        differs = params[1:] != params[:-1]
        new_run = np.ones(len(params), dtype=bool)
        new_run[1:] = differs[:, 0] | differs[:, 1] | differs[:, 2]
        starts = np.flatnonzero(new_run)
        runs = np.ascontiguousarray(params[starts]).view(_KEY).ravel()
        pos = np.searchsorted(self.keys, runs)
        found = np.zeros(len(runs), dtype=bool)
        if self.size:
            found = self.keys[np.minimum(pos, self.size - 1)] == runs
        if not found.all():
            missing = np.unique(runs[~found])
            self._add_basic(missing.view(float).reshape(-1, 3))
            keys = np.concatenate([self.keys, missing])
            order = np.argsort(keys, kind="stable")
            self.keys = keys[order]
            self.slots = np.concatenate([self.slots, np.arange(self.size - len(missing),
                                                                self.size)])[order]
            pos = np.searchsorted(self.keys, runs)
        idx = self.slots[pos]
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
        # The parameters were checked where they entered (DiscreteWing.checked_inputs).
        expm = None
        if self.compiled:
            from aero_dva.flight.held_kernel import compiled_expm as expm  # numba: on first use
        m = self.wing.discretise(p, expm)
        phi, gam = m.ad, m.bd
        cacc, dacc = m.c[:, N_DISPLACEMENTS:], m.d[:, N_DISPLACEMENTS:]
        k0, k1 = self.size, self.size + len(p)
        self._grow(k1)
        for name, value in (("phi", phi), ("gam", gam), ("cacc", cacc), ("dacc", dacc)):
            self.arr[name][k0:k1] = value
        if "stack" in self.arr:
            from aero_dva.flight.held_kernel import stack_maps

            self.arr["stack"][k0:k1] = stack_maps(phi, gam, cacc, dacc,
                                                  self.model.c_displacement)
        self.done["basic"][k0:k1] = True
        self.size = k1

    def _made(self, level):
        """Make the arrays of ``level`` if they do not exist yet."""
        cap = len(self.done["basic"])
        for name in self.LEVELS[level]:
            if name not in self.arr:
                self.arr[name] = np.zeros((cap,) + self.shapes[name])

    def _add_carry(self, idx):
        self._made("carry")
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
        self._made("period")
        h, model = self.hold, self.model
        phi, gam = self.arr["phi"][idx], self.arr["gam"][idx]
        cacc, dacc = self.arr["cacc"][idx], self.arr["dacc"][idx]
        k, n = gam.shape
        # Outputs over one hold period as one linear map of (start state, forces):
        # output o at sample j = obs[j, o] x0 + sum_i toep[j, o, i] u_i.
        period = np.zeros((k, h, N_OUTPUTS, n + h))
        obs = period[..., :n]
        rows = np.concatenate([np.broadcast_to(model.c_displacement, (k, N_DISPLACEMENTS, n)),
                               cacc], axis=1)
        for j in range(h):  # C phi^j, by products from the left
            obs[:, j] = rows
            if j < h - 1:
                rows = rows @ phi
        markov = (obs @ gam[:, None, :, None])[..., 0]  # (k, h, p): C phi^j gamma
        toep = period[..., n:]
        for j in range(1, h):
            toep[:, j, :, :j] = markov[:, j - 1::-1].transpose(0, 2, 1)
        toep[:, np.arange(h), N_DISPLACEMENTS:, np.arange(h)] = dacc[None]
        self.arr["period"][idx] = period.reshape(k, N_OUTPUTS * h, n + h)
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

    Writes outputs into ``out`` (F, L, p); returns the final state (F, n).
    """
    arr = cache.arr
    phi, gam = arr["phi"][keys], arr["gam"][keys]
    cacc, dacc = arr["cacc"][keys], arr["dacc"][keys]
    c_disp = cache.model.c_displacement
    nd = N_DISPLACEMENTS
    for j in range(u.shape[1]):
        out[:, j, :nd] = y @ c_disp.T
        out[:, j, nd:] = np.einsum("fon,fn->fo", cacc, y) + dacc * u[:, j, None]
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
    ``out[f, b] = period[keys[b]] @ x[f, b]`` into ``out`` (F, B, p h), a period's outputs in
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
"""Without the compiled loop (the streaming simulator's long calls, the reference route): from
this many flights sharing one schedule on, the period starts come from the two-level carry
(:func:`_carry`, its products serve all flights at once) and the outputs from
:func:`_period_outputs`; fewer flights take one banded solve per flight (:func:`_run_few`)."""


def _run_outputs(period, keys, x, out):
    """Outputs of every hold period, one matrix product per run of periods with one key.

    As :func:`_period_outputs` (``out[f, b] = period[keys[b]] @ x[f, b]``), for keys that
    come in runs (a held condition lasts several periods): each run's outputs are written in
    place, and no period map is gathered.
    """
    cuts = np.flatnonzero(keys[1:] != keys[:-1]) + 1
    bounds = [0, *cuts.tolist(), len(keys)]
    for a, b, key in zip(bounds[:-1], bounds[1:], keys[bounds[:-1]].tolist()):
        np.matmul(x[:, a:b], period[key].T, out=out[:, a:b])


def _run_few(cache, y, k, u, out):
    """Full hold periods of fewer than :data:`BATCH_COLUMNS` flights sharing the cached
    conditions ``k`` (B,): y (F, n), u (F, B, h), outputs into ``out`` (F, B, h, p); returns
    the final state.

    The forced response at the end of each period from rest for all periods at once, the
    period starts by one banded solve, then the outputs run by run.
    """
    f, nb, h = u.shape
    arr = cache.arr
    g = np.einsum("bnj,fbj->bnf", arr["ctrb"][k], u)
    starts = period_starts(arr["phih"][k], g, y.T)  # (B + 1, n, F)
    x = np.concatenate([starts[:-1].transpose(2, 0, 1), u], axis=2)
    _run_outputs(arr["period"], k, x, out.reshape(f, nb, -1))
    return starts[-1].T


def _run_compiled(cache, y, k, u, out):
    """Full hold periods of flights sharing the cached conditions ``k`` (B,), by the
    compiled sample loop (:mod:`~aero_dva.flight.held_kernel`):
    y (F, n), u (F, B, h), outputs into ``out`` (F, B, h, p); returns the final state."""
    from aero_dva.flight.held_kernel import step_periods, step_stacked  # numba: on first use

    f, nb, h = u.shape
    arr = cache.arr
    flat = out.reshape(f, nb * h, N_OUTPUTS)
    dest = flat if flat.flags.c_contiguous else np.empty(flat.shape)  # one compiled layout
    k = np.ascontiguousarray(k, dtype=np.intp)
    force = np.ascontiguousarray(u.reshape(f, nb * h))
    if "stack" in arr:  # a model of at most held_kernel.STACK_STATES states
        n = y.shape[1]
        start = np.zeros((f, arr["stack"].shape[1] - 1))
        start[:, :n] = y
        end = step_stacked(arr["stack"], k, h, start, force, dest)[:, :n]
    else:
        end = step_periods(arr["phi"], arr["gam"], arr["cacc"], arr["dacc"],
                           np.ascontiguousarray(cache.model.c_displacement), k, h,
                           np.ascontiguousarray(y), force, dest)
    if dest is not flat:
        flat[...] = dest
    return end


def _run_full(cache, y, rows, u, out, reference=False, compiled=False):
    """Full hold periods: y (F, n), parameter rows (F, B, 3), u (F, B, h).

    Writes displacements and accelerations into ``out`` (F, B, h, p); returns the final
    state. The forced response at the end of each period from rest is computed for all periods
    at once, then the states at the period boundaries, then the outputs of all periods at once.
    Flights that share one parameter schedule share the matrices and take
    :func:`_run_compiled` if ``compiled``; else fewer than :data:`BATCH_COLUMNS` of them take
    :func:`_run_few`, unless ``reference`` (the previous route: :func:`_carry`, then stepping
    the periods' samples in parallel).
    """
    f, nb, h = u.shape
    arr = cache.arr
    shared = f == 1 or bool(np.all(rows == rows[:1]))
    if shared and compiled:
        return _run_compiled(cache, y, cache.lookup(rows[0]), u, out)
    if shared and f < BATCH_COLUMNS and not reference:
        return _run_few(cache, y, cache.lookup(rows[0], "period"), u, out)
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
        outs = out.transpose(1, 2, 0, 3)  # (B, h, F, p) view of out
        nd, na = N_DISPLACEMENTS, N_OUTPUTS - N_DISPLACEMENTS
        outs[..., :nd] = _tall_product(rows_t.reshape(-1, n),
                                       cache.model.c_displacement.T).reshape(nb, h, f, nd)
        acc = rows_t.reshape(nb, h * f, n) @ arr["cacc"][k].transpose(0, 2, 1)
        outs[..., nd:] = acc.reshape(nb, h, f, na) + arr["dacc"][k][:, None, None, :] * ut
        return starts[-1].T
    keys = cache.lookup(rows.reshape(-1, 3), "period").reshape(f, nb)
    g = np.einsum("fbnj,fbj->fbn", arr["ctrb"][keys], u)[..., None]
    starts = _carry(arr["phih"][keys], g, y[..., None])[..., 0]  # (F, B + 1, n)
    x = np.concatenate([starts[:, :-1], u], axis=2)
    np.einsum("fbi,fboi->fbo", x, arr["period"][keys], out=out.reshape(f, nb, -1))
    return starts[:, -1]


class BatchStepper:
    """Steps many flights of one :class:`DiscreteWing` (F, N) at once, in calls of any length:
    the batch simulator's machinery, also taken by the streaming simulator's long calls."""

    def __init__(self, wing: DiscreteWing, cache: _DiscreteCache | None = None,
                 reference: bool = False, compiled: bool = False):
        self.wing = wing
        self.hold, self.quantum = wing.hold, wing.quantum
        self.reference = reference
        # The compiled sample loop for few flights on one schedule; off for the streaming
        # simulator, whose process should not wait for numba's import in mid-flight.
        self.compiled = compiled and not reference
        self.cache = _DiscreteCache(wing, compiled=self.compiled) if cache is None else cache

    def prefetch(self, u, rho, c, level):
        """Held conditions of a whole flight from sample 0, discretised in one batch.

        ``u``, ``rho``, ``c`` (N,) are the flight's checked inputs. Returns the held rows
        (1, P, 3) of its hold periods, the rule of :meth:`run`, to pass on to :meth:`run`:
        its lookups then find everything cached (one vectorised matrix exponential for the
        whole flight instead of one per chunk).
        """
        raw = np.stack([u[::self.hold], rho[::self.hold], c[::self.hold]], axis=-1)[None]
        if self.compiled:
            from aero_dva.flight.held_kernel import hold_rule

            rows = hold_rule(raw[0], np.full(3, np.nan), self.quantum, np.empty_like(raw[0]))
            rows = rows[None]
        else:
            rows = held_values(raw, np.full((1, 3), np.nan), self.quantum)
        if rows.shape[1] <= self.cache.max_size:
            runs = 1 + int(np.count_nonzero(np.any(rows[0, 1:] != rows[0, :-1], axis=1)))
            if self.cache.size + runs > self.cache.max_size:
                self.cache.clear()  # conditions kept from earlier calls make room
            self.cache.lookup(rows[0], level)
        return rows

    def run(self, y, start, force, u, rho, c, held, out, applied, shared=False, rows=None):
        """Simulate samples ``start .. start + L - 1``; y (F, n), inputs (F, L).

        ``held`` (F, 3) are the parameters in force before ``start`` (NaN: none). Writes the
        outputs into ``out`` (F, L, p) (displacements then accelerations) and the applied
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
            rows = held_values(raw, held[: raw.shape[0]], self.quantum)  # (F', P, 3)
        nf = applied.shape[0]
        if first:
            y = self._partial(y, held, force, out, applied, 0, first)
        n_full = (total - first) // h
        if n_full and total >= 4 * h:
            sl = slice(first, first + n_full * h)
            pb = np.broadcast_to(rows[:, :n_full], (f, n_full, 3))
            fb = force[:, sl].reshape(f, n_full, h)
            y = _run_full(self.cache, y, pb, fb, out[:, sl].reshape(f, n_full, h, N_OUTPUTS),
                          self.reference, self.compiled)
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


_SHARED_MODELS = 2
"""Models whose discretised conditions :func:`simulate_flights` keeps between calls."""
_SHARED_CONDITIONS = 2048
"""A model's kept conditions (~13 kB each) are dropped after a call that left more."""
_shared = KeptByKey(_SHARED_MODELS)


def _shared_wing(wing, absorber, aero, sample_rate, hold, quantum):
    """The sampled wing of these arguments with its discretised conditions kept between
    calls, and the lock of those: (DiscreteWing, _DiscreteCache, Lock).

    Flights of one wing repeat their conditions (the seeds of an evaluation case, the repeats
    of a benchmark); a condition's matrices depend only on the model, the sample rate, the hold
    and the condition itself, which is the key here and in the cache. The model and the
    sampled wing are kept too: building and checking them costs as much as a short flight.
    """
    real = (int, float, np.integer, np.floating)
    plain = (isinstance(sample_rate, real) and isinstance(quantum, real)
             and isinstance(hold, (int, np.integer))
             and not any(isinstance(v, (bool, np.bool_)) for v in (sample_rate, hold, quantum)))
    key = (wing, absorber, aero, float(sample_rate), int(hold), float(quantum)) if plain \
        else None  # other types: built (and refused, if they are wrong) below, not kept
    try:
        entry = _shared.get(key) if plain else None
        if entry is not None:
            return entry
    except TypeError:  # unhashable: not kept, and refused by name below
        plain = False
    model = AeroelasticModel(wing, absorber, aero)
    dw = DiscreteWing(model, sample_rate, hold=hold, quantum=quantum)
    entry = (dw, _DiscreteCache(dw, compiled=True), threading.Lock())
    return _shared.keep(key, entry) if plain else entry


def forget_conditions() -> None:
    """Drop the discretised conditions :func:`simulate_flights` keeps between calls."""
    _shared.clear()


def simulate_flights(wing, absorber=None, *, force, airspeed, density, damping=None,
                     sample_rate: float = 1000.0, aero=None, x0=None,
                     hold: int = DEFAULT_HOLD, quantum: float = 2e-3,
                     chunk: int | None = None) -> FlightSamples:
    """Simulate a batch of whole flights at once.

    Parameters
    ----------
    wing, absorber, aero
        As for :class:`~aero_dva.flight.streaming_simulator.StreamingSimulator`.
    force : array_like, shape (F, N) or (N,)
        Aileron force [N] per flight and sample.
    airspeed, density, damping : array_like
        Broadcastable to (F, N): [m/s], [kg/m^3], [N s/m] (``None``: the absorber's value).
    sample_rate : float
        [Hz]
    x0 : array_like, shape (n_states,) or (F, n_states), optional
    hold, quantum : the parameter hold (:mod:`aero_dva.flight.discrete_model`). ``quantum``
        (default 2e-3) lets a held value lag its input by up to 0.2 % (0.2 m/s at 100 m/s) in
        exchange for speed.
    chunk : int, optional
        Hold periods processed together (bounds memory; default about 65536 / F).

    Returns
    -------
    FlightSamples
        The ``F`` flights (a leading axis of flights): airspeed, density and damping as applied
        (held), the force, the displacements and accelerations (views of one sample-major
        (F, N, p) buffer, each hold period's outputs computed as one contiguous block: use
        ``np.ascontiguousarray`` where a channel-major copy is needed), the final ``state``.

    The discretised conditions are kept between calls for the same model (a few models),
    so repeated flights of one schedule skip the matrix exponentials.
    """
    return _simulate(wing, absorber, aero, force, airspeed, density, damping, sample_rate,
                     x0, hold, quantum, chunk, reference=False)


def reference_simulate_flights(wing, absorber=None, *, force, airspeed, density,
                               damping=None, sample_rate: float = 1000.0, aero=None, x0=None,
                               hold: int = DEFAULT_HOLD, quantum: float = 2e-3,
                               chunk: int | None = None) -> FlightSamples:
    """:func:`simulate_flights` by the previous route: a fresh cache per call, the period
    starts by the two-level carry and the outputs by gathered period maps or by stepping.
    Kept as the baseline of ``bench/bench_wing_sim.py`` and of the equality tests."""
    return _simulate(wing, absorber, aero, force, airspeed, density, damping, sample_rate,
                     x0, hold, quantum, chunk, reference=True)


def _simulate(wing, absorber, aero, force, airspeed, density, damping, sample_rate, x0, hold,
              quantum, chunk, reference):
    if reference:
        dw = DiscreteWing(AeroelasticModel(wing, absorber, aero), sample_rate, hold=hold,
                          quantum=quantum)
        return _simulate_with(BatchStepper(dw, reference=True), force, airspeed, density,
                              damping, x0, chunk)
    dw, cache, lock = _shared_wing(wing, absorber, aero, sample_rate, hold, quantum)
    if not lock.acquire(blocking=False):  # in use by another thread: a private cache
        return _simulate_with(BatchStepper(dw, compiled=True), force, airspeed, density,
                              damping, x0, chunk)
    try:
        return _simulate_with(BatchStepper(dw, cache, compiled=True), force, airspeed, density,
                              damping, x0, chunk)
    finally:
        if cache.size > _SHARED_CONDITIONS:
            cache.clear()
        lock.release()


def _simulate_with(eng, force, airspeed, density, damping, x0, chunk) -> FlightSamples:
    dw, model = eng.wing, eng.wing.model
    f = real_array(force, "force")
    if f.ndim == 1:
        f = f[None, :]
    if f.ndim != 2:
        raise ValueError(f"force must have shape (F, N) or (N,), got {f.shape}")
    nf, total = f.shape
    u, rho, c = dw.checked_inputs(airspeed, density, damping, (nf, total))
    n = model.n_states
    y = np.zeros((nf, n)) if x0 is None else np.broadcast_to(real_array(x0, "x0"), (nf, n))
    y = np.array(y, dtype=float)
    dw.check_sampling(u[0, 0], rho[0, 0], c[0, 0])
    shared = all(np.ndim(v) <= 1 for v in (airspeed, density, damping))
    rows = None
    if shared and total >= 4 * eng.hold:
        maps = nf >= BATCH_COLUMNS or not eng.reference
        level = ("basic" if eng.compiled
                 else "period" if maps else "carry")
        rows = eng.prefetch(u[0], rho[0], c[0], level)
    # sample-major: each hold period's outputs are contiguous
    out = np.empty((nf, total, N_OUTPUTS))
    applied = np.empty((1 if shared else nf, total, 3))
    held = np.full((nf, 3), np.nan)
    periods = int(np.clip(65536 // nf, 32, 4096)) if chunk is None else max(1, int(chunk))
    if not shared:  # per-flight matrices are gathered: bound that memory (~32 MB)
        periods = max(8, min(periods, int(4e6 // (nf * N_OUTPUTS * eng.hold
                                                     * (n + eng.hold)))))
    step = periods * eng.hold
    for s in range(0, total, step):
        sl = slice(s, min(s + step, total))
        part = None if rows is None else rows[:, s // eng.hold:-(-sl.stop // eng.hold)]
        y, held = eng.run(y, s, f[:, sl], u[:, sl], rho[:, sl], c[:, sl], held, out[:, sl],
                          applied[:, sl], shared, part)
    applied = np.broadcast_to(applied, (nf, total, 3))
    return FlightSamples(
        first_index=0,
        sample_rate=dw.sample_rate,
        airspeed=applied[..., 0],
        density=applied[..., 1],
        damping=applied[..., 2],
        force=f,
        displacements=out.transpose(0, 2, 1)[:, :N_DISPLACEMENTS],
        accelerations=out.transpose(0, 2, 1)[:, N_DISPLACEMENTS:],
        state=y,
    )

