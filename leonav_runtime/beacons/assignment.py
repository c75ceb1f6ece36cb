"""Minimum-cost rectangular assignment (the linear sum assignment problem), without SciPy.

Why here and not `scipy.optimize.linear_sum_assignment`: `leonav beacons` assigns a few tone
combs to the few dozen satellites above the mask, a problem of at most tens by hundreds,
solved in well under a millisecond; importing `scipy.optimize` for it costs about 0.4 s of CPU
on the 2-vCPU build machine, most of the command's fixed cost once the element file is cached
(docs/performance.md). The algorithm is the shortest augmenting path method with dual
variables (Jonker-Volgenant in the rectangular form of D. F. Crouse, "On implementing 2D
rectangular assignment algorithms", IEEE Trans. Aerospace and Electronic Systems 52(4), 2016),
which is also the method SciPy documents for `linear_sum_assignment`. Ties between equally
cheap columns are broken the same way (the first one found, unless a later one is still free),
so the two return the same assignment, not only the same total cost; tests compare them.
"""
from __future__ import annotations

import numpy as np


def linear_sum_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of a minimum-cost assignment of the 2-D `cost` matrix.

    Every row is assigned when there are no more rows than columns, else every column;
    `rows` is ascending, `cost[rows, cols].sum()` is the minimum. Costs are any finite
    numbers (+inf marks a forbidden pair). Raises ValueError for NaN or -inf entries, a
    non-2-D input, or when no complete assignment avoids the +inf entries.
    """
    c = np.asarray(cost, dtype=float)
    if c.ndim != 2:
        raise ValueError(f"expected a matrix, got an array of shape {c.shape}")
    if np.isnan(c).any() or np.isneginf(c).any():
        raise ValueError("cost matrix contains NaN or -inf")
    transpose = c.shape[1] < c.shape[0]
    if transpose:
        c = c.T
    nr, nc = c.shape
    if nr == 0:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    u, v = np.zeros(nr), np.zeros(nc)
    col4row = np.full(nr, -1, np.intp)
    row4col = np.full(nc, -1, np.intp)
    for cur in range(nr):
        sink, min_val, path, spc, rows_seen, cols_seen = _augmenting_path(c, u, v, row4col, cur)
        # dual update: rows and columns reached on the way keep reduced costs >= 0
        u[cur] += min_val
        for i in np.nonzero(rows_seen)[0]:
            if i != cur:
                u[i] += min_val - spc[col4row[i]]
        cols = np.nonzero(cols_seen)[0]
        v[cols] -= min_val - spc[cols]
        j = sink
        while True:   # flip the path back to the current row
            i = path[j]
            row4col[j] = i
            col4row[i], j = j, col4row[i]
            if i == cur:
                break
    if transpose:
        order = np.argsort(col4row, kind="stable")
        return col4row[order], order.astype(np.intp)
    return np.arange(nr, dtype=np.intp), col4row.copy()


def _augmenting_path(c: np.ndarray, u: np.ndarray, v: np.ndarray, row4col: np.ndarray, start: int):
    """Dijkstra over reduced costs from row `start` to the nearest free column:
    (sink column, path length, predecessor row of each column, distances, rows seen, columns seen)."""
    nr, nc = c.shape
    min_val = 0.0
    remaining = list(range(nc - 1, -1, -1))   # columns not yet settled, in the order they are scanned
    spc = np.full(nc, np.inf)
    path = np.full(nc, -1, np.intp)
    rows_seen = np.zeros(nr, bool)
    cols_seen = np.zeros(nc, bool)
    i = start
    while True:
        rows_seen[i] = True
        rem = np.asarray(remaining, np.intp)
        r = min_val + c[i, rem] - u[i] - v[rem]
        better = r < spc[rem]
        spc[rem[better]] = r[better]
        path[rem[better]] = i
        d = spc[rem]
        lowest = d.min()
        if lowest == np.inf:
            raise ValueError("cost matrix is infeasible: no complete assignment avoids the +inf entries")
        at_min = np.nonzero(d == lowest)[0]
        free = at_min[row4col[rem[at_min]] == -1]
        index = int(free[-1]) if free.size else int(at_min[0])   # the last free one, else the first
        min_val = float(lowest)
        j = remaining[index]
        cols_seen[j] = True
        remaining[index] = remaining[-1]   # remove by moving the last one in (keeps the scan order)
        remaining.pop()
        if row4col[j] == -1:
            return j, min_val, path, spc, rows_seen, cols_seen
        i = int(row4col[j])
