"""Consistency statistics of the sweep's trials: NEES and NIS sums, computed with element-wise
array operations only, so a block of trials gives each trial bit for bit what it gives alone
(a batched LAPACK solve or a pairwise sum could round differently with the batch's shape)."""
from __future__ import annotations

import numpy as np


def nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """err' P^-1 err for each leading index: err (..., n), P (..., n, n) symmetric positive
    definite -> (...). An entry whose P is not positive definite falls back to a solve."""
    n = err.shape[-1]
    out = nees_batch_last(np.moveaxis(err.reshape(-1, n), 0, -1), np.moveaxis(P.reshape(-1, n, n), 0, -1).copy())
    return out.reshape(err.shape[:-1])


def nees_batch_last(e: np.ndarray, A: np.ndarray) -> np.ndarray:
    """`nees` with the batch last: e (n, batch), A (n, n, batch), its lower triangle overwritten by
    the Cholesky factor. A factor and a forward substitution over the batch at once, the same
    operations on every entry in the same order."""
    n = e.shape[0]
    y = np.empty_like(e)
    diag = A[np.arange(n), np.arange(n)].copy()     # the factor overwrites it (kept for the fallback)
    with np.errstate(invalid="ignore", divide="ignore"):
        for j in range(n):
            for k in range(j):          # column j of A becomes column j of the factor L
                A[j:, j] -= A[j:, k] * A[j, k]
            A[j, j] = np.sqrt(A[j, j])
            A[j + 1:, j] /= A[j, j]
            yj = e[j].copy()
            for k in range(j):
                yj -= A[j, k] * y[k]
            y[j] = yj / A[j, j]
        out = y[0] * y[0]
        for j in range(1, n):
            out += y[j] * y[j]
    bad = np.flatnonzero(~np.isfinite(out))
    if bad.size:    # P again from its diagonal and the strict upper triangle the factor left alone
        upper = np.triu(np.moveaxis(A[:, :, bad], -1, 0), 1)
        Pb = upper + np.swapaxes(upper, 1, 2) + np.einsum("ib,ij->bij", diag[:, bad], np.eye(n))
        eb = e[:, bad].T
        out[bad] = np.einsum("ni,ni->n", eb, np.linalg.solve(Pb, eb[:, :, None])[:, :, 0])
    return out


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
    return nis_sums_many(kinds, index, nis[None], status[None])[0]


def nis_sums_many(kinds: np.ndarray, index: np.ndarray, nis: np.ndarray, status: np.ndarray,
                  ) -> list[tuple[dict[int, float], dict[int, int]]]:
    """`nis_sums` of B trials whose streams share their kinds (`index` (n,)): nis, status (B, n).
    One bincount over (trial, kind) bins; each bin still sums its trial's records in record order,
    so every trial gets what it gets alone."""
    B, K = nis.shape[0], kinds.size
    used = (index >= 0) & (status >= 0) & (status <= 1)
    bins = (np.arange(B)[:, None] * K + index)[used]
    sums = np.bincount(bins, weights=nis[used], minlength=B * K).reshape(B, K)
    counts = np.bincount(bins, minlength=B * K).reshape(B, K)
    keys = [int(k) for k in kinds]
    return [(dict(zip(keys, s.tolist())), dict(zip(keys, c.tolist()))) for s, c in zip(sums, counts)]
