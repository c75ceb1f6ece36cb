"""A dataset description -> IMU samples, GNSS fixes and a reference on one time axis.

Time axis: seconds since the first usable GNSS fix (`Dataset.t0_unix`, unix s). ENU origin:
that fix (lat, lon rad; h m). IMU samples are rotated from the sensor axes to the vehicle
frame (`[imu] axes`, `frame`) and then to body FLU, the filter's body frame; converted to
rad/s and m/s^2. Rows that are short, not finite, clipped, repeated or out of time order
are counted (`Dataset.counts`) and skipped.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.dataset import checks, readers
from leonav_runtime.dataset.spec import ACCEL_UNITS, GYRO_UNITS, TIME_UNITS, DatasetSpec
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
class Dataset:
    spec: DatasetSpec
    t0_unix: float
    origin: tuple[float, float, float]
    imu_raw_t: np.ndarray           # IMU time stamps as in the file, converted to s (before the offset)
    imu: ImuSamples
    fixes: FixTable
    reference: Reference | None
    counts: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    local_raw: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)   # sensor -> (t as in file, z)

    def _axis(self, offset_s: float) -> float:
        return (0.0 if self.spec["imu"]["time_base"] == "first_fix" else -self.t0_unix) + offset_s

    def imu_on_axis(self, offset_s: float) -> ImuSamples:
        """The IMU samples with time offset `offset_s` (s) applied on the run axis."""
        return ImuSamples(self.imu_raw_t + self._axis(offset_s), self.imu.w_b_radps, self.imu.f_b_mps2)

    def local_on_axis(self, offset_s: float) -> list[LocalSensorTable]:
        """Each local sensor's samples on the run axis (its times share the IMU's base and offset)."""
        return [LocalSensorTable(token, t + self._axis(offset_s), z, self.spec[token]["sigma_si"])
                for token, (t, z) in self.local_raw.items()]


def _vehicle_flu(raw: np.ndarray, axis_map, frame: str) -> np.ndarray:
    """Sensor columns (n, 3) -> vehicle frame by the axis map -> body FLU."""
    out = np.column_stack([sign * raw[:, axis] for axis, sign in axis_map])
    if frame == "FRD":
        out[:, 1:] *= -1.0
    return out


def read_imu(spec: DatasetSpec, counts: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t s as in the file, w rad/s FLU, f m/s^2 FLU) of the good IMU rows."""
    s = spec["imu"]
    path = readers.resolve(spec.data_dir / s["file"], "IMU", spec.where("imu", "file"), spec.shared)
    cols = ([("time_column", s["time_column"])] + [("gyro_columns", c) for c in s["gyro_columns"]]
            + [("accel_columns", c) for c in s["accel_columns"]])
    if s["format"] == "mat":
        data = readers.read_mat_columns(path, s["mat_struct"], [("time_column", s["time_column"])]
                                        + [("gyro_columns", c) for c in s["gyro_columns"]]
                                        + [("accel_columns", c) for c in s["accel_columns"]])
    else:
        data = readers.read_columns(path, cols, s["delimiter"])
    if data.values.shape[1] != 7:
        raise UserInputError(f"{path}: expected a time column and 3 + 3 gyro/accel columns, got "
                             f"{data.values.shape[1]} columns")
    v = data.values
    t = v[:, 0] * TIME_UNITS[s["time_unit"]]
    w = v[:, 1:4] * GYRO_UNITS[s["gyro_unit"]]
    f = v[:, 4:7] * ACCEL_UNITS[s["accel_unit"]]
    clipped = np.zeros(t.size, bool)
    if s["accel_range_mps2"] > 0:
        clipped |= (np.abs(f) >= 0.999 * s["accel_range_mps2"]).any(axis=1)
    if s["gyro_range_radps"] > 0:
        clipped |= (np.abs(w) >= 0.999 * s["gyro_range_radps"]).any(axis=1)
    keep, order = readers.monotonic_rows(np.where(clipped, np.nan, t))
    keep &= ~clipped
    counts["imu"] = data.counts | order | {"rows_clipped": int(clipped.sum()), "rows_used": int(keep.sum())}
    if keep.sum() < 2:
        raise UserInputError(f"{path}: fewer than 2 usable IMU rows: expected samples with increasing time")
    t, w, f = t[keep], w[keep], f[keep]
    checks.imu_units(spec, t, w, f, path)
    dt = np.diff(t)
    med = float(np.median(dt))
    gaps = dt > 2.5 * med
    counts["imu"] |= {"rate_hz": 1.0 / med, "gaps": int(gaps.sum()), "gap_seconds": float(dt[gaps].sum())}
    return t, _vehicle_flu(w, s["axis_map"], s["frame"]), _vehicle_flu(f, s["axis_map"], s["frame"])


