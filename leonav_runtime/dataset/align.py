"""Standstills, IMU noise at rest, coarse alignment and the IMU-GNSS time offset.

- `standstill`: per IMU sample, at rest when over a centred window the accelerometer's
  per-axis standard deviation and the gyro's magnitude stay below thresholds.
- `initial_rest`: the first standstill from the start (up to a limit): gyro bias (mean
  rate), white noise (per-sample std * sqrt(dt): vrw m/s/sqrt(s), arw rad/sqrt(s)) and the
  specific force used for leveling (generated `leonav_level`).
- `gnss_velocity`: ENU velocity from fix positions differenced over a window (central,
  on a regular grid); its course is the heading of a vehicle driving forward.
- `level_in_motion`: roll and pitch when the data starts moving: the specific force less the
  GNSS acceleration (rotated into the body by the course heading) is the reaction to gravity,
  so the climb (pitch) and the centripetal acceleration of a turn (roll) do not tilt the level.
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


def veto_moving(still: np.ndarray, imu_t_s: np.ndarray, fixes: FixTable, window_s: float,
                speed_mps: float) -> tuple[np.ndarray, float]:
    """(still, seconds vetoed): IMU samples flagged at rest are not where the GNSS speed (fixes
    differenced over `window_s`) exceeds `speed_mps`; more than 2 window_s outside the fixes'
    velocity grid the IMU decides."""
    t_v, v = gnss_velocity(fixes, window_s)
    if t_v.size < 2:
        return still, 0.0
    speed = np.hypot(np.interp(imu_t_s, t_v, v[:, 0]), np.interp(imu_t_s, t_v, v[:, 1]))
    # the grid starts half a window after the first fix: its first speed holds back to the fix
    # and a little before it (an IMU that starts before the receiver's first fix)
    inside = (imu_t_s >= t_v[0] - 2 * window_s) & (imu_t_s <= t_v[-1] + 2 * window_s)
    moving = inside & (speed > speed_mps)
    veto = still & moving
    dt = np.diff(imu_t_s, prepend=imu_t_s[0])
    return still & ~moving, float(dt[veto].sum())


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


def _rot_b_to_n(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """C_b_n (body FLU -> ENU) of Z-Y-X Euler angles, yaw from East towards North."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def along_track_accel(fixes: FixTable, t_s: float, yaw_rad: float, window_s: float) -> tuple[float, float]:
    """(a m/s^2, its 1-sigma) along the heading at t_s: the second derivative of a quadratic
    least-squares fit to the fixes' horizontal positions within window_s of t_s (the fix sigmas
    weigh it). Fix noise makes a differenced velocity's derivative useless; the fit averages it."""
    sel = np.abs(fixes.t - t_s) <= window_s / 2
    if sel.sum() < 5:
        return 0.0, math.inf
    dt = fixes.t[sel] - t_s
    along = fixes.p_enu_m[sel, 0] * math.cos(yaw_rad) + fixes.p_enu_m[sel, 1] * math.sin(yaw_rad)
    sigma = np.hypot(fixes.sigma_enu_m[sel, 0], fixes.sigma_enu_m[sel, 1]) / math.sqrt(2)
    A = np.column_stack([np.ones_like(dt), dt, 0.5 * dt**2]) / sigma[:, None]
    coef, *_ = np.linalg.lstsq(A, along / sigma, rcond=None)
    cov = np.linalg.inv(A.T @ A)
    return float(coef[2]), float(math.sqrt(cov[2, 2]))


def level_in_motion(imu: ImuSamples, fixes: FixTable, t_v: np.ndarray, v_enu: np.ndarray, t_s: float,
                    yaw_rad: float, window_s: float, nav, iterations: int = 4) -> tuple[float, float, dict]:
    """(roll, pitch (rad), report) at t_s of a moving vehicle (module doc).

    f_b: the mean specific force (m/s^2, body FLU) over `window_s` centred on t_s. The vehicle's
    acceleration: centripetal from the gyro's mean up rate times the GNSS horizontal velocity
    (a turn), along the heading from `along_track_accel` over 3 window_s, kept only where it
    exceeds twice its sigma (else the fix noise would tilt the level more than it corrects);
    no vertical acceleration (a road vehicle). The generated `leonav_level` is applied to
    f_b - C_n_b a_enu, C_n_b from the current roll, pitch and the course yaw, a few fixed-point
    iterations. The report has both levels and the naive one's difference (deg).
    """
    half = window_s / 2
    sel = (imu.t >= t_s - half) & (imu.t <= t_s + half)
    k = min(int(np.searchsorted(imu.t, t_s)), imu.t.size - 1)
    f_b = imu.f_b_mps2[sel].mean(axis=0) if sel.any() else imu.f_b_mps2[k]
    w_up = float(imu.w_b_radps[sel, 2].mean()) if sel.any() else float(imu.w_b_radps[k, 2])
    v = np.array([np.interp(t_s, t_v, v_enu[:, j]) for j in range(2)])
    a_c = w_up * np.array([-v[1], v[0], 0.0])
    a_t, a_t_sigma = along_track_accel(fixes, t_s, yaw_rad, 3 * window_s)
    a_t_used = a_t if abs(a_t) > 2 * a_t_sigma else 0.0
    a_enu = a_c + a_t_used * np.array([math.cos(yaw_rad), math.sin(yaw_rad), 0.0])
    naive = nav.level(f_b)
    roll, pitch = naive
    for _ in range(iterations):
        a_b = _rot_b_to_n(roll, pitch, yaw_rad).T @ a_enu
        roll, pitch = nav.level(f_b - a_b)
    err = float(np.degrees(np.max(np.abs(np.array(naive) - [roll, pitch]))))
    return roll, pitch, {"accel_enu_mps2": a_enu.tolist(), "centripetal_mps2": float(np.linalg.norm(a_c)),
                         "along_track_mps2": a_t, "along_track_sigma_mps2": a_t_sigma,
                         "along_track_used": a_t_used != 0.0, "f_b_mean_mps2": f_b.tolist(),
                         "naive_roll_pitch_deg": np.degrees(naive).tolist(),
                         "roll_pitch_deg": np.degrees([roll, pitch]).tolist(), "naive_error_deg": err,
                         "window_s": window_s}
