"""Scores of a replay: errors against a reference on an evaluation grid, RMSE per mode.

Reference: truth.csv when present (synthetic sessions: position, velocity and attitude),
else the GNSS fixes (position only; then fix+imu is compared with its own input, which
flatters it). Errors are `x_est [-] x_ref` (generated boxminus): position and velocity
in ENU at the origin (m, m/s), attitude as the body rotation vector (rad); with the fixes
as reference only the position difference. Evaluation times: every IMU sample inside the
truth's span, or the fix times; the estimate is the one after the last record at that time.
"""
from __future__ import annotations

import csv
import dataclasses
import datetime as _dt
import math
from pathlib import Path

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import navfuncs, records
from leonav_runtime.orbits import geometry
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.inputs import FilterInputs, FixTable
from leonav_runtime.scoring.errors import rms

TRUTH_COLUMNS = ("utc_unix_s", "lat_deg", "lon_deg", "h_m", "v_e_mps", "v_n_mps", "v_u_mps", "roll_rad",
                 "pitch_rad", "yaw_rad")


@dataclasses.dataclass
class Reference:
    """Reference on the replay axis: t (s), p_enu_m (m), v_enu_mps (m/s) or None, rpy_rad
    (roll, pitch, yaw; rad, yaw from East towards North, unwrapped) or None."""

    kind: str
    t: np.ndarray
    p_enu_m: np.ndarray
    v_enu_mps: np.ndarray | None
    rpy_rad: np.ndarray | None


def _interp_rows(t_ref: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, t_ref, values[:, j]) for j in range(values.shape[1])])