def _enu(lat_rad, lon_rad, h_m, origin) -> np.ndarray:
    r0 = geometry.geodetic_to_ecef(*origin)
    return geometry.ecef_to_enu(geometry.geodetic_to_ecef(lat_rad, lon_rad, h_m), r0, origin[0], origin[1])


def read_fixes(spec: DatasetSpec, counts: dict, notes: list[str]):
    """(t unix s, lat rad, lon rad, h m, sigma (n, 3) m E N U or None) of the good fixes."""
    g = spec["gnss"]
    path = readers.resolve(spec.data_dir / g["file"], "GNSS", spec.where("gnss", "file"), spec.shared)
    if g["format"] in ("nmea", "ubx"):
        return _decoded_fixes(path, counts, notes)
    cols = [("time_column", g["time_column"]), ("lat_column", g["lat_column"]), ("lon_column", g["lon_column"]),
            ("height_column", g["height_column"])] + [("sigma_columns", c) for c in g["sigma_columns"]]
    data = readers.read_columns(path, cols, g["delimiter"])
    v = data.values
    t = v[:, 0] * TIME_UNITS[g["time_unit"]]
    bad = (np.abs(v[:, 1]) > 90) | (np.abs(v[:, 2]) > 360)
    if g["sigma_columns"]:
        bad |= (v[:, 4:7] <= 0).any(axis=1)
    keep, order = readers.monotonic_rows(np.where(bad, np.nan, t))
    keep &= ~bad
    counts["gnss"] = data.counts | order | {"rows_out_of_range": int(bad.sum()), "rows_used": int(keep.sum())}
    if not keep.any():
        raise UserInputError(f"{path}: no usable fix: expected latitude in [-90, 90] deg and longitude in deg")
    dt = np.diff(t[keep])
    if dt.size:
        gaps = dt > 5 * np.median(dt)
        counts["gnss"] |= {"gaps": int(gaps.sum()), "gap_seconds": float(dt[gaps].sum())}
    v = v[keep]
    sigma = v[:, 4:7] if g["sigma_columns"] else None
    h = v[:, 3] + (g["geoid_separation_m"] if g["height_datum"] == "msl" else 0.0)   # WGS84 ellipsoidal
    return t[keep], np.radians(v[:, 1]), np.radians(v[:, 2]), h, sigma


def _decoded_fixes(path, counts: dict, notes: list[str]):
    """Fixes of an NMEA or UBX log through the device layer's decoder (GGA + RMC date, NAV-PVT);
    per-fix sigma as a recorded session's replay takes it (GST, NAV-PVT accuracy, else HDOP)."""
    from leonav.hardware.gnss.reader import GnssDecoder
    from leonav.hardware.records import GnssFix
    from leonav_runtime.replay.gnss_table import fix_height_m, fix_table, usable_fix

    dec = GnssDecoder()
    recs = dec.decode(path.read_bytes(), 0.0) + dec.close()
    all_fixes = [r for r in recs if isinstance(r, GnssFix)]
    fixes = [f for f in all_fixes if usable_fix(f) and f.utc is not None]
    if not fixes:
        raise UserInputError(f"{path}: no GNSS fix with a position and a date (GGA + RMC, or NAV-PVT) in the log")
    t = np.array([f.utc.timestamp() for f in fixes])
    keep, order = readers.monotonic_rows(t)
    fixes = [f for f, k in zip(fixes, keep) if k]
    origin = (fixes[0].lat_rad, fixes[0].lon_rad, fix_height_m(fixes[0]))
    table, fc = fix_table([r for r in recs if not isinstance(r, GnssFix)] + fixes, None, 0.0, origin, notes)
    counts["gnss"] = order | {"rows_used": len(fixes), "rows_without_date_or_position": len(all_fixes) - int(
        keep.size), "decoder_rejected": dict(dec.rejected), "fix_sigma_source": fc["fix_sigma_source"]}
    notes.append(f"GNSS: {len(fixes)} fixes decoded from {path.name}")
    return (t[keep], np.array([f.lat_rad for f in fixes]), np.array([f.lon_rad for f in fixes]),
            np.array([fix_height_m(f) for f in fixes]), table.sigma_enu_m)


