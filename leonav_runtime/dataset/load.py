"""A dataset description -> IMU samples, GNSS fixes (and velocity) and a reference on one time axis.

Time axis: seconds since the first usable GNSS fix (`Dataset.t0_unix`, unix s). ENU origin:
that fix (lat, lon rad; h m). Every time column is first put in its section's time base
(`timebase`: unix, GPS week + time of week, GPS seconds; the IMU also first_fix or a boot
clock). IMU samples (`imu_read`: one file, or gyro and accelerometer files) are rotated from
the sensor axes to the vehicle frame (`[imu] axes`, `frame`) and then to body FLU, the
filter's body frame; converted to rad/s and m/s^2. The reference's attitude becomes the yaw
of body x from East towards North (`attitude`). Rows that are short, not finite, clipped,
repeated, out of time order or with a bad quaternion are counted (`Dataset.counts`) and
skipped. Physics checks (`checks`): IMU units, a boot clock that misses the fixes, the gyro
unit against the GNSS course.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.dataset import attitude, checks, readers, timebase
from leonav_runtime.dataset.gnss_read import read_fixes
from leonav_runtime.dataset.imu_read import read_imu
from leonav_runtime.dataset.spec import TIME_UNITS, DatasetSpec
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.inputs import FixTable, LocalSensorTable


@dataclass
class ImuSamples:
    """IMU samples on the run axis: t (n,) s; w_b_radps, f_b_mps2 (n, 3) body FLU (vehicle)."""

    t: np.ndarray
    w_b_radps: np.ndarray
    f_b_mps2: np.ndarray


@dataclass
class Reference:
    """Reference trajectory on the run axis: t (n,) s, p_enu_m (n, 3) at the run's origin,
    yaw_rad (n,) from East towards North (true, unwrapped) or None."""

    t: np.ndarray
    p_enu_m: np.ndarray
    yaw_rad: np.ndarray | None
    source: str = ""


@dataclass
class GnssVelocity:
    """GNSS velocity on the fixes' axis: t (n,) s, v_enu_mps (n, 3) at the run's ENU axes,
    sigma_mps (n, 3) 1-sigma E N U."""

    t: np.ndarray
    v_enu_mps: np.ndarray
    sigma_mps: np.ndarray


@dataclass
class Dataset:
    spec: DatasetSpec
    t0_unix: float
    origin: tuple[float, float, float]
    imu_raw_t: np.ndarray           # IMU times in s of its time base (unix, first_fix or boot s), before the offset
    imu: ImuSamples
    fixes: FixTable
    reference: Reference | None
    counts: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    local_raw: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)   # sensor -> (t IMU base, z)
    velocity: GnssVelocity | None = None    # GNSS velocity, if the fix file or log has one

    def _axis(self, offset_s: float) -> float:
        return (0.0 if self.spec["imu"]["time_base"] == "first_fix" else -self.t0_unix) + offset_s

    def imu_on_axis(self, offset_s: float) -> ImuSamples:
        """The IMU samples with time offset `offset_s` (s) applied on the run axis."""
        return ImuSamples(self.imu_raw_t + self._axis(offset_s), self.imu.w_b_radps, self.imu.f_b_mps2)

    def local_on_axis(self, offset_s: float) -> list[LocalSensorTable]:
        """Each local sensor's samples on the run axis (its times share the IMU's base and offset)."""
        return [LocalSensorTable(token, t + self._axis(offset_s), z, self.spec[token]["sigma_si"])
                for token, (t, z) in self.local_raw.items()]


def _enu(lat_rad, lon_rad, h_m, origin) -> np.ndarray:
    r0 = geometry.geodetic_to_ecef(*origin)
    return geometry.ecef_to_enu(geometry.geodetic_to_ecef(lat_rad, lon_rad, h_m), r0, origin[0], origin[1])


def read_reference(spec: DatasetSpec, t0_unix: float, origin, counts: dict) -> Reference | None:
    """The reference trajectory on the run axis and frame, or None when the file is not set."""
    r = spec["reference"]
    if not r["file"]:
        return None
    path = readers.resolve(spec.data_dir / r["file"], "reference", spec.where("reference", "file"), spec.shared)
    return reference_from_file(path, r, t0_unix, origin, counts, spec["gnss"]["geoid_separation_m"])


def reference_from_file(path, r: dict, t0_unix: float, origin, counts: dict, geoid_m: float = 0.0) -> Reference:
    """Reference from a CSV or npy/npz (columns, CRS, time base and attitude of the `[reference]`
    options `r`; keys it lacks take the SCHEMA defaults) or an RTKLIB .pos (ellipsoidal heights);
    `r["height_datum"]` "msl" adds the geoid height geoid_m (m) to CSV heights. Rows whose
    quaternion is not of unit norm are counted (`rows_bad_quaternion`) and skipped."""
    yaw = None
    n_quat = 0
    if r["format"] == "pos" or str(path).endswith(".pos"):
        from leonav_runtime.gnss import solution_io
        from leonav_runtime.gnss import time as gtime

        rows = solution_io.read_pos(path)
        if not rows:
            raise UserInputError(f"{path}: no solution line in the .pos file")
        t = np.array([gtime.gps_seconds_to_utc(p.t_gps_s).timestamp() for p in rows])
        lat = np.radians([p.lat_deg for p in rows])
        lon = np.radians([p.lon_deg for p in rows])
        h = np.array([p.height_m for p in rows])
        n_bad = 0
    else:
        wk = timebase.week_key(r)
        att_key = "euler_columns" if r.get("attitude") == "euler_deg" else "quaternion_columns"
        att_cols = r.get(att_key, [])
        cols = [("time_column", r["time_column"])] + wk + [("position_columns", c) for c in r["position_columns"]]
        cols += [(att_key, c) for c in att_cols]
        data = readers.read_source(path, r, cols)
        v = data.values
        t, n_tow = timebase.to_base(v[:, 0] * TIME_UNITS[r["time_unit"]], r, v[:, 1] if wk else None,
                                    f"{path}: [reference] time_base")
        v = v[:, len(wk):]
        lat, lon, h, conv = _to_geodetic(v[:, 1:4], r["crs"], path)
        if r.get("height_datum") == "msl":
            h = h + geoid_m
        if att_cols:
            yaw, bad_q = attitude.reference_yaw(v[:, 4:], r.get("attitude", "quat_enu"),
                                                r.get("quaternion_order", "xyzw"), lat, lon, conv)
            n_quat = int(bad_q.sum())
            t = np.where(bad_q, np.nan, t)       # not scored: neither yaw nor position of that row
        n_bad = data.counts["rows_nan"] + data.counts["rows_short"] + n_tow
    keep, order = readers.monotonic_rows(t)
    counts["reference"] = order | {"rows_bad": n_bad, "rows_used": int(keep.sum())}
    if n_quat:
        counts["reference"]["rows_bad_quaternion"] = n_quat
    if not keep.any():
        raise UserInputError(f"{path}: no usable reference row ({n_quat} with a quaternion of norm not 1, {n_bad} bad)")
    p = _enu(lat[keep], lon[keep], h[keep], origin)
    return Reference(t[keep] - t0_unix, np.atleast_2d(p), None if yaw is None else np.unwrap(yaw[keep]), str(path))


def _to_geodetic(xyz: np.ndarray, crs: str, path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(lat rad, lon rad, h m, grid convergence rad: true yaw = grid yaw + it) of reference rows."""
    if crs == "llh":
        return np.radians(xyz[:, 0]), np.radians(xyz[:, 1]), xyz[:, 2], np.zeros(len(xyz))
    if crs == "ecef":
        lat, lon, h = geometry.ecef_to_geodetic(xyz)
        return np.asarray(lat), np.asarray(lon), np.asarray(h), np.zeros(len(xyz))
    try:
        from pyproj import Transformer
        from pyproj.exceptions import CRSError
    except ImportError:   # pragma: no cover - pyproj is a dependency
        raise UserInputError(f"{path}: crs {crs}: needs pyproj (pip install pyproj)") from None
    try:
        to_ll = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
        to_grid = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    except CRSError as exc:
        raise UserInputError(f"{path}: crs {crs}: not a coordinate system pyproj knows ({exc})") from None
    lon, lat = to_ll.transform(xyz[:, 0], xyz[:, 1])
    # grid azimuth of true north: a step north in latitude, seen in the grid
    e1, n1 = to_grid.transform(lon, lat + 1e-4)
    conv = np.arctan2(np.asarray(e1) - xyz[:, 0], np.asarray(n1) - xyz[:, 1])
    return np.radians(lat), np.radians(lon), xyz[:, 2], conv


