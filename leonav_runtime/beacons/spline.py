"""Not-a-knot cubic interpolation of the predicted curves, without importing SciPy's interpolation.

Why here and not `scipy.interpolate.CubicSpline`: `leonav beacons` interpolates its predicted
Doppler and rate curves (a 0.5 s grid) at the measurement epochs, and importing
`scipy.interpolate` (which imports `scipy.optimize`, `scipy.sparse` and `scipy.spatial` with it)
costs about 0.3 s of CPU on the 2-vCPU build machine, more than the work. The interpolant is the
same one, computed the same way, so the values are the same to the last bit (a test compares
them on random and predicted curves):

- slopes s_i at the knots from the tridiagonal system of C2 continuity with the not-a-knot
  ends (third derivative continuous across the second and the last-but-one knot), solved by
  Gaussian elimination with partial pivoting in LAPACK's `dgtsv` order (`_tridiagonal_solve`);
- per interval the cubic Hermite polynomial c0 s^3 + c1 s^2 + c2 s + c3 in s = t - t_i, summed
  term by term from the constant one up (as SciPy's piecewise-polynomial evaluation does);
- outside the grid the first or the last cubic is extended.
"""
from __future__ import annotations

import numpy as np


class NotAKnotSpline:
    """Cubic not-a-knot spline through (x_i, y_i) along axis 1 of `y` (rows are curves).

    x: (n,) strictly increasing, n >= 4; y: (m, n). Call with times t (any shape) to get
    (m,) + t.shape.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray) -> None:
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if x.ndim != 1 or x.size < 4 or y.ndim != 2 or y.shape[1] != x.size:
            raise ValueError(f"expected x (n >= 4,) and y (m, n); got {x.shape} and {y.shape}")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and np.all(np.diff(x) > 0)):
            raise ValueError("x must be finite and strictly increasing, y finite")
        self.x = x
        yk = np.ascontiguousarray(y.T)            # knots first, as the formulas below index them
        n = x.size
        dx = np.diff(x)
        dxr = dx.reshape(-1, 1)
        slope = np.diff(yk, axis=0) / dxr
        diag, upper, lower = np.zeros(n), np.zeros(n), np.zeros(n)   # upper[j] is A[j-1, j]; lower[j] is A[j+1, j]
        b = np.empty_like(yk)
        diag[1:-1] = 2 * (dx[:-1] + dx[1:])
        upper[2:] = dx[:-1]
        lower[:-2] = dx[1:]
        b[1:-1] = 3 * (dxr[1:] * slope[:-1] + dxr[:-1] * slope[1:])
        d = x[2] - x[0]                           # not-a-knot at the start
        diag[0], upper[1] = dx[1], d
        b[0] = ((dxr[0] + 2 * d) * dxr[1] * slope[0] + dxr[0] ** 2 * slope[1]) / d
        d = x[-1] - x[-3]                         # and at the end
        diag[-1], lower[-2] = dx[-2], d
        b[-1] = (dxr[-1] ** 2 * slope[-2] + (2 * d + dxr[-1]) * dxr[-2] * slope[-1]) / d
        s = _tridiagonal_solve(lower[:-1].tolist(), diag.tolist(), upper[1:].tolist(), b)
        t = (s[:-1] + s[1:] - 2 * slope) / dxr    # cubic Hermite coefficients per interval
        self.c = np.stack((t / dxr, (slope - s[:-1]) / dxr - t, s[:-1], yk[:-1]))

    def __call__(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        flat = t.reshape(-1)
        i = np.clip(np.searchsorted(self.x, flat, side="right") - 1, 0, self.x.size - 2)
        z1 = (flat - self.x[i])[:, None]
        z2 = z1 * z1
        z3 = z2 * z1
        c = self.c[:, i, :]
        out = 0.0 + c[3]
        out = out + c[2] * z1
        out = out + c[1] * z2
        out = out + c[0] * z3
        return out.T.reshape((self.c.shape[2],) + t.shape)


def _tridiagonal_solve(dl: list[float], d: list[float], du: list[float], b: np.ndarray) -> np.ndarray:
    """Solve A s = b for tridiagonal A (sub-, main and super-diagonal), b (n, m): Gaussian
    elimination with partial pivoting, operation for operation as LAPACK's dgtsv."""
    n = len(d)
    b = np.array(b, dtype=np.float64)
    for i in range(n - 1):
        if abs(d[i]) >= abs(dl[i]):               # no row interchange
            if d[i] == 0.0:
                raise np.linalg.LinAlgError("singular tridiagonal system")
            fact = dl[i] / d[i]
            d[i + 1] = d[i + 1] - fact * du[i]
            b[i + 1] = b[i + 1] - fact * b[i]
            if i < n - 2:
                dl[i] = 0.0
        else:                                     # interchange rows i and i + 1
            fact = d[i] / dl[i]
            d[i] = dl[i]
            temp = d[i + 1]
            d[i + 1] = du[i] - fact * temp
            if i < n - 2:
                dl[i] = du[i + 1]
                du[i + 1] = -fact * dl[i]
            du[i] = temp
            row = b[i].copy()
            b[i] = b[i + 1]
            b[i + 1] = row - fact * b[i + 1]
    if d[n - 1] == 0.0:
        raise np.linalg.LinAlgError("singular tridiagonal system")
    b[n - 1] = b[n - 1] / d[n - 1]
    b[n - 2] = (b[n - 2] - du[n - 2] * b[n - 1]) / d[n - 2]
    for i in range(n - 3, -1, -1):
        b[i] = (b[i] - du[i] * b[i + 1] - dl[i] * b[i + 2]) / d[i]
    return b
