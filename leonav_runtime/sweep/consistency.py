"""Consistency statistics of the sweep's trials: NEES and NIS sums, computed with element-wise
array operations only, so a block of trials gives each trial bit for bit what it gives alone
(a batched LAPACK solve or a pairwise sum could round differently with the batch's shape)."""
from __future__ import annotations

import numpy as np


def nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """err' P^-1 err for each leading index: err (..., n), P (..., n, n) symmetric positive
    definite -> (...). A Cholesky factor and a forward substitution over the batch at once, in a
    fixed order of operations; an entry whose P is not positive definite falls back to a solve."""
    n = err.shape[-1]
    shape = err.shape[:-1]
    A = np.moveaxis(P.reshape(-1, n, n), 0, -1).copy()     # (n, n, batch): each entry contiguous
    e = np.moveaxis(err.reshape(-1, n), 0, -1)
    y = np.empty_like(e)
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(n):
            for k in range(j):          # column j of A becomes column j of the factor L
                for i in range(j, n):
                    A[i, j] -= A[i, k] * A[j, k]
            A[j, j] = np.sqrt(A[j, j])
            for i in range(j + 1, n):
                A[i, j] /= A[j, j]
            yj = e[j].copy()
            for k in range(j):
                yj -= A[j, k] * y[k]
            y[j] = yj / A[j, j]
        out = y[0] * y[0]
        for j in range(1, n):
            out += y[j] * y[j]
    bad = ~np.isfinite(out)
    if bad.any():
        eb, Pb = err.reshape(-1, n)[bad], P.reshape(-1, n, n)[bad]
        out[bad] = np.einsum("ni,ni->n", eb, np.linalg.solve(Pb, eb[:, :, None])[:, :, 0])
    return out.reshape(shape)


def kind_index(kind: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measurement kinds of a record stream (sorted ids) and each record's index among them
    (-1: an IMU record)."""
    kinds = np.unique(kind[kind >= 0])
    index = np.where(kind >= 0, np.searchsorted(kinds, kind), -1)
    return kinds, index


def nis_sums(kinds: np.ndarray, index: np.ndarray, nis: np.ndarray, status: np.ndarray,
             ) -> tuple[dict[int, float], dict[int, int]]:
    """Per measurement kind (`kind_index`): the sum of NIS over the applied and gated updates
    (status 0, 1), and their number, in record order."""
    used = (index >= 0) & (status >= 0) & (status <= 1)
    sums = np.bincount(index[used], weights=nis[used], minlength=kinds.size)
    counts = np.bincount(index[used], minlength=kinds.size)
    return ({int(k): float(v) for k, v in zip(kinds, sums)}, {int(k): int(c) for k, c in zip(kinds, counts)})
