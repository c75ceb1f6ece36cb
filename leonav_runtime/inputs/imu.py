"""IMU table -> IMU records, and the averaged specific force the Doppler-rate model uses.

An IMU record at `t` carries the increments over `(t - dt, t]` (body FLU, rad and m/s);
the generated predict integrates them (docs/design.md, "IMU input").
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import records
from leonav_runtime.inputs.tables import ImuTable

F_B_AVERAGE_S = 0.1
"""s: the Doppler-rate model needs the receiver acceleration; the filter takes it from the
accelerometer averaged over this window (one sample's white noise, shared by every
satellite of an epoch, would otherwise be a correlated error the filter cannot see)."""


def imu_records(imu: ImuTable) -> np.ndarray:
    """One IMU record per interval of the table."""
    return records.imu_records(imu.t, imu.dtheta_b, imu.dvel_b, imu.dt)


def averaged_specific_force(dvel_b: np.ndarray, dt_s: np.ndarray | float,
                            window_s: float = F_B_AVERAGE_S) -> tuple[np.ndarray, float]:
    """Specific force (m/s^2, body) averaged over the last `window_s` at every IMU sample.

    dvel_b (n, 3): velocity increments of the n intervals (m/s); dt_s: their lengths (s).
    Returns (f_b (n+1, 3) at samples 0..n, sample 0 taking the first interval; the
    averaging span in s), the input of the Doppler-rate model's receiver acceleration and
    of its noise (generated `leonav_doppler_rate_variance`).
    """
    n = dvel_b.shape[0]
    dt = np.broadcast_to(np.asarray(dt_s, dtype=float), (n,))
    dt_median = float(np.median(dt))
    n_avg = max(1, int(round(window_s / dt_median)))
    dv = np.vstack([np.zeros(3), np.cumsum(dvel_b, axis=0)])    # velocity change from sample 0 to sample k
    tt = np.concatenate([[0.0], np.cumsum(dt)])
    # the window of sample k runs from sample max(max(k, 1) - n_avg, 0) to sample max(k, 1)
    m = min(n_avg, n) + 1

    def ends(a):
        return np.concatenate([a[1:2], a[1:]])

    def starts(a):
        return np.concatenate([np.broadcast_to(a[:1], (m,) + a.shape[1:]), a[1:max(n + 1 - n_avg, 1)]])

    return (ends(dv) - starts(dv)) / (ends(tt) - starts(tt))[:, None], n_avg * dt_median


def latest_sample(imu: ImuTable, t_s: np.ndarray) -> np.ndarray:
    """Sample index (0 = the start of the first interval, j + 1 = the end of interval j) of the
    latest IMU sample at or before each time `t_s` (s), 1 ns tolerance: the row of
    `averaged_specific_force`'s output to use at a measurement time."""
    return np.searchsorted(imu.t, np.asarray(t_s) + 1e-9)     # (interval index, -1 before the first) + 1
