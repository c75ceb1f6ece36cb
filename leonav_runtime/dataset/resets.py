"""A record stream through the generated filter with covariance resets at IMU gaps and gate lockouts.

The generated C loop runs the stream in segments; between two segments the error
covariance is re-initialised, and the records of each segment are concatenated into one
`RunResult`:

- IMU gap: an IMU interval longer than `max_gap_s` says nothing of how the rates varied
  inside it, and one IMU step from the samples around it turns any change of tilt inside it
  into a gravity error (5 deg over 5 s: 4 m/s). `bridge_gaps` replaces that step by the
  generated constant-velocity predict (position moves with the velocity, velocity and
  attitude held) and drops the measurements inside the gap (the state still stands at its
  start), counted. After that step the covariance is inflated by what it cannot know: with
  sigma_f, sigma_w the per-axis standard deviations of 0.25 s means of the specific force
  and the rate over the `around_s` seconds of IMU records on both sides (the motion's own
  variability, without the vibration that averages out) and g the gap length, the
  variances grow by (sigma_f g)^2 (velocity), (sigma_f g^2 / 2)^2 (position) and
  (sigma_w g)^2 (attitude, but not beyond the start prior's variance: the filter converges
  from there, and a tilt variance of several degrees lets the fixes turn gravity into
  velocity), per axis. The next fixes then pull the state back.
- Gate lockout: once the state is wrong by more than the fix covariance admits, every
  later fix is gated and the filter never recovers. After `lockout_fixes` consecutive fix
  epochs with a gated fix, the position and velocity covariance are set back to the start
  prior's, each position variance raised to at least the largest squared innovation of
  that axis over those epochs (what the fixes keep saying: a jump larger than the prior
  would be gated again), and the attitude variances raised to at least the prior's (a wrong
  tilt or heading is what drives the state off) before the next record, so the next fix is
  applied.
Both kinds of reset are counted and reported with the run.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import records


def long_gaps(recs: np.ndarray, max_gap_s: float, kind: int = records.KIND_IMU) -> np.ndarray:
    """Indices of the `kind` predict records whose interval dt (s) exceeds max_gap_s (increasing)."""
    return np.flatnonzero((recs["kind"] == kind) & (recs["dt"] > max_gap_s))


def _near(recs: np.ndarray, i: int, around_s: float) -> np.ndarray:
    """Mask of the IMU records within around_s (s) before the start or after the end of gap record i."""
    imu = (recs["kind"] == records.KIND_IMU) & (recs["dt"] > 0)
    imu[i] = False
    t1 = recs["t"][i]
    t0 = t1 - recs["dt"][i]
    near = imu & (((recs["t"] >= t0 - around_s) & (recs["t"] <= t0)) |
                  ((recs["t"] > t1) & (recs["t"] <= t1 + around_s)))
    near[i] = False
    return near


def _rates(recs: np.ndarray, layout) -> tuple[np.ndarray, np.ndarray]:
    dt = recs["dt"][:, None]
    return recs["u"][:, layout.U_DTHETA_B_SLICE] / dt, recs["u"][:, layout.U_DVEL_B_SLICE] / dt


def bridge_gaps(recs: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, int]:
    """(records with each long IMU gap's step made a constant-velocity predict and without the
    measurements strictly inside a gap, how many measurements were dropped) (module doc)."""
    recs = recs.copy()
    gaps = long_gaps(recs, max_gap_s)
    inside = np.zeros(recs.size, bool)
    is_meas = recs["kind"] >= 0
    for i in gaps:
        t1, g = recs["t"][i], recs["dt"][i]
        inside |= is_meas & (recs["t"] > t1 - g) & (recs["t"] < t1)
    recs["kind"][gaps] = records.KIND_CV
    return recs[~inside], int(inside.sum())


def reset_covariance(P: np.ndarray, P0: np.ndarray, layout, pos_var: np.ndarray | None = None) -> np.ndarray:
    """P with the position and velocity rows/columns set to P0's (cross terms to the rest
    zeroed; the position variances raised to at least `pos_var` (3,) m^2 when given) and each
    attitude variance raised to at least P0's (its row and column scaled with it, so P stays
    positive semi-definite)."""
    P = P.copy()
    idx = np.r_[np.arange(layout.DX_DP_SLICE.start, layout.DX_DP_SLICE.stop),
                np.arange(layout.DX_DV_SLICE.start, layout.DX_DV_SLICE.stop)]
    P[idx, :] = 0.0
    P[:, idx] = 0.0
    P[np.ix_(idx, idx)] = P0[np.ix_(idx, idx)]
    if pos_var is not None:
        dp = np.arange(layout.DX_DP_SLICE.start, layout.DX_DP_SLICE.stop)
        P[dp, dp] = np.maximum(P[dp, dp], pos_var)
    for k in range(layout.DX_DTHETA_SLICE.start, layout.DX_DTHETA_SLICE.stop):
        if P[k, k] < P0[k, k]:
            s = np.sqrt(P0[k, k] / P[k, k]) if P[k, k] > 0 else 0.0
            P[k, :] *= s
            P[:, k] *= s
            P[k, k] = P0[k, k]
    return P


def gap_inflation(recs: np.ndarray, i: int, around_s: float, layout, block_s: float = 0.25) -> np.ndarray:
    """Variances (NDX,) to add after the gap-bridging IMU record i (module doc)."""
    near = _near(recs, i, around_s)
    g = float(recs["dt"][i])
    add = np.zeros(layout.NDX)
    if near.sum() < 3:
        return add
    w, f = _rates(recs[near], layout)
    # the variability that does not average out over the gap: of block means, not of samples
    n = max(1, int(round(block_s / float(np.median(recs["dt"][near])))))
    m = (w.shape[0] // n) * n
    if m < 2 * n:
        sig_w, sig_f = w.std(axis=0), f.std(axis=0)
    else:
        sig_w = w[:m].reshape(-1, n, 3).mean(axis=1).std(axis=0)
        sig_f = f[:m].reshape(-1, n, 3).mean(axis=1).std(axis=0)
    add[layout.DX_DP_SLICE] = (sig_f * g * g / 2) ** 2
    add[layout.DX_DV_SLICE] = (sig_f * g) ** 2
    add[layout.DX_DTHETA_SLICE] = (sig_w * g) ** 2
    return add


def _lockout_end(res: lfilter.RunResult, fix_ids: np.ndarray, n_fixes: int) -> tuple[int, np.ndarray] | None:
    """(index of the last record of the n_fixes-th consecutive fix epoch with a gated fix, the
    largest squared innovation per fix kind in `fix_ids` order over those epochs), or None."""
    if n_fixes <= 0:
        return None
    rows = np.flatnonzero(np.isin(res.kind, fix_ids))
    if rows.size == 0:
        return None
    t = res.t[rows]
    first = np.r_[True, t[1:] != t[:-1]]
    epoch = np.cumsum(first) - 1
    gated = np.zeros(epoch[-1] + 1, bool)
    np.logical_or.at(gated, epoch, res.status[rows] == lfilter.STATUS_GATED)
    run = 0
    for e, g in enumerate(gated):
        run = run + 1 if g else 0
        if run == n_fixes:
            span = rows[(epoch > e - n_fixes) & (epoch <= e)]
            y2 = np.array([np.nanmax(np.r_[0.0, res.y[span[res.kind[span] == k]] ** 2]) for k in fix_ids])
            return int(span[-1]), y2
    return None


def _concat(parts: list[lfilter.RunResult]) -> lfilter.RunResult:
    if len(parts) == 1:
        return parts[0]
    cat = {f: np.concatenate([getattr(p, f) for p in parts]) for f in
           ("t", "kind", "sat_id", "x", "P_diag", "y", "S", "nis", "status")}
    counts = {f: sum(getattr(p, f) for p in parts) for f in ("n_imu", "n_applied", "n_gated", "n_failed", "n_cv")}
    return lfilter.RunResult(P=None, **cat, **counts)


def run(recs: np.ndarray, x0: np.ndarray, P0: np.ndarray, params: np.ndarray, layout, *, gate: float | None,
        library, fix_ids, max_gap_s: float, lockout_fixes: int,
        around_s: float = 1.0) -> tuple[lfilter.RunResult, dict]:
    """(RunResult over all of `recs`, {"imu_gap": resets, "gate_lockout": resets}) (module doc).
    fix_ids: the kinds of the E, N, U position fixes, in that order; gate: NIS threshold or None."""
    gaps = set(long_gaps(recs, max_gap_s, records.KIND_CV).tolist())
    fix_ids = np.asarray(fix_ids)
    x, P = np.asarray(x0, float), np.asarray(P0, float)
    parts: list[lfilter.RunResult] = []
    counts = {"imu_gap": 0, "gate_lockout": 0}
    start = 0
    while start < recs.size:
        stop = min([g + 1 for g in gaps if g >= start] + [recs.size])
        ekf = lfilter.EKF(x, P, params, gate=gate, library=library)
        res = ekf.run(recs[start:stop])
        lock = _lockout_end(res, fix_ids, lockout_fixes)
        j = None if lock is None else lock[0]
        if j is not None and start + j + 1 < recs.size:
            ekf = lfilter.EKF(x, P, params, gate=gate, library=library)
            res = ekf.run(recs[start:start + j + 1])
            parts.append(res)
            x, P = ekf.x.copy(), reset_covariance(ekf.P, P0, layout, lock[1])
            counts["gate_lockout"] += 1
            start += j + 1
            continue
        parts.append(res)
        x, P = ekf.x.copy(), ekf.P
        if stop - 1 in gaps and stop < recs.size:
            add = gap_inflation(recs, stop - 1, around_s, layout)
            th = layout.DX_DTHETA_SLICE   # attitude: no more uncertain than the start prior's
            d = np.diag(P)[th]
            add[th] = np.clip(np.maximum(d, np.diag(P0)[th]) - d, 0.0, add[th])
            P = P + np.diag(add)
            counts["imu_gap"] += 1
        start = stop
    return _concat(parts), counts