def read_local(spec: DatasetSpec, token: str, counts: dict, imu_week: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(t s in the IMU's time base, z (n, k) in the observables' units) of a local sensor's good rows;
    with gps_week_tow the week is [imu] gps_week, else the IMU file's first week (`imu_week`)."""
    s = spec[token]
    path = readers.resolve(spec.data_dir / s["file"], token, spec.where(token, "file"), spec.shared)
    data = readers.read_columns(path, [("time_column", s["time_column"])] + [("columns", c) for c in s["columns"]],
                                s["delimiter"])
    imu = dict(spec["imu"], gps_week=spec["imu"]["gps_week"] or imu_week)
    t, _ = timebase.to_base(data.values[:, 0] * TIME_UNITS[s["time_unit"]], imu, None,
                            spec.where("imu", "time_base") + f" (of [{token}])")
    keep, order = readers.monotonic_rows(t)
    counts[token] = data.counts | order | {"rows_used": int(keep.sum())}
    if not keep.any():
        raise UserInputError(f"{path}: no usable {token} row: expected samples with increasing time")
    return t[keep], data.values[keep, 1:]


def load(spec: DatasetSpec) -> Dataset:
    """Read every file the description names (module doc)."""
    counts: dict = {}
    notes: list[str] = []
    vel: dict = {}
    t_fix, lat, lon, h, sig = read_fixes(spec, counts, notes, vel)
    t0 = float(t_fix[0])
    origin = (float(lat[0]), float(lon[0]), float(h[0]))
    g = spec["gnss"]
    p = np.atleast_2d(_enu(lat, lon, h, origin))
    if sig is None:
        sig = np.tile(g["sigma_m"], (t_fix.size, 1))
        counts["gnss"]["sigma_source"] = f"[gnss] sigma_m {g['sigma_m']}"
    else:
        counts["gnss"]["sigma_source"] = counts["gnss"].pop("fix_sigma_source", "per-fix sigma columns")
    fixes = FixTable(t_fix - t0, p, np.asarray(sig, float), np.full((t_fix.size, 2), np.nan))
    velocity = GnssVelocity(vel["t"] - t0, vel["v_enu_mps"], vel["sigma_mps"]) if vel else None
    t_imu, w, f = read_imu(spec, counts)
    ds = Dataset(spec, t0, origin, t_imu, ImuSamples(t_imu, w, f), fixes, None, counts, notes, velocity=velocity)
    _check_imu_on_fixes(ds)
    ds.reference = read_reference(spec, t0, origin, counts)
    week = int(np.floor(timebase.gps_week_of_unix(t_imu[0]))) if spec["imu"]["time_base"] == "gps_week_tow" else 0
    ds.local_raw = {token: read_local(spec, token, counts, week) for token in model.LOCAL_SENSORS
                    if spec[token]["file"]}
    return ds


def _check_imu_on_fixes(ds: Dataset) -> None:
    """A boot clock mapped past the fixes is one line naming its key; the gyro unit against the
    GNSS course (or the Earth rate at rest) once the IMU is on the fixes' axis (`checks`)."""
    s = ds.spec["imu"]
    offset = 0.0 if isinstance(s["time_offset_s"], str) else float(s["time_offset_s"])
    imu = ds.imu_on_axis(offset)
    if s["time_base"] == "boot":
        key = "clock_pair" if s["clock_pair"] else "time_offset_s"
        checks.clock_mapping(ds.spec, key, imu.t + ds.t0_unix, ds.fixes.t + ds.t0_unix)
    checks.gyro_unit(ds.spec, imu, ds.fixes, ds.counts)
