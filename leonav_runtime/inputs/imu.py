"""IMU table -> IMU records, and the averaged specific force the Doppler-rate model uses.

An IMU record at `t` carries the increments over `(t - dt, t]` (body FLU, rad and m/s);
the generated predict integrates them (docs/design.md, "IMU input").
"""
from __future__ import annotations

import numpy as np

from leonav_runtime import records
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
    dt = np.broadcast_to(np.asarray(dt_s, dtype=float), (dvel_b.shape[0],))
    dt_median = float(np.median(dt))
    n_avg = max(1, int(round(window_s / dt_median)))
    dv = np.vstack([np.zeros(3), np.cumsum(dvel_b, axis=0)])
    tt = np.concatenate([[0.0], np.cumsum(dt)])
    k_end = np.maximum(np.arange(dvel_b.shape[0] + 1), 1)
    k_start = np.maximum(k_end - n_avg, 0)
    return (dv[k_end] - dv[k_start]) / (tt[k_end] - tt[k_start])[:, None], n_avg * dt_median


def latest_sample(imu: ImuTable, t_s: np.ndarray) -> np.ndarray:
    """Sample index (0 = the start of the first interval, j + 1 = the end of interval j) of the
    latest IMU sample at or before each time `t_s` (s), 1 ns tolerance: the row of
    `averaged_specific_force`'s output to use at a measurement time."""
    return np.searchsorted(imu.t, np.asarray(t_s) + 1e-9)     # (interval index, -1 before the first) + 1
