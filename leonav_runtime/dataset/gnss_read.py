"""GNSS fixes and GNSS velocity of a dataset description, in unix time (UTC).

- CSV / npy / npz (`[gnss] format`): the time column in `time_base` (`timebase.to_base`),
  lat/lon (deg), height (m; msl + geoid_separation_m when height_datum = "msl"), optional
  per-fix sigma columns (m). Rows with an impossible latitude/longitude or sigma <= 0 are
  counted (`rows_out_of_range`) and skipped.
- Velocity: `velocity_columns` (E N U, m/s) and `velocity_sigma_columns` (m/s) or the constant
  `velocity_sigma_mps`, read on their own (a fix without a velocity keeps its position);
  counted in `counts["gnss_velocity"]`.
- NMEA / UBX logs through the device layer's decoder: NAV-PVT velN/velE/velD with sAcc as the
  1-sigma of each axis; else RMC speed over ground and course, horizontal only: Up is 0 with
  RMC_UP_SIGMA_MPS (large: the filter learns nothing vertical from it) and E, N take
  `velocity_sigma_mps` (RMC has no accuracy). Said in the notes.
"""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.dataset import readers, timebase
from leonav_runtime.dataset.spec import TIME_UNITS, DatasetSpec

KNOT_MPS = 1852.0 / 3600.0
RMC_UP_SIGMA_MPS = 10.0
"""Up 1-sigma (m/s) of a velocity from RMC, which has no vertical speed."""


def _times(spec: DatasetSpec, v: np.ndarray, week: bool) -> tuple[np.ndarray, int]:
    g = spec["gnss"]
    return timebase.to_base(v[:, 0] * TIME_UNITS[g["time_unit"]], g, v[:, 1] if week else None,
                            spec.where("gnss", "time_base"))


def read_fixes(spec: DatasetSpec, counts: dict, notes: list[str], velocity: dict | None = None):
    """(t unix s, lat rad, lon rad, h m, sigma (n, 3) m E N U or None) of the good fixes;
    `velocity` (if given) receives t unix s, v_enu_mps (n, 3), sigma_mps (n, 3) when the file
    or log has a velocity (module doc)."""
    g = spec["gnss"]
    path = readers.resolve(spec.data_dir / g["file"], "GNSS", spec.where("gnss", "file"), spec.shared)
    if g["format"] in ("nmea", "ubx"):
        return _decoded_fixes(path, counts, notes, g, velocity)
    wk = timebase.week_key(g)
    cols = [("time_column", g["time_column"])] + wk + [
        ("lat_column", g["lat_column"]), ("lon_column", g["lon_column"]),
        ("height_column", g["height_column"])] + [("sigma_columns", c) for c in g["sigma_columns"]]
    data = readers.read_source(path, g, cols)
    t, n_tow = _times(spec, data.values, bool(wk))
    v = data.values[:, len(wk):]
    bad = (np.abs(v[:, 1]) > 90) | (np.abs(v[:, 2]) > 360)
    if g["sigma_columns"]:
        bad |= (v[:, 4:7] <= 0).any(axis=1)
    keep, order = readers.monotonic_rows(np.where(bad, np.nan, t))
    keep &= ~bad
    counts["gnss"] = data.counts | order | {"rows_out_of_range": int(bad.sum()), "rows_used": int(keep.sum())}
    if n_tow:
        counts["gnss"]["rows_bad_time_of_week"] = n_tow
    if not keep.any():
        raise UserInputError(f"{path}: no usable fix: expected latitude in [-90, 90] deg and longitude in deg")
    dt = np.diff(t[keep])
    if dt.size:
        gaps = dt > 5 * np.median(dt)
        counts["gnss"] |= {"gaps": int(gaps.sum()), "gap_seconds": float(dt[gaps].sum())}
    v = v[keep]
    sigma = v[:, 4:7] if g["sigma_columns"] else None
    h = v[:, 3] + (g["geoid_separation_m"] if g["height_datum"] == "msl" else 0.0)   # WGS84 ellipsoidal
    if velocity is not None and g["velocity_columns"]:
        velocity.update(_velocity_columns(spec, path, counts))
    return t[keep], np.radians(v[:, 1]), np.radians(v[:, 2]), h, sigma


