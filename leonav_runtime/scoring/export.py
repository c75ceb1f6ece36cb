"""Trajectory files of a run: CSV (geodetic + ECEF + ENU, per-epoch sigma), RTKLIB .pos, KML, GPX.

Epochs: every 1/rate s from the filter start, the state after the last record at or before
each (the IMU point's position). Geodetic: WGS84 latitude/longitude (deg), ellipsoidal height
(m); ECEF (m); sigma: 1-sigma of the ENU position error (m) and of the attitude error about
the body up axis (deg, the yaw sigma of a level vehicle). `.pos` is written by
`gnss.solution_io.write_pos` (GPS time, Q = 5, ns = 0: loosely coupled, no satellites);
KML by simplekml, GPX by gpxpy (maintained libraries).
"""
from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.common import output
from leonav_runtime.orbits import geometry
from leonav_runtime.dataset.scoring import states_at, yaw_of
from leonav_runtime.gnss import solution_io
from leonav_runtime.gnss import time as gtime

CSV_HEADER = ("t_s", "unix_s", "lat_deg", "lon_deg", "h_m", "x_ecef_m", "y_ecef_m", "z_ecef_m", "e_m", "n_m", "u_m",
              "sigma_e_m", "sigma_n_m", "sigma_u_m", "v_e_mps", "v_n_mps", "v_u_mps", "yaw_deg", "sigma_yaw_deg")


def trajectory(res: lfilter.RunResult, layout, origin, t0_unix: float, t_start: float, rate_hz: float) -> dict:
    """Arrays per output epoch (module doc): t, unix, lat/lon rad, h, r_ecef, p_enu, sigma_enu,
    v_enu, yaw_rad, sigma_yaw_rad."""
    t = np.arange(t_start, float(res.t[-1]) + 1e-9, 1.0 / rate_hz)
    t = t[t >= res.t[0]]                  # epochs with an estimate (the first record ends after the start)
    _, x, pd = states_at(res, t)
    p = x[:, layout.X_P_ENU_SLICE]
    lat0, lon0, h0 = origin
    r = geometry.enu_to_ecef(p, geometry.geodetic_to_ecef(lat0, lon0, h0), lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r)
    return {"t": t, "unix": t + t0_unix, "lat": np.asarray(lat), "lon": np.asarray(lon), "h": np.asarray(h),
            "r_ecef": np.atleast_2d(r), "p_enu": p, "sigma_enu": np.sqrt(pd[:, layout.DX_DP_SLICE]),
            "v_enu": x[:, layout.X_V_ENU_SLICE], "yaw": yaw_of(x[:, layout.X_Q_NB_SLICE]),
            "sigma_yaw": np.sqrt(pd[:, layout.DX_DTHETA_SLICE][:, 2])}


def write_all(stem: Path, traj: dict, name: str, inputs: list[str]) -> list[Path]:
    """stem.csv, stem.pos, stem.kml, stem.gpx; returns the paths written."""
    return [write_csv(stem.with_suffix(".csv"), traj), write_pos(stem.with_suffix(".pos"), traj, inputs),
            write_kml(stem.with_suffix(".kml"), traj, name), write_gpx(stem.with_suffix(".gpx"), traj, name)]


def write_csv(path: Path, traj: dict) -> Path:
    n = traj["t"].size
    rows = (
        [f"{traj['t'][i]:.3f}", f"{traj['unix'][i]:.3f}", f"{np.degrees(traj['lat'][i]):.9f}",
         f"{np.degrees(traj['lon'][i]):.9f}", f"{traj['h'][i]:.4f}"]
        + [f"{v:.4f}" for v in traj["r_ecef"][i]] + [f"{v:.4f}" for v in traj["p_enu"][i]]
        + [f"{v:.4f}" for v in traj["sigma_enu"][i]] + [f"{v:.4f}" for v in traj["v_enu"][i]]
        + [f"{np.degrees(traj['yaw'][i]):.3f}", f"{np.degrees(traj['sigma_yaw'][i]):.3f}"]
        for i in range(n))
    return output.write_csv(path, CSV_HEADER, rows)


def gps_seconds(unix_s: np.ndarray) -> np.ndarray:
    """GPS seconds of unix times (the leap second count of the first epoch; runs span minutes)."""
    whole = float(np.floor(unix_s[0]))
    shift = gtime.utc_to_gps_seconds(_dt.datetime.fromtimestamp(whole, _dt.timezone.utc)) - whole
    return np.asarray(unix_s, float) + shift


def write_pos(path: Path, traj: dict, inputs: list[str]) -> Path:
    cov = np.zeros((traj["t"].size, 3, 3))
    for j in range(3):
        cov[:, j, j] = traj["sigma_enu"][:, j] ** 2
    zeros = np.zeros(traj["t"].size)
    return solution_io.write_pos(path, gps_seconds(traj["unix"]), traj["r_ecef"], cov, zeros, zeros, inputs=inputs,
                                 options={"pos mode": "leonav GNSS/INS (loosely coupled fixes)"}, program="leonav run")


def write_kml(path: Path, traj: dict, name: str) -> Path:
    import simplekml

    kml = simplekml.Kml()
    line = kml.newlinestring(name=name, coords=list(zip(np.degrees(traj["lon"]).tolist(),
                                                        np.degrees(traj["lat"]).tolist(), traj["h"].tolist())))
    line.altitudemode = simplekml.AltitudeMode.clamptoground
    line.style.linestyle.width = 3
    kml.save(str(path))
    return path


def write_gpx(path: Path, traj: dict, name: str) -> Path:
    import gpxpy.gpx

    gpx = gpxpy.gpx.GPX()
    track = gpxpy.gpx.GPXTrack(name=name)
    seg = gpxpy.gpx.GPXTrackSegment()
    for lat, lon, h, u in zip(np.degrees(traj["lat"]), np.degrees(traj["lon"]), traj["h"], traj["unix"]):
        seg.points.append(gpxpy.gpx.GPXTrackPoint(float(lat), float(lon), elevation=float(h),
                                                  time=_dt.datetime.fromtimestamp(float(u), _dt.timezone.utc)))
    track.segments.append(seg)
    gpx.tracks.append(track)
    path.write_text(gpx.to_xml())
    return path
