"""GNSS fixes of a recorded session -> `inputs.FixTable` on the replay time axis.

Fixes (GGA or NAV-PVT) are placed at the receiver's own UTC of the fix (else their mapped
arrival): latitude/longitude/ellipsoidal height -> ENU at the origin (m). 1-sigma per axis:
GST (latitude/longitude/altitude sigmas of the same epoch) when present, else NAV-PVT
hAcc/sqrt(2) and vAcc, else `DEFAULT_UERE_M * HDOP` per horizontal axis and twice that
vertically (at least 0.1 m). Horizontal velocity: NAV-PVT, else the RMC speed/course of the
same epoch (NaN without). A fix without a finite latitude, longitude and height (e.g. a
GGA with an empty altitude field) is neither the origin nor a measurement; such fixes are
counted (`gnss_fixes_unusable`), and so are GST and valid RMC sentences whose time or values
are empty or unreadable (`gst_rmc_unreadable`; e.g. hour 25, which pynmea2 hands back as text).
"""
from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from leonav.hardware.gnss.nmea import time_field
from leonav.hardware.records import GnssFix, NmeaSentence
from leonav_runtime.orbits import geometry
from leonav_runtime.inputs import FixTable

DEFAULT_UERE_M = 1.5            # per-axis horizontal sigma per unit HDOP when no GST/NAV-PVT accuracy


def _tod_key(t: _dt.time | _dt.datetime) -> int:
    """Time of day in hundredths of a second (matches GGA/RMC/GST of one epoch)."""
    return round((t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6) * 100)


def fix_height_m(fix) -> float | None:
    """Ellipsoidal height of a fix (m): its own, else its height above mean sea level (no geoid
    separation sent), None when neither is a finite number (e.g. a GGA with an empty altitude)."""
    for h in (fix.height_m, fix.hmsl_m):
        if h is not None and math.isfinite(h):
            return float(h)
    return None


def usable_fix(fix) -> bool:
    """A fix with finite latitude, longitude and height: it can be the origin and a measurement."""
    return (fix.lat_rad is not None and fix.lon_rad is not None and math.isfinite(fix.lat_rad)
            and math.isfinite(fix.lon_rad) and fix_height_m(fix) is not None)


def _epoch_entry(kind: str, msg) -> tuple[int, tuple[float, ...]]:
    """(time-of-day key, GST 1-sigma latitude/longitude/altitude in m, or RMC (v_E, v_N) in m/s)
    of a GST or valid RMC sentence; ValueError/TypeError when its time or a value is empty or
    unreadable."""
    tod = time_field(msg)               # BadField (a ValueError) for a time pynmea2 could not read
    if tod is None:
        raise ValueError("no time of day")
    if kind == "GST":
        return _tod_key(tod), (float(msg.std_dev_latitude), float(msg.std_dev_longitude), float(msg.std_dev_altitude))
    speed = float(msg.spd_over_grnd or 0.0) * 1852.0 / 3600.0
    course = math.radians(float(msg.true_course or 0.0))
    return _tod_key(tod), (speed * math.sin(course), speed * math.cos(course))


def _positive_finite(v) -> bool:
    return v is not None and math.isfinite(v) and v > 0


def fix_table(gnss_records, to_utc, epoch: float, origin, notes: list[str]) -> tuple[FixTable, dict]:
    """Fixes on the replay axis in ENU at `origin` (rad, rad, m) with their 1-sigma.

    Fixes without a finite position (`usable_fix`) are left out and counted."""
    tables: dict[str, dict] = {"GST": {}, "RMC": {}}
    unreadable = 0
    for r in gnss_records:
        if isinstance(r, NmeaSentence) and r.msg is not None and r.sentence_type in tables \
                and (r.sentence_type == "GST" or r.msg.status == "A"):
            try:
                key, value = _epoch_entry(r.sentence_type, r.msg)
            except (TypeError, ValueError):
                unreadable += 1       # this epoch has no GST sigmas / RMC velocity
                continue
            tables[r.sentence_type][key] = value
    gst, rmc = tables["GST"], tables["RMC"]
    if unreadable:
        notes.append(f"GNSS: {unreadable} GST/RMC sentence(s) with an empty or unreadable time or value left out "
                     "(their epochs take the NAV-PVT or HDOP sigmas and no RMC velocity)")
    fixes = [r for r in gnss_records if isinstance(r, GnssFix)]
    usable = [f for f in fixes if usable_fix(f)]
    counts = {"gnss_fixes": len(fixes), "gnss_fixes_unusable": len(fixes) - len(usable), "fix_sigma_source": {},
              "gst_rmc_unreadable": unreadable}
    if len(usable) < len(fixes):
        notes.append(f"GNSS: {len(fixes) - len(usable)} fix(es) without a finite latitude, longitude and height "
                     "(e.g. an empty GGA altitude field) left out")
    fixes = usable
    if not fixes:
        return FixTable.empty(), counts
    lat0, lon0, h0 = origin
    r0 = geometry.geodetic_to_ecef(lat0, lon0, h0)
    t, enu, sig, vel = [], [], [], []
    no_height = 0
    for f in fixes:
        t_utc = f.utc.timestamp() if f.utc is not None else float(to_utc(f.t_mono_s))
        h = fix_height_m(f)
        no_height += f.height_m is None or not math.isfinite(f.height_m)
        enu.append(geometry.ecef_to_enu(geometry.geodetic_to_ecef(f.lat_rad, f.lon_rad, h), r0, lat0, lon0))
        t.append(t_utc - epoch)
        key = _tod_key(f.utc) if f.utc is not None else None
        if key in gst and all(math.isfinite(v) and v > 0 for v in gst[key]):
            s_n, s_e, s_u = gst[key]
            src = "GST"
        elif _positive_finite(f.h_acc_m) and _positive_finite(f.v_acc_m):
            s_e = s_n = f.h_acc_m / math.sqrt(2.0)
            s_u = f.v_acc_m
            src = "NAV-PVT accuracy"
        else:
            hdop = f.hdop if _positive_finite(f.hdop) else 1.0
            s_e = s_n = DEFAULT_UERE_M * hdop
            s_u = 2.0 * s_e
            src = f"{DEFAULT_UERE_M:g} m x HDOP"
        counts["fix_sigma_source"][src] = counts["fix_sigma_source"].get(src, 0) + 1
        sig.append([max(s_e, 0.1), max(s_n, 0.1), max(s_u, 0.1)])
        if f.vel_ned_mps is not None:
            vel.append([f.vel_ned_mps[1], f.vel_ned_mps[0]])
        else:
            vel.append(list(rmc.get(key, (math.nan, math.nan))))
    if no_height:
        notes.append(f"GNSS: {no_height} fix(es) without geoid separation: height above mean sea level used as "
                     "ellipsoidal height (tens of metres off in Up)")
    return FixTable(np.array(t), np.array(enu), np.array(sig), np.array(vel)), counts
