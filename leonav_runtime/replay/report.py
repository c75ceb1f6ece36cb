"""Replay outputs: metrics.json, rmse_vs_time.csv, trajectory.csv, columns.txt, the plots, and per mode
the geodetic trajectory files (trajectory_<mode>.csv/.pos/.kml/.gpx, `scoring.export`)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.inputs import FilterInputs
from leonav_runtime.common.output import write_csv, write_json
from leonav_runtime.replay.plots import plot_rmse_vs_time, plot_trajectories
from leonav_runtime.replay.scoring import Reference

RMSE_COLUMNS = ["t_s", "mode", "position_error_m", "horizontal_error_m", "vertical_error_m", "velocity_error_mps",
                "attitude_error_deg"]
TRAJECTORY_COLUMNS = ["t_s", "mode", "p_e_m", "p_n_m", "p_u_m", "v_e_mps", "v_n_mps", "v_u_mps", "roll_deg",
                      "pitch_deg", "yaw_deg", "sigma_p_e_m", "sigma_p_n_m", "sigma_p_u_m", "sigma_v_e_mps",
                      "sigma_v_n_mps", "sigma_v_u_mps"]
COLUMNS_TEXT = (
    "rmse_vs_time.csv: t_s [s since the first IMU sample, UTC in metrics.json initialization.epoch_utc], mode, "
    "position/horizontal/vertical error [m], velocity error [m/s], attitude error [deg] = norms of "
    "estimate [-] reference (ENU at the origin; attitude as body rotation vector); NaN where the reference "
    "has no such quantity.\ntrajectory.csv: the estimates at the same times, ENU (m, m/s), Euler roll/pitch/yaw "
    "(deg, yaw from East towards North) and 1-sigma from the filter's covariance.\n")


def _norm(v: np.ndarray) -> float:
    return float(np.sqrt(np.sum(v**2)))


def write_outputs(out_dir: Path, inputs: FilterInputs, scored: dict, metrics: dict, ref: Reference | None,
                  nav: navfuncs.NavFunctions) -> None:
    """metrics.json, rmse_vs_time.csv, trajectory.csv, columns.txt, rmse_vs_time.png, trajectories.png."""
    L = nav.layout
    from leonav_runtime.common.provenance import provenance

    metrics = {"provenance": provenance(), **metrics}
    write_json(out_dir / "metrics.json", metrics)
    rows, traj = [], []
    for mode, s in scored.items():
        e, x, sigma = s["err"], s["x"], s["sigma"]
        rpy = nav.euler_from_quat(x[:, L.X_Q_NB_SLICE]) if x.size else np.zeros((0, 3))
        for i, t in enumerate(s["t"]):
            dp = e[i, L.DX_DP_SLICE]
            rows.append([t, mode, _norm(dp), _norm(dp[:2]), abs(dp[2]), _norm(e[i, L.DX_DV_SLICE]),
                         math.degrees(_norm(e[i, L.DX_DTHETA_SLICE]))])
            traj.append([t, mode, *x[i, L.X_P_ENU_SLICE], *x[i, L.X_V_ENU_SLICE], *np.degrees(rpy[i]),
                         *sigma[i, L.DX_DP_SLICE], *sigma[i, L.DX_DV_SLICE]])
    write_csv(out_dir / "rmse_vs_time.csv", RMSE_COLUMNS, rows)
    write_csv(out_dir / "trajectory.csv", TRAJECTORY_COLUMNS, traj)
    (out_dir / "columns.txt").write_text(COLUMNS_TEXT)
    plot_rmse_vs_time(out_dir / "rmse_vs_time.png", scored, metrics, L)
    plot_trajectories(out_dir / "trajectories.png", scored, ref, inputs, L)
    from leonav_runtime.common import html_report

    html_report.write_replay_report(out_dir, metrics)


def write_geodetic_trajectories(out_dir: Path, inputs: FilterInputs, runs: dict, layout, rate_hz: float = 10.0,
                                source: str = "") -> dict[str, list[str]]:
    """trajectory_<mode>.csv/.pos/.kml/.gpx (WGS84 lat/lon/h, ECEF, ENU, per-epoch sigma) of each
    run, as `leonav run` writes them; none when the run has no UTC epoch or ENU origin."""
    from leonav_runtime.scoring import export

    if inputs.epoch_utc is None or inputs.origin is None:
        return {}
    out = {}
    for mode, (_, res, _) in runs.items():
        traj = export.trajectory(res, layout, inputs.origin, inputs.epoch_utc.timestamp(),
                                 float(inputs.init.get("start_s", res.t[0])), rate_hz)
        stem = out_dir / f"trajectory_{mode.replace('+', '_')}"
        out[mode] = [p.name for p in export.write_all(stem, traj, mode, [source])]
    return out