def truth_reference(path: Path, epoch_utc: _dt.datetime, origin, nav: navfuncs.NavFunctions) -> Reference:
    """truth.csv (utc, geodetic, ENU velocity at the row's position, Euler) on the replay axis and frame."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or any(k not in rows[0] for k in TRUTH_COLUMNS):
        raise UserInputError(f"{path}: expected a header with {', '.join(TRUTH_COLUMNS)} and at least one row")
    try:
        a = np.array([[float(r[k]) for k in TRUTH_COLUMNS] for r in rows])
    except ValueError as exc:
        raise UserInputError(f"{path}: non-numeric value ({exc})") from None
    col = {k: j for j, k in enumerate(TRUTH_COLUMNS)}
    lat, lon = np.radians(a[:, col["lat_deg"]]), np.radians(a[:, col["lon_deg"]])
    lat0, lon0, h0 = origin
    t = a[:, col["utc_unix_s"]] - epoch_utc.timestamp()
    r = geometry.geodetic_to_ecef(lat, lon, a[:, col["h_m"]])
    p = geometry.ecef_to_enu(r, geometry.geodetic_to_ecef(lat0, lon0, h0), lat0, lon0)
    v_local = a[:, [col["v_e_mps"], col["v_n_mps"], col["v_u_mps"]]]
    v_ecef = np.einsum("nji,nj->ni", geometry.C_enu_ecef(lat, lon), v_local)
    v = v_ecef @ geometry.C_enu_ecef(lat0, lon0).T
    rpy = np.column_stack([a[:, col["roll_rad"]], a[:, col["pitch_rad"]], np.unwrap(a[:, col["yaw_rad"]])])
    return Reference("truth.csv", t, p, v, rpy)


def fix_reference(fixes: FixTable) -> Reference:
    return Reference("GNSS fixes", fixes.t, fixes.p_enu_m, None, None)


def evaluate(inputs: FilterInputs, runs: dict, ref: Reference | None, nav: navfuncs.NavFunctions) -> dict:
    """Errors per mode on the evaluation grid: {mode: dict(t, err (n, 9), x (n, NX), sigma (n, 9))}."""
    L = nav.layout
    out = {}
    for mode, (recs, res, _) in runs.items():
        if ref is None:
            t_eval = inputs.imu.t
        elif ref.rpy_rad is not None:   # truth: every IMU time inside the truth's span
            t_eval = inputs.imu.t[(inputs.imu.t >= ref.t[0]) & (inputs.imu.t <= ref.t[-1])]
        else:                           # fixes: at the fix times
            t_eval = ref.t[(ref.t >= inputs.imu.t[0]) & (ref.t <= inputs.imu.t[-1])]
        rows = np.searchsorted(recs["t"], t_eval + 1e-9, side="left") - 1
        ok = rows >= 0
        t_eval, rows = t_eval[ok], rows[ok]
        x = res.x[rows]
        err = np.full((t_eval.size, 9), np.nan)
        if ref is not None and t_eval.size:
            if ref.rpy_rad is not None:
                x_ref = np.zeros_like(x)
                x_ref[:, L.X_P_ENU_SLICE] = _interp_rows(ref.t, ref.p_enu_m, t_eval)
                x_ref[:, L.X_V_ENU_SLICE] = _interp_rows(ref.t, ref.v_enu_mps, t_eval)
                x_ref[:, L.X_Q_NB_SLICE] = nav.quat_from_euler(_interp_rows(ref.t, ref.rpy_rad, t_eval))
                rest = slice(L.X_Q_NB_SLICE.stop, None)     # biases, clock, LO: not scored
                x_ref[:, rest] = x[:, rest]
                err = np.atleast_2d(nav.boxminus(x, x_ref))[:, L.DX_NAV9_SLICE]
            else:
                k = np.searchsorted(ref.t, t_eval)
                k = np.clip(k, 0, ref.t.size - 1)
                err[:, L.DX_DP_SLICE] = x[:, L.X_P_ENU_SLICE] - ref.p_enu_m[k]
        out[mode] = {"t": t_eval, "err": err, "x": x, "sigma": np.sqrt(res.P_diag[rows][:, L.DX_NAV9_SLICE])}
    return out


def mode_metrics(runs: dict, scored: dict, nav: navfuncs.NavFunctions) -> dict:
    """Per mode: RMSE (position, horizontal, vertical, velocity, attitude), final errors, record counts."""
    L = nav.layout
    names = {v: k for k, v in nav.library.meas_ids.items()}
    out = {}
    for mode, (recs, res, seconds) in runs.items():
        s = scored[mode]
        e = s["err"]
        per_kind = {}
        for kind in np.unique(res.kind[res.kind != records.KIND_IMU]):
            sel = res.kind == kind
            used = (res.status == lfilter.STATUS_APPLIED) | (res.status == lfilter.STATUS_GATED)
            nis = res.nis[sel & used]
            per_kind[names.get(int(kind), str(kind))] = {
                "records": int(sel.sum()), "applied": int(np.sum(res.status[sel] == lfilter.STATUS_APPLIED)),
                "gated": int(np.sum(res.status[sel] == lfilter.STATUS_GATED)),
                "failed": int(np.sum(res.status[sel] == lfilter.STATUS_FAILED)),
                "nis_mean": float(np.mean(nis)) if nis.size else None}
        dp = e[:, L.DX_DP_SLICE]
        att = e[:, L.DX_DTHETA_SLICE] * 180 / math.pi
        final = dp[-1] if e.size else None
        out[mode] = {
            "rmse_position_m": rms(dp), "rmse_horizontal_m": rms(dp[:, :2]),
            "rmse_vertical_m": rms(dp[:, 2:]), "rmse_velocity_mps": rms(e[:, L.DX_DV_SLICE]),
            "rmse_attitude_deg": rms(att),
            "final_position_error_m": (float(np.linalg.norm(final)) if final is not None and np.all(np.isfinite(final))
                                       else None),
            "eval_points": int(s["t"].size),
            "records": {"imu": res.n_imu, "applied": res.n_applied, "gated": res.n_gated, "failed": res.n_failed},
            "per_observable": per_kind, "filter_seconds": seconds,
        }
        if res.orbit_states is not None:   # --orbit-states: the estimated orbit offsets per satellite
            out[mode]["orbit_states"] = res.orbit_states
    return out
