"""Scores of a dataset run against its reference trajectory.

Every line is scored the same way, at the reference epochs (the CPET run: its 800
ground-truth poses): the estimate is the filter state after the last record at or before the
epoch (position of the IMU point, which the reference is taken to be), errors in ENU at the
run's origin. GPS alone, two ways: holding the last fix (the antenna's position as the receiver
gave it), and interpolating linearly between the fixes around the epoch (no lag; a late time tag
shows as an error along the track rather than being cancelled by the hold's lag).
Outages: fixes removed over [start, start + length); the horizontal error at the end
(state just before the first fix after it; reference interpolated linearly) against holding
the last fix before the outage. Yaw: wrapped difference to the reference yaw from
`yaw_skip_s` on.
"""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.dataset.load import Reference
from leonav_runtime.inputs import FixTable
from leonav_runtime.scoring.errors import (cdf, error_stats, hold_last_fix, rms, states_at,  # noqa: F401
                                           wrap, yaw_of)


def reference_at(ref: Reference, t: float | np.ndarray) -> np.ndarray:
    """Reference position (m, ENU) interpolated linearly at t."""
    t = np.atleast_1d(t)
    return np.column_stack([np.interp(t, ref.t, ref.p_enu_m[:, j]) for j in range(3)])


def run_scores(res: lfilter.RunResult, layout, ref: Reference, yaw_skip_s: float) -> tuple[dict, dict]:
    """(scores, series) of one run: position stats at the reference epochs, yaw RMSE after
    `yaw_skip_s`, and the per-epoch series (t, err_enu, sigma_enu, yaw_err_rad) for plots."""
    _, x, pd = states_at(res, ref.t)
    err = x[:, layout.X_P_ENU_SLICE] - ref.p_enu_m
    out = error_stats(err)
    yaw_err = np.full(ref.t.size, np.nan)
    if ref.yaw_rad is not None:
        yaw_err = wrap(yaw_of(x[:, layout.X_Q_NB_SLICE]) - ref.yaw_rad)
        late = (ref.t >= yaw_skip_s) & np.isfinite(yaw_err)
        out["rmse_yaw_deg_after_skip"] = math.degrees(rms(yaw_err[late])) if late.any() else None
        out["rmse_yaw_deg"] = math.degrees(rms(yaw_err)) if np.isfinite(yaw_err).any() else None
        out["yaw_skip_s"] = yaw_skip_s
    series = {"t": ref.t, "err_enu": err, "sigma_enu": np.sqrt(pd[:, layout.DX_DP_SLICE]), "yaw_err_rad": yaw_err}
    # consistency of the exported per-epoch sigma: mean of (error / sigma)^2 per axis (1 if honest)
    z2 = (err / series["sigma_enu"]) ** 2
    ok = np.all(np.isfinite(z2), axis=1)
    out["position_nees_enu"] = z2[ok].mean(axis=0).tolist() if ok.any() else None
    return out, series


def outage_scores(fixes: FixTable, ref: Reference, starts_s, length_s: float, runs: dict, layout) -> dict:
    """Per outage start: the filter's horizontal error at its end (runs: {start: RunResult}) and
    holding the last fix; summary: medians, their ratio, and outages worse than holding."""
    rows = []
    for start in starts_s:
        end = start + length_s
        if start < fixes.t[0] or end > ref.t[-1] or start not in runs:
            rows.append({"start_s": start, "skipped": "outside the reference or fix span"})
            continue
        p_ref = reference_at(ref, end)[0]
        _, x, _ = states_at(runs[start], np.array([end - 1e-6]))
        k = np.searchsorted(fixes.t, start) - 1
        filt = float(np.hypot(*(x[0, layout.X_P_ENU_SLICE][:2] - p_ref[:2])))
        hold = float(np.hypot(*(fixes.p_enu_m[k, :2] - p_ref[:2])))
        rows.append({"start_s": start, "end_s": end, "filter_horizontal_m": filt, "hold_last_fix_horizontal_m": hold,
                     "ratio": filt / hold if hold > 0 else None})
    done = [r for r in rows if "filter_horizontal_m" in r]
    med_f = float(np.median([r["filter_horizontal_m"] for r in done])) if done else None
    med_h = float(np.median([r["hold_last_fix_horizontal_m"] for r in done])) if done else None
    return {"length_s": length_s, "outages": rows, "median_filter_m": med_f, "median_hold_last_fix_m": med_h,
            "median_ratio": med_f / med_h if done and med_h else None,
            "median_of_ratios": float(np.median([r["ratio"] for r in done])) if done else None,
            "worse_than_hold": int(sum(r["filter_horizontal_m"] > r["hold_last_fix_horizontal_m"] for r in done))}


def fix_nis_stats(nis_by_kind: dict[str, np.ndarray]) -> dict:
    """Mean NIS per fix axis and over all fix records."""
    allv = np.concatenate(list(nis_by_kind.values())) if nis_by_kind else np.zeros(0)
    out = {k: (float(np.mean(v)) if v.size else None) for k, v in nis_by_kind.items()}
    out["all"] = float(np.mean(allv)) if allv.size else None
    out["records"] = int(allv.size)
    return out




def interpolated_fix(fixes: FixTable, t: np.ndarray) -> np.ndarray:
    """(n, 3) fixes interpolated linearly at each t (m, ENU; NaN outside the fixes' span)."""
    out = np.column_stack([np.interp(t, fixes.t, fixes.p_enu_m[:, j]) for j in range(3)])
    out[(t < fixes.t[0]) | (t > fixes.t[-1])] = np.nan
    return out


def latency_estimate(res: lfilter.RunResult, layout) -> dict:
    """The estimated fix latency at the end of a run: value and 1-sigma (s)."""
    from leonav_runtime.replay.options import latency_estimate as of_state

    return of_state(res.x[-1], res.P_diag[-1], layout)


AUTO_OUTAGE_FRACTIONS = (0.2, 0.35, 0.5, 0.65, 0.8)
"""Where 'auto' outages start, as fractions of the IMU/GNSS overlap."""


def settings(sc: dict, imu_t: np.ndarray, fix_t: np.ndarray) -> dict:
    """The `[scoring]` values with 'auto' resolved on the IMU/GNSS overlap (s on the run axis):
    outages at AUTO_OUTAGE_FRACTIONS of it, 30 s long or 10 % of it; the yaw skip 60 s or 15 % of it."""
    lo, hi = max(float(imu_t[0]), float(fix_t[0])), min(float(imu_t[-1]), float(fix_t[-1]))
    span = max(hi - lo, 0.0)
    out = {"overlap_s": [lo, hi]}
    length = sc["outage_length_s"]
    out["outage_length_s"] = float(min(30.0, 0.1 * span)) if length == "auto" else float(length)
    starts = sc["outage_starts_s"]
    out["outage_starts_s"] = ([round(lo + f * span, 3) for f in AUTO_OUTAGE_FRACTIONS] if starts == "auto"
                              else [float(v) for v in starts])
    skip = sc["yaw_skip_s"]
    out["yaw_skip_s"] = float(min(60.0, 0.15 * span)) if skip == "auto" else float(skip)
    out["source"] = {k: ("auto" if sc[k] == "auto" else "given") for k in ("outage_starts_s", "outage_length_s",
                                                                          "yaw_skip_s")}
    return out
