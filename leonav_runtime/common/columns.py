"""Element-wise NumPy operations on (..., 3)-shaped arrays one last-axis column at a time.

Over a C-ordered (B, n, 3) array broadcast against a short vector (or written into a view with
a short last axis) NumPy runs its inner loop on 3 elements at a time; a column is a single
strided run of B x n elements instead, 2-4x faster on the sweep's blocks of trials (measured in
the sweep's draws). The values are the same: the same operation on the same elements.
"""
from __future__ import annotations

import numpy as np


def columnwise(ufunc: np.ufunc, a, b, out: np.ndarray) -> np.ndarray:
    """ufunc(a, b, out=out) column by column of out's last axis; a and b broadcast to out's shape.
    An operand that overlaps out without being out itself goes through the plain ufunc: column by
    column, a later column would read what an earlier one wrote."""
    shape = out.shape
    a, b = np.broadcast_to(a, shape), np.broadcast_to(b, shape)
    if any(np.may_share_memory(v, out) and not _same_view(v, out) for v in (a, b)):
        return ufunc(a, b, out=out)
    for c in range(shape[-1]):
        ufunc(a[..., c], b[..., c], out=out[..., c])
    return out


def _same_view(v: np.ndarray, out: np.ndarray) -> bool:
    """v reads exactly the elements out writes, in the same places (an in-place operation)."""
    return (v.__array_interface__["data"][0] == out.__array_interface__["data"][0] and v.strides == out.strides
            and v.shape == out.shape)
