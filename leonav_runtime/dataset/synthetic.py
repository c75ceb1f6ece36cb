"""A synthetic drive written as a dataset: files and a description, with known truth.

The GNSS/INS path is judged on real drives (`cpet_run3`); this writes a drive whose every
error is known, to test what a real drive cannot isolate: a car moving from the first
sample (no standstill), turns and speed changes, a consumer IMU, fixes with a known
receiver latency (a fix tagged t holds the antenna position at t - latency).

The motion is a scenario's `maneuvers` trajectory through the generated mechanization
(`simulation.simulate.truth`): the IMU increments are exact for it, then the profile's biases
and white noise are added (`sensor_errors`). Files (CSV, unix time): imu.csv (rates in body
FLU), fixes.csv (lat, lon, ellipsoidal height, GNSS velocity E N U), reference.csv (truth:
lat, lon, h, quaternion body -> ENU x y z w) and drive.toml, a description with documented keys.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.orbits import geometry

EPOCH_UNIX_S = 1_700_000_000.0
"""Truth t = 0 (2023-11-14 22:13:20 UTC): an arbitrary day, unix seconds."""

TURNS_AND_SPEED_CHANGES = (
    # [duration_s, acceleration_mps2, turn_rate_deg_s]: a town drive, 10 m/s at the start
    (4.0, 0.0, 0.0), (5.0, 0.8, 0.0), (6.0, 0.0, 15.0), (4.0, -1.0, 0.0), (6.0, 0.0, -20.0), (5.0, 0.6, 0.0),
    (6.0, 0.0, 12.0), (5.0, -0.8, 0.0), (6.0, 0.0, -15.0), (5.0, 0.5, 5.0), (8.0, 0.0, 0.0),
)


@dataclasses.dataclass
class DriveConfig:
    """Settings of the synthetic drive (SI; degrees where the name says so)."""

    seconds: float = 60.0
    seed: int = 0
    lat_deg: float = 45.5
    lon_deg: float = -73.4
    h_m: float = 30.0
    speed_mps: float = 10.0
    yaw_deg: float = 30.0                # initial heading, from East towards North
    maneuvers: tuple = TURNS_AND_SPEED_CHANGES
    imu_profile: str = "wt901"
    imu_rate_hz: float = 100.0
    gnss_rate_hz: float = 10.0
    fix_latency_s: float = 0.1
    fix_sigma_m: tuple = (0.5, 0.5, 1.0)  # white, per axis E N U
    velocity_sigma_mps: tuple = (0.05, 0.05, 0.1)
    time_offset: str = "estimate"        # what the description says under [gnss] time_offset_s
    modes: tuple = ("fix+imu", "fix+imu+nhc")


@dataclasses.dataclass
class Drive:
    """What the files hold, exactly: truth at the IMU samples and the fix epochs."""

    toml: Path
    t_s: np.ndarray          # (n+1,) truth sample times, s from the start
    x_true: np.ndarray       # (n+1, NX)
    fix_t_s: np.ndarray      # (m,) fix tags, s from the start
    config: DriveConfig


def _scenario(cfg: DriveConfig):
    from leonav_runtime.scenarios.load import scenario_from_dict

    return scenario_from_dict({
        "name": "synthetic-drive",
        "site": {"lat_deg": cfg.lat_deg, "lon_deg": cfg.lon_deg, "alt_m": cfg.h_m},
        "time": {"epoch": "2023-11-14T22:13:20Z", "duration_s": cfg.seconds},
        "trajectory": {"kind": "maneuvers", "attitude_deg": [0.0, 0.0, cfg.yaw_deg], "speed_mps": cfg.speed_mps,
                       "maneuvers": [list(m) for m in cfg.maneuvers]},
        "imu": {"profile": cfg.imu_profile, "rate_hz": cfg.imu_rate_hz},
    }, source="<synthetic drive>")


def _llh(p_enu_m: np.ndarray, cfg: DriveConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lat0, lon0 = math.radians(cfg.lat_deg), math.radians(cfg.lon_deg)
    r = geometry.enu_to_ecef(p_enu_m, geometry.geodetic_to_ecef(lat0, lon0, cfg.h_m), lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r)
    return np.degrees(lat), np.degrees(lon), np.asarray(h)


def _interp_rows(t: np.ndarray, t_grid: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, t_grid, values[:, j]) for j in range(values.shape[1])])


def write_drive(folder: str | Path, cfg: DriveConfig | None = None) -> Drive:
    """Write the drive's files and description into `folder` (created); returns the truth."""
    from leonav_runtime.core.params import build_params
    from leonav_runtime.gen.profiles import IMU_PROFILES
    from leonav_runtime.simulation import sensor_errors, simulate

    cfg = cfg or DriveConfig()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    scn = _scenario(cfg)
    profile = IMU_PROFILES[cfg.imu_profile]
    nav = navfuncs.NavFunctions()
    nav.params = np.array(build_params(scn.lat_rad, scn.lon_rad, scn.alt_m, imu=profile))
    t, x_true, u_true = simulate.truth(scn, nav.params, nav)
    L = nav.layout
    rng = np.random.default_rng(cfg.seed)
    n, dt = u_true.shape[0], 1.0 / cfg.imu_rate_hz
    b_a, b_g = sensor_errors.bias_walks(rng, profile, n, dt, nav=nav)
    x_true = x_true.copy()
    x_true[:, L.X_B_A_SLICE], x_true[:, L.X_B_G_SLICE] = b_a, b_g
    u = sensor_errors.measured_increments(rng, profile, u_true, b_a, b_g, dt)
    w_b, f_b = u[:, L.U_DTHETA_B_SLICE] / dt, u[:, L.U_DVEL_B_SLICE] / dt
    # an interval's mean rate is the instantaneous rate at its midpoint (to second order): a rate
    # sensor's sample, which the loader integrates by the trapezoid between samples
    imu_rows = np.column_stack([EPOCH_UNIX_S + t[1:] - dt / 2, w_b, f_b])
    np.savetxt(folder / "imu.csv", imu_rows, delimiter=",", fmt="%.6f,%.9e,%.9e,%.9e,%.9e,%.9e,%.9e",
               header="t_unix_s,wx_radps,wy_radps,wz_radps,fx_mps2,fy_mps2,fz_mps2", comments="")

    # fixes: the antenna (at the IMU point) latency seconds before each tag, plus white noise
    step = 1.0 / cfg.gnss_rate_hz
    fix_t = np.arange(cfg.fix_latency_s + step, cfg.seconds, step)
    p_true = _interp_rows(fix_t - cfg.fix_latency_s, t, x_true[:, L.X_P_ENU_SLICE])
    v_true = _interp_rows(fix_t - cfg.fix_latency_s, t, x_true[:, L.X_V_ENU_SLICE])
    p = p_true + np.asarray(cfg.fix_sigma_m) * rng.standard_normal(p_true.shape)
    v = v_true + np.asarray(cfg.velocity_sigma_mps) * rng.standard_normal(v_true.shape)
    lat, lon, h = _llh(p, cfg)
    np.savetxt(folder / "fixes.csv", np.column_stack([EPOCH_UNIX_S + fix_t, lat, lon, h, v]), delimiter=",",
               fmt="%.6f,%.10f,%.10f,%.4f,%.4f,%.4f,%.4f", header="t_unix_s,lat_deg,lon_deg,h_m,ve_mps,vn_mps,vu_mps",
               comments="")

    k = np.arange(0, t.size, max(1, int(round(cfg.imu_rate_hz / 10))))   # reference at 10 Hz
    lat, lon, h = _llh(x_true[k, L.X_P_ENU_SLICE], cfg)
    q = x_true[k, L.X_Q_NB_SLICE]            # [w x y z] body FLU -> ENU
    np.savetxt(folder / "reference.csv", np.column_stack([EPOCH_UNIX_S + t[k], lat, lon, h, q[:, 1:], q[:, :1]]),
               delimiter=",", fmt="%.6f,%.10f,%.10f,%.4f,%.9f,%.9f,%.9f,%.9f",
               header="t_unix_s,lat_deg,lon_deg,h_m,qx,qy,qz,qw", comments="")

    offset = '"estimate"' if cfg.time_offset == "estimate" else f"{float(cfg.time_offset):g}"
    modes = ", ".join(f'"{m}"' for m in cfg.modes)
    sig = ", ".join(f"{s:g}" for s in cfg.fix_sigma_m)
    vsig = ", ".join(f"{s:g}" for s in cfg.velocity_sigma_mps)
    (folder / "drive.toml").write_text(f'''# A synthetic drive (leonav_runtime/dataset/synthetic.py): {cfg.seconds:g} s, {cfg.speed_mps:g} m/s at the
# start, turns and speed changes; {cfg.imu_profile} IMU at {cfg.imu_rate_hz:g} Hz; fixes at {cfg.gnss_rate_hz:g} Hz
# tagged {cfg.fix_latency_s:g} s late.
name = "synthetic_drive"
description = "synthetic drive, fix latency {cfg.fix_latency_s:g} s"

[imu]
file = "imu.csv"
time_column = "t_unix_s"
gyro_columns = ["wx_radps", "wy_radps", "wz_radps"]
accel_columns = ["fx_mps2", "fy_mps2", "fz_mps2"]
frame = "FLU"
time_base = "unix"

[gnss]
file = "fixes.csv"
time_column = "t_unix_s"
lat_column = "lat_deg"
lon_column = "lon_deg"
height_column = "h_m"
sigma_m = [{sig}]
velocity_columns = ["ve_mps", "vn_mps", "vu_mps"]
velocity_sigma_mps = [{vsig}]
time_offset_s = {offset}

[reference]
file = "reference.csv"
time_column = "t_unix_s"
position_columns = ["lat_deg", "lon_deg", "h_m"]
quaternion_columns = ["qx", "qy", "qz", "qw"]

[filter]
modes = [{modes}]
imu_noise = "{cfg.imu_profile}"
bias_profile = "{cfg.imu_profile}"
''')
    return Drive(folder / "drive.toml", t, x_true, fix_t, cfg)