def read_reference(spec: DatasetSpec, t0_unix: float, origin, counts: dict) -> Reference | None:
    """The reference trajectory on the run axis and frame, or None when the file is not set."""
    r = spec["reference"]
    if not r["file"]:
        return None
    path = readers.resolve(spec.data_dir / r["file"], "reference", spec.where("reference", "file"), spec.shared)
    return reference_from_file(path, r, t0_unix, origin, counts, spec["gnss"]["geoid_separation_m"])


def reference_from_file(path, r: dict, t0_unix: float, origin, counts: dict, geoid_m: float = 0.0) -> Reference:
    """Reference from a CSV (columns and CRS of the `[reference]` options `r`) or an RTKLIB .pos (ellipsoidal
    heights); `r["height_datum"]` "msl" adds the geoid height geoid_m (m) to CSV heights."""
    yaw = None
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
        cols = [("time_column", r["time_column"])] + [("position_columns", c) for c in r["position_columns"]]
        cols += [("quaternion_columns", c) for c in r["quaternion_columns"]]
        data = readers.read_columns(path, cols, r["delimiter"])
        v = data.values
        t = v[:, 0] * TIME_UNITS[r["time_unit"]]
        lat, lon, h, conv = _to_geodetic(v[:, 1:4], r["crs"], path)
        if r.get("height_datum") == "msl":
            h = h + geoid_m
        if r["quaternion_columns"]:
            qx, qy, qz, qw = v[:, 4].copy(), v[:, 5], v[:, 6], v[:, 7]
            yaw = np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy**2 + qz**2)) + conv
        n_bad = data.counts["rows_nan"] + data.counts["rows_short"]
    keep, order = readers.monotonic_rows(t)
    counts["reference"] = order | {"rows_bad": n_bad, "rows_used": int(keep.sum())}
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


def read_local(spec: DatasetSpec, token: str, counts: dict) -> tuple[np.ndarray, np.ndarray]:
    """(t s as in the file, z (n, k) in the observables' units) of a local sensor's good rows."""
    s = spec[token]
    path = readers.resolve(spec.data_dir / s["file"], token, spec.where(token, "file"), spec.shared)
    data = readers.read_columns(path, [("time_column", s["time_column"])] + [("columns", c) for c in s["columns"]],
                                s["delimiter"])
    t = data.values[:, 0] * TIME_UNITS[s["time_unit"]]
    keep, order = readers.monotonic_rows(t)
    counts[token] = data.counts | order | {"rows_used": int(keep.sum())}
    if not keep.any():
        raise UserInputError(f"{path}: no usable {token} row: expected samples with increasing time")
    return t[keep], data.values[keep, 1:]


def load(spec: DatasetSpec) -> Dataset:
    """Read every file the description names (module doc)."""
    counts: dict = {}
    notes: list[str] = []
    t_fix, lat, lon, h, sig = read_fixes(spec, counts, notes)
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
    t_imu, w, f = read_imu(spec, counts)
    ref = read_reference(spec, t0, origin, counts)
    local = {token: read_local(spec, token, counts) for token in model.LOCAL_SENSORS if spec[token]["file"]}
    return Dataset(spec, t0, origin, t_imu, ImuSamples(t_imu, w, f), fixes, ref, counts, notes, local)