def _velocity_columns(spec: DatasetSpec, path, counts: dict) -> dict:
    """The velocity columns of the fix file (module doc)."""
    g = spec["gnss"]
    wk = timebase.week_key(g)
    cols = ([("time_column", g["time_column"])] + wk + [("velocity_columns", c) for c in g["velocity_columns"]]
            + [("velocity_sigma_columns", c) for c in g["velocity_sigma_columns"]])
    data = readers.read_source(path, g, cols)
    t, _ = _times(spec, data.values, bool(wk))
    v = data.values[:, 1 + len(wk):]
    bad = (v[:, 3:6] <= 0).any(axis=1) if g["velocity_sigma_columns"] else np.zeros(t.size, bool)
    keep, order = readers.monotonic_rows(np.where(bad, np.nan, t))
    keep &= ~bad
    counts["gnss_velocity"] = data.counts | order | {"rows_bad_sigma": int(bad.sum()), "rows_used": int(keep.sum()),
                                                     "sigma_source": "velocity_sigma_columns" if
                                                     g["velocity_sigma_columns"] else "velocity_sigma_mps"}
    sigma = v[keep, 3:6] if g["velocity_sigma_columns"] else np.tile(g["velocity_sigma_mps"], (int(keep.sum()), 1))
    return {"t": t[keep], "v_enu_mps": v[keep, :3], "sigma_mps": np.asarray(sigma, float)}


def _rmc_velocity(rec) -> tuple[int, tuple[float, float]] | None:
    """(time-of-day key ms, (v_E, v_N) m/s) of a valid RMC sentence with a speed, else None."""
    msg = getattr(rec, "msg", None)
    if getattr(rec, "sentence_type", "") != "RMC" or msg is None or getattr(msg, "status", "") != "A":
        return None
    try:
        speed = float(msg.spd_over_grnd) * KNOT_MPS
        course = float(msg.true_course) if msg.true_course not in (None, "") else (0.0 if speed == 0 else math.nan)
        tod = msg.timestamp
        key = ((tod.hour * 60 + tod.minute) * 60 + tod.second) * 1000 + round(tod.microsecond / 1000)
    except (TypeError, ValueError, AttributeError):
        return None
    if not (math.isfinite(speed) and math.isfinite(course)):
        return None
    c = math.radians(course)            # clockwise from North
    return key, (speed * math.sin(c), speed * math.cos(c))


def _decoded_velocity(recs: list, fixes: list, g: dict, notes: list[str]) -> dict:
    """Velocity of each decoded fix that has one (module doc)."""
    from leonav.hardware.records import GnssFix, NavPvt

    s_acc, rmc, last_pvt = {}, {}, None
    for r in recs:
        if isinstance(r, NavPvt):
            last_pvt = r
        elif isinstance(r, GnssFix) and r.source == "NAV-PVT" and last_pvt is not None:
            s_acc[id(r)] = last_pvt.s_acc_mps
        else:
            got = _rmc_velocity(r)
            if got is not None:
                rmc[got[0]] = got[1]
    t, v, sig, n_pvt, n_rmc = [], [], [], 0, 0
    for f in fixes:
        tod = f.utc
        key = ((tod.hour * 60 + tod.minute) * 60 + tod.second) * 1000 + round(tod.microsecond / 1000)
        if f.vel_ned_mps is not None and s_acc.get(id(f), 0) > 0:
            n, e, d = f.vel_ned_mps
            t.append(f.utc.timestamp()), v.append((e, n, -d)), sig.append((s_acc[id(f)],) * 3)
            n_pvt += 1
        elif key in rmc:
            t.append(f.utc.timestamp()), v.append((*rmc[key], 0.0))
            sig.append((g["velocity_sigma_mps"][0], g["velocity_sigma_mps"][1], RMC_UP_SIGMA_MPS))
            n_rmc += 1
    if n_rmc:
        notes.append(f"GNSS velocity: {n_rmc} from RMC speed and course (horizontal only: Up 0 with sigma "
                     f"{RMC_UP_SIGMA_MPS:g} m/s; E, N sigma from [gnss] velocity_sigma_mps)")
    if n_pvt:
        notes.append(f"GNSS velocity: {n_pvt} from NAV-PVT velN/velE/velD (sigma sAcc)")
    if not t:
        return {}
    return {"t": np.array(t), "v_enu_mps": np.array(v, float), "sigma_mps": np.array(sig, float),
            "counts": {"rows_used": len(t), "from_nav_pvt": n_pvt, "from_rmc": n_rmc}}


def _decoded_fixes(path, counts: dict, notes: list[str], g: dict, velocity: dict | None = None):
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
    if velocity is not None:
        vel = _decoded_velocity(recs, fixes, g, notes)
        if vel:
            counts["gnss_velocity"] = vel.pop("counts")
            velocity.update(vel)
    return (t[keep], np.array([f.lat_rad for f in fixes]), np.array([f.lon_rad for f in fixes]),
            np.array([fix_height_m(f) for f in fixes]), table.sigma_enu_m)
