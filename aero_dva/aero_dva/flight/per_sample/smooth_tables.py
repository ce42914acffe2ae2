"""The switched flight's per-sample maps at many (airspeed, c2 level) pairs, interpolated from
a few Chebyshev nodes (pure numerics).

A ramp holds about two hundred airspeeds and the lagged damper 65 c2 levels: thirteen thousand
zero-order-hold steps, each a matrix exponential. Every entry of a map is a smooth (entire)
function of the airspeed and of the Maxwell relaxation rate r = k2 / c2: the model matrix is
polynomial in U and affine in r, and a map is built from exp(A dt), its integral and the
measurement matrices by products and sums. So each entry is interpolated, exactly as a
polynomial of degree ``nodes - 1`` at Chebyshev nodes, in r over the table's range and in U over
the held airspeeds of each density: the error falls like (half-range * dt)^n / n!, below 1e-13
relative here with 10 nodes in r and 8 in U (a test checks it against the exact maps).

Held conditions of one density are interpolated in U when they number more than the U nodes;
otherwise, or when densities vary from period to period, each is built exactly.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["RATE_NODES", "SPEED_NODES", "chebyshev_nodes", "interpolated_maps",
           "lagrange_weights"]

RATE_NODES = 10
SPEED_NODES = 8


def chebyshev_nodes(lo: float, hi: float, count: int) -> np.ndarray:
    """``count`` Chebyshev points of the first kind on [lo, hi] (ascending)."""
    k = np.arange(count)
    x = -np.cos(math.pi * (2 * k + 1) / (2 * count))
    return 0.5 * (lo + hi) + 0.5 * (hi - lo) * x


def lagrange_weights(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(len(x), len(nodes)) weights of the interpolating polynomial through ``nodes``
    (barycentric form; exact at a node)."""
    nodes = np.asarray(nodes, dtype=float)
    x = np.asarray(x, dtype=float)
    diff = nodes[:, None] - nodes[None, :]
    np.fill_diagonal(diff, 1.0)
    bary = 1.0 / diff.prod(axis=1)
    d = x[:, None] - nodes[None, :]
    hit = d == 0.0
    d[hit] = 1.0
    w = bary / d
    w /= w.sum(axis=1, keepdims=True)
    rows = hit.any(axis=1)
    w[rows] = hit[rows].astype(float)
    return w


def interpolated_maps(build: Callable, conditions: np.ndarray, levels: np.ndarray,
                      series_stiffness: float):
    """``build(conditions, levels)`` for many conditions and levels, as base maps and
    per-condition weights.

    ``build(cond (k, 2), lev (l,))`` returns (k, l, S): one map per condition (airspeed,
    density) and c2 level. Returns ``(base (B, L, S), index (K, m), weight (K, m))`` for
    ``conditions`` (K, 2) and ``levels`` (L,): condition q's map at level l is
    ``sum_j weight[q, j] base[index[q, j], l]`` (the flight forms it only for the levels it
    flies), built at Chebyshev nodes where that is cheaper.
    """
    conditions = np.asarray(conditions, dtype=float)
    levels = np.asarray(levels, dtype=float)
    if levels.size > RATE_NODES:
        rates = series_stiffness / levels
        rate_nodes = chebyshev_nodes(rates.min(), rates.max(), RATE_NODES)
        level_nodes = series_stiffness / rate_nodes
        w_rate = lagrange_weights(rate_nodes, rates)
    else:
        level_nodes, w_rate = levels, None
    groups = []
    for rho in np.unique(conditions[:, 1]):
        rows = np.flatnonzero(conditions[:, 1] == rho)
        speeds = conditions[rows, 0]
        if np.unique(speeds).size > SPEED_NODES:
            nodes = chebyshev_nodes(speeds.min(), speeds.max(), SPEED_NODES)
            groups.append((rows, np.column_stack([nodes, np.full(nodes.size, rho)]),
                           lagrange_weights(nodes, speeds)))
        else:
            groups.append((rows, conditions[rows], np.ones((rows.size, 1))))
    width = max(w.shape[1] for _, _, w in groups)
    index = np.zeros((conditions.shape[0], width), dtype=np.int64)
    weight = np.zeros((conditions.shape[0], width))
    built, base = [], 0
    for rows, at, w in groups:
        if w.shape[1] == 1:  # each condition built exactly
            index[rows, 0] = base + np.arange(rows.size)
        else:
            index[rows, :w.shape[1]] = base + np.arange(w.shape[1])
        weight[rows, :w.shape[1]] = w
        built.append(build(at, level_nodes))
        base += at.shape[0]
    maps = built[0] if len(built) == 1 else np.concatenate(built)
    if w_rate is not None:  # (B, l_nodes, S) -> (B, L, S)
        maps = np.einsum("lj,bjs->bls", w_rate, maps)
    return np.ascontiguousarray(maps), index, weight
