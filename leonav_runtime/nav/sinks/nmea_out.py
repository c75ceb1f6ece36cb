"""NMEA 0183 sentences of a navigation solution: GGA, RMC, GST and $PLNAV.

GGA's altitude field is the height above mean sea level and the next field the geoid
separation; leonav has no geoid model, so it writes the ellipsoidal height with a geoid
separation of 0 (a reader that adds them, as gpsd does for altHAE, gets the ellipsoidal
height back exactly; one that shows "MSL" shows the ellipsoidal height). GST carries the
1-sigma North/East/Up errors. The proprietary `$PLNAV` sentence carries what NMEA has no
standard sentence for: `PLNAV,hhmmss.ss,v_e,v_n,v_u (m/s),roll,pitch,heading (deg,
heading clockwise from North),sigma_e,sigma_n,sigma_u (m),mode,n_gnss,n_leo`.
"""
from __future__ import annotations

import dataclasses
import math

from leonav.hardware.gnss import nmea_write
from leonav_runtime.nav.sinks.solution import NavSolution

HDOP_PER_M = 1.0 / 1.5  # GGA HDOP from the horizontal sigma, at the UERE the replay assumes


def gga(sol: NavSolution) -> bytes:
    hdop = min(99.99, sol.sigma_horizontal_m * HDOP_PER_M) if math.isfinite(sol.sigma_horizontal_m) else 99.99
    return nmea_write.gga(sol.utc, sol.lat_deg, sol.lon_deg, sol.h_m, 0.0, quality=sol.fix_quality,
                          num_sv=min(sol.n_gnss, 99), hdop=hdop)


def rmc(sol: NavSolution) -> bytes:
    return nmea_write.rmc(sol.utc, sol.lat_deg, sol.lon_deg, sol.v_enu_mps[0], sol.v_enu_mps[1],
                          valid=sol.fix_quality > 0)


def gst(sol: NavSolution) -> bytes:
    e, n, u = sol.sigma_enu_m
    return nmea_write.gst(sol.utc, n, e, u, rms_m=math.sqrt(e * e + n * n + u * u))


def plnav(sol: NavSolution) -> bytes:
    t = sol.utc
    roll, pitch = (math.degrees(a) for a in sol.rpy_rad[:2])
    e, n, u = sol.sigma_enu_m
    body = (f"PLNAV,{t.hour:02d}{t.minute:02d}{t.second:02d}.{t.microsecond // 10000:02d},"
            f"{sol.v_enu_mps[0]:.3f},{sol.v_enu_mps[1]:.3f},{sol.v_enu_mps[2]:.3f},"
            f"{roll:.2f},{pitch:.2f},{sol.heading_deg:.2f},{e:.2f},{n:.2f},{u:.2f},"
            f"{sol.mode},{sol.n_gnss:d},{sol.n_leo:d}")
    return nmea_write.sentence(body)


def sentences(sol: NavSolution) -> bytes:
    """The epoch's sentences in the order a receiver sends them: RMC, GGA, GST, PLNAV.

    The time is rounded to the sentences' hundredths of a second first, so a rounding
    carry reaches the date too (23:59:59.996 is written as 00:00:00.00 of the next day)."""
    sol = dataclasses.replace(sol, utc=nmea_write.round_to_centiseconds(sol.utc))
    return rmc(sol) + gga(sol) + gst(sol) + plnav(sol)

