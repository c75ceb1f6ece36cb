"""Error statistics and reference-side helpers shared by the scoring of datasets (`leonav run`) and of
recorded sessions (`leonav replay`): states at reference epochs, yaw, wrapping, RMSE with the rows
without an estimate left out, the error summary, GNSS alone (hold the last fix), CDFs."""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.inputs import FixTable

def states_at(res: lfilter.RunResult, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, x (n, NX), P_diag (n, NDX)) of the state after the last record at or before each t
    (rows -1 where t precedes the run: x, P NaN)."""
    rows = np.searchsorted(res.t, t, side="right") - 1
    ok = rows >= 0
    x = np.full((t.size, res.x.shape[1]), np.nan)
    pd = np.full((t.size, res.P_diag.shape[1]), np.nan)
    x[ok], pd[ok] = res.x[rows[ok]], res.P_diag[rows[ok]]
    return rows, x, pd


_NAV: list = []


def yaw_of(q: np.ndarray) -> np.ndarray:
    """Yaw (rad, from East towards North) of q_nb rows [w x y z], by the generated
    euler_from_quat (NaN rows stay NaN)."""
    from leonav_runtime.core.navfuncs import NavFunctions

    if not _NAV:
        _NAV.append(NavFunctions())
    q = np.atleast_2d(q)
    out = np.full(q.shape[0], np.nan)
    ok = np.all(np.isfinite(q), axis=1)
    if ok.any():
        out[ok] = _NAV[0].euler_from_quat(q[ok])[:, 2]
    return out


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles (rad) reduced to [-pi, pi): the one wrap of the dataset code."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def rms(e: np.ndarray) -> float | None:
    """Root mean square of the rows (of their squared norms for (n, k)); rows with a NaN are left out;
    None when none is left."""
    e = e[np.all(np.isfinite(e), axis=1)] if e.ndim == 2 else e[np.isfinite(e)]
    if e.size == 0:
        return None
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1) if e.ndim == 2 else e**2)))


def error_stats(err_enu: np.ndarray) -> dict:
    """Horizontal, vertical and 3-D RMSE (m), horizontal 50/68/95 % and max (m), epochs."""
    ok = np.all(np.isfinite(err_enu), axis=1)
    e = err_enu[ok]
    h = np.hypot(e[:, 0], e[:, 1])
    q = (lambda p: float(np.percentile(h, p)) if h.size else None)
    return {"rmse_horizontal_m": rms(e[:, :2]), "rmse_vertical_m": rms(e[:, 2:]), "rmse_3d_m": rms(e),
            "horizontal_p50_m": q(50), "horizontal_p68_m": q(68), "horizontal_p95_m": q(95),
            "horizontal_max_m": float(h.max()) if h.size else None, "epochs": int(ok.sum()),
            "epochs_without_estimate": int((~ok).sum())}


def hold_last_fix(fixes: FixTable, t: np.ndarray) -> np.ndarray:
    """(n, 3) the last fix at or before each t (NaN before the first)."""
    k = np.searchsorted(fixes.t, t, side="right") - 1
    out = np.full((t.size, 3), np.nan)
    out[k >= 0] = fixes.p_enu_m[k[k >= 0]]
    return out


def cdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sorted finite values, cumulative fraction) for a CDF plot."""
    v = np.sort(values[np.isfinite(values)])
    return v, np.arange(1, v.size + 1) / max(v.size, 1)
