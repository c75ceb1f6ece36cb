"""Position solutions to files: RTKLIB's `.pos` text and CSV (geodetic and ECEF).

`.pos` follows what rnx2rtkp writes for `-p 0` with its default output options (GPS week
and seconds of week with 3 decimals, latitude/longitude in degrees, ellipsoidal height,
Q (5 = single), ns, standard deviations sdn sde sdu and the signed square roots sdne sdeu
sdun of the ENU covariance, age, ratio), with a '%' header naming the program, input
files, time span and options, so RTKLIB's tools (rtkplot, pos2kml) read it. As in RTKLIB
the solution time is the receive time corrected by the estimated receiver clock.
`read_pos` reads such files back (rnx2rtkp's own as well).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import C_LIGHT_MPS
from leonav_runtime.gnss import time as gtime

Q_SINGLE = 5
POS_COLUMNS = ("%  GPST          latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)"
               "  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio")


@dataclass
class PosRecord:
    """One solution line of a .pos file."""

    t_gps_s: float
    lat_deg: float
    lon_deg: float
    height_m: float
    q: int
    ns: int
    sd: tuple[float, ...]  # sdn sde sdu sdne sdeu sdun (m)

    @property
    def r_ecef_m(self) -> np.ndarray:
        return np.asarray(geometry.geodetic_to_ecef(math.radians(self.lat_deg), math.radians(self.lon_deg),
                                                    self.height_m), float)


def _sqvar(c: float) -> float:
    return math.copysign(math.sqrt(abs(c)), c)


def _calendar(t_gps_s: float) -> str:
    d = gtime.gps_seconds_to_datetime(t_gps_s)
    return f"{d:%Y/%m/%d %H:%M:%S}.{int(round(d.microsecond / 1e5)) % 10}"


def write_pos(path: str | Path, t_gps_s, r_ecef_m, cov_enu_m2, ns, clock_m, *, inputs: Sequence[str],
              options: dict[str, str], program: str = "leonav spp", q: int = Q_SINGLE) -> Path:
    """Write solutions (arrays over epochs; only the rows given) in RTKLIB's .pos format.

    t_gps_s: receive times (GPS s); r_ecef_m (n, 3); cov_enu_m2 (n, 3, 3) local ENU
    covariance; ns (n,) satellites used; clock_m (n,) receiver clock (m), subtracted from the
    time as RTKLIB does; options: header lines "name : value" (pos mode, elev mask, ...)."""
    path = Path(path)
    t = np.asarray(t_gps_s, float)
    lat, lon, h = geometry.ecef_to_geodetic(np.asarray(r_ecef_m, float))
    lines = [f"% program   : {program}"]
    lines += [f"% inp file  : {name}" for name in inputs]
    if t.size:
        for label, tt in (("obs start", t[0]), ("obs end  ", t[-1])):
            week, tow = gtime.week_tow(tt)
            lines.append(f"% {label} : {_calendar(tt)} GPST (week{int(week):04d} {float(tow):8.1f}s)")
    lines += [f"% {name:<9} : {value}" for name, value in options.items()]
    lines += ["%", "% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,"
              "ns=# of satellites)", POS_COLUMNS]
    weeks, tows = gtime.week_tow(t - np.asarray(clock_m, float) / C_LIGHT_MPS)
    lat_deg, lon_deg = np.degrees(lat), np.degrees(lon)
    for i in range(t.size):
        week, tow = int(weeks[i]), float(tows[i])
        if round(tow, 3) >= 604800.0:
            week, tow = week + 1, tow - 604800.0
        c = cov_enu_m2[i]
        sd = (math.sqrt(max(c[1, 1], 0.0)), math.sqrt(max(c[0, 0], 0.0)), math.sqrt(max(c[2, 2], 0.0)),
              _sqvar(c[1, 0]), _sqvar(c[0, 2]), _sqvar(c[2, 1]))
        lines.append(f"{week:4d} {tow:10.3f} {lat_deg[i]:14.9f} {lon_deg[i]:14.9f} "
                     f"{h[i]:10.4f} {q:3d} {int(ns[i]):3d} " + " ".join(f"{v:8.4f}" for v in sd)
                     + f" {0.0:6.2f} {0.0:6.1f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def read_pos(path: str | Path) -> list[PosRecord]:
    """Solution lines of a .pos file (GPS week + seconds, or 'yyyy/mm/dd hh:mm:ss.sss' GPST).

    Header lines start with '%'. A line that cannot be read raises UserInputError naming
    the file, the line and the field."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise UserInputError(f"{path}: .pos file not found") from None
    out = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.startswith("%"):
            continue
        p = line.split()
        try:
            if "/" in p[0]:
                y, mo, d = (int(v) for v in p[0].split("/"))
                hh, mm, ss = p[1].split(":")
                t = float(gtime.calendar_to_seconds(y, mo, d, int(hh), int(mm), float(ss)))
            else:
                t = float(gtime.gps_seconds(int(p[0]), float(p[1])))
        except (ValueError, IndexError):
            raise UserInputError(f"{path}:{lineno}: field GPST: {' '.join(p[:2])!r} is not a week/seconds or "
                                 "date/time") from None
        names = ("latitude", "longitude", "height", "Q", "ns", "sdn", "sde", "sdu", "sdne", "sdeu", "sdun")
        values = []
        for k, name in enumerate(names):
            try:
                values.append(float(p[2 + k]))
            except (ValueError, IndexError):
                raise UserInputError(f"{path}:{lineno}: field {name}: missing or not a number") from None
        out.append(PosRecord(t, values[0], values[1], values[2], int(values[3]), int(values[4]), tuple(values[5:11])))
    return out


def compare_pos(ours: Sequence[PosRecord], reference: Sequence[PosRecord], tol_s: float = 0.0015) -> dict:
    """3-D differences (m) of the epochs two solution lists share (matched on time within
    tol_s) and how often the satellite counts agree."""
    ref = sorted(reference, key=lambda r: r.t_gps_s)
    tr = np.array([r.t_gps_s for r in ref])
    d, same_ns, matched = [], 0, 0
    for r in ours:
        if tr.size == 0:
            break
        k = int(np.argmin(np.abs(tr - r.t_gps_s)))
        if abs(tr[k] - r.t_gps_s) > tol_s:
            continue
        matched += 1
        d.append(float(np.linalg.norm(r.r_ecef_m - ref[k].r_ecef_m)))
        same_ns += r.ns == ref[k].ns
    d_arr = np.array(d)
    return {"epochs_ours": len(ours), "epochs_reference": len(ref), "epochs_matched": matched,
            "median_3d_m": float(np.median(d_arr)) if d else math.nan,
            "max_3d_m": float(d_arr.max()) if d else math.nan,
            "same_ns": same_ns, "same_ns_fraction": same_ns / matched if matched else math.nan}
