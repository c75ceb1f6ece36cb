"""Standstills, IMU noise at rest, coarse alignment and the IMU-GNSS time offset.

- `standstill`: per IMU sample, at rest when over a centred window the accelerometer's
  per-axis standard deviation and the gyro's magnitude stay below thresholds.
- `initial_rest`: the first standstill from the start (up to a limit): gyro bias (mean
  rate), white noise (per-sample std * sqrt(dt): vrw m/s/sqrt(s), arw rad/sqrt(s)) and the
  specific force used for leveling (generated `leonav_level`).
- `gnss_velocity`: ENU velocity from fix positions differenced over a window (central,
  on a regular grid); its course is the heading of a vehicle driving forward.
- `calibrate_time_offset`: the IMU time offset that best lines up the gyro's yaw rate with
  the rate of the GNSS course (both smoothed over the same window): a grid search on the
  correlation (reported; used when `[imu] time_offset_s = "calibrate"`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from leonav_runtime.dataset.load import ImuSamples
from leonav_runtime.dataset.scoring import wrap
from leonav_runtime.inputs import FixTable


def _moving(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving mean over n samples (edges: shorter windows), column-wise."""
    x = np.asarray(x, float)
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)], axis=0)
    i = np.arange(x.shape[0])
    lo, hi = np.clip(i - n // 2, 0, x.shape[0]), np.clip(i - n // 2 + n, 0, x.shape[0])
    return (c[hi] - c[lo]) / (hi - lo).reshape((-1,) + (1,) * (x.ndim - 1))


def standstill(imu: ImuSamples, window_s: float, accel_std_mps2: float, gyro_radps: float) -> np.ndarray:
    """Boolean (n,): the vehicle is at rest around each IMU sample (module doc)."""
    dt = float(np.median(np.diff(imu.t)))
    n = max(3, int(round(window_s / dt)))
    f = imu.f_b_mps2
    var = _moving(f**2, n) - _moving(f, n) ** 2
    acc_std = np.sqrt(np.clip(var, 0, None)).max(axis=1)
    gyro = _moving(np.linalg.norm(imu.w_b_radps, axis=1), n)
    return (acc_std < accel_std_mps2) & (gyro < gyro_radps)


@dataclass
class Rest:
    """The initial standstill: samples [0, n), its length (s), mean gyro (bias, rad/s FLU), mean
    specific force (m/s^2 FLU), white noise vrw (m/s/sqrt(s)) and arw (rad/sqrt(s)) or None when
    there is no initial standstill."""

    n: int
    seconds: float
    gyro_mean: np.ndarray
    f_mean: np.ndarray
    vrw: float | None
    arw: float | None


def initial_rest(imu: ImuSamples, still: np.ndarray, max_s: float) -> Rest:
    """The standstill at the start of the IMU record (module doc)."""
    moving = np.flatnonzero(~still)
    n = int(moving[0]) if moving.size else still.size
    n = int(np.searchsorted(imu.t, imu.t[0] + max_s)) if n and imu.t[n - 1] - imu.t[0] > max_s else n
    if n < 20:
        return Rest(0, 0.0, np.zeros(3), imu.f_b_mps2[:50].mean(axis=0), None, None)
    dt = float(np.median(np.diff(imu.t[:n])))
    vrw = float(np.sqrt(np.mean(imu.f_b_mps2[:n].var(axis=0)) * dt))
    arw = float(np.sqrt(np.mean(imu.w_b_radps[:n].var(axis=0)) * dt))
    return Rest(n, float(imu.t[n - 1] - imu.t[0]), imu.w_b_radps[:n].mean(axis=0), imu.f_b_mps2[:n].mean(axis=0),
                vrw, arw)


def gnss_velocity(fixes: FixTable, window_s: float, rate_hz: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """(t (m,) s, v_enu (m, 3) m/s) on a regular grid over the fixes (module doc)."""
    t = np.arange(fixes.t[0] + window_s / 2, fixes.t[-1] - window_s / 2, 1.0 / rate_hz)
    if t.size == 0:
        return t, np.zeros((0, 3))
    p = fixes.p_enu_m
    ahead = np.column_stack([np.interp(t + window_s / 2, fixes.t, p[:, j]) for j in range(3)])
    behind = np.column_stack([np.interp(t - window_s / 2, fixes.t, p[:, j]) for j in range(3)])
    return t, (ahead - behind) / window_s


def moving_start(t_v: np.ndarray, v_enu: np.ndarray, speed_mps: float, hold_s: float) -> int | None:
    """Index of the first grid time from which the horizontal speed stays above `speed_mps`
    for `hold_s`, or None."""
    fast = np.hypot(v_enu[:, 0], v_enu[:, 1]) > speed_mps
    if t_v.size < 2:
        return None
    n = max(1, int(round(hold_s / (t_v[1] - t_v[0]))))
    run = np.convolve(fast.astype(int), np.ones(n, int), "valid")
    k = np.flatnonzero(run == n)
    return int(k[0]) if k.size else None


def heading_source_gnss(fixes: FixTable, window_s: float, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """(t s, course rad) of the GNSS velocity where the speed exceeds `speed_mps`."""
    t_v, v = gnss_velocity(fixes, window_s)
    ok = np.hypot(v[:, 0], v[:, 1]) > speed_mps
    return t_v[ok], np.arctan2(v[ok, 1], v[ok, 0])


def calibrate_time_offset(imu_t_s: np.ndarray, gyro_up_radps: np.ndarray, t_heading_s: np.ndarray,
                          heading_rad: np.ndarray, pair_s: float = 2.0, span_s: float = 2.0,
                          step_s: float = 0.01) -> dict:
    """Offset (s) to add to the IMU times `imu_t_s` (run axis, offset 0) so that the heading
    changes the gyro integrates (up rate, rad/s) over `pair_s` match those of a heading
    source (reference yaw, or the GNSS course) over the same span: grid search over
    [-span_s, span_s] on the mean wrapped difference, clipped at 0.5 rad against outliers.
    Returns offset_s, cost_rad (at the best offset) and cost_at_zero_rad, pairs used."""
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (gyro_up_radps[1:] + gyro_up_radps[:-1]) * np.diff(imu_t_s))])
    inside = (t_heading_s > imu_t_s[0] + span_s) & (t_heading_s + pair_s < imu_t_s[-1] - span_s)
    t_a, h_a = t_heading_s[inside], heading_rad[inside]
    b = np.searchsorted(t_a, t_a + pair_s)
    ok = b < t_a.size
    a, b = np.flatnonzero(ok), b[ok]
    if a.size < 20:
        return {"offset_s": None, "pairs": int(a.size), "reason": "too few heading pairs"}
    d_ref = wrap(h_a[b] - h_a[a])
    cost = {}
    for d in np.round(np.arange(-span_s, span_s + step_s / 2, step_s), 6):
        g = np.interp(t_a, imu_t_s + d, psi)
        cost[float(d)] = float(np.mean(np.minimum(np.abs(wrap(d_ref - (g[b] - g[a]))), 0.5)))
    best = min(cost, key=cost.get)
    return {"offset_s": best, "cost_rad": cost[best], "cost_at_zero_rad": cost.get(0.0), "pairs": int(a.size),
            "pair_s": pair_s, "search_s": [-span_s, span_s], "step_s": step_s}
