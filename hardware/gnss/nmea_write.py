"""NMEA 0183 sentence writers (GGA, RMC, GST) for simulators and tests.

The output follows what a u-blox M10 sends with NMEA 4.10 on a multi-constellation fix
(talker `GN`): time `hhmmss.ss`, latitude `ddmm.mmmmm` and longitude `dddmm.mmmmm`
(1e-5 arc-minute, about 1.9 cm), heights to 0.1 m, speed in knots to 0.001, course to
0.01 deg. Every sentence ends with `*hh` (XOR checksum, `nmea.nmea_checksum`) and CR LF.
These are the inverse of `hardware.gnss.nmea` and round-trip through `GnssDecoder`.
"""
from __future__ import annotations

import datetime as _dt
import math

from leonav.hardware.gnss.nmea import nmea_checksum

KNOT_MPS = 1852.0 / 3600.0


def sentence(body: str) -> bytes:
    """`$<body>*hh\\r\\n` with the checksum of `body` (the text between '$' and '*')."""
    return f"${body}*{nmea_checksum(body.encode('ascii')):02X}\r\n".encode("ascii")


def round_to_centiseconds(utc: _dt.datetime) -> _dt.datetime:
    """`utc` rounded to the sentences' hundredths of a second; the carry reaches the date
    (23:59:59.996 becomes 00:00:00.00 of the next day)."""
    cs = round(utc.microsecond / 1e4)
    return utc.replace(microsecond=0) + _dt.timedelta(microseconds=cs * 10000)


def _time(utc: _dt.datetime) -> str:
    t = round_to_centiseconds(utc)
    return f"{t.hour:02d}{t.minute:02d}{t.second:02d}.{t.microsecond // 10000:02d}"


def _angle(deg: float, width: int, pos: str, neg: str) -> tuple[str, str]:
    """Signed degrees -> ('ddmm.mmmmm' with `width` degree digits, hemisphere letter)."""
    hemi = pos if deg >= 0 else neg
    a = abs(deg)
    whole = int(a)
    minutes = round((a - whole) * 60.0, 5)
    if minutes >= 60.0:          # rounding carried into the next degree
        whole, minutes = whole + 1, 0.0
    return f"{whole:0{width}d}{minutes:08.5f}", hemi


def gga(utc: _dt.datetime, lat_deg: float, lon_deg: float, hmsl_m: float, geoid_sep_m: float,
        quality: int = 1, num_sv: int = 12, hdop: float = 0.8, talker: str = "GN") -> bytes:
    """GGA fix: position (WGS84 deg), height above mean sea level and geoid separation (m)."""
    lat, ns = _angle(lat_deg, 2, "N", "S")
    lon, ew = _angle(lon_deg, 3, "E", "W")
    body = (f"{talker}GGA,{_time(utc)},{lat},{ns},{lon},{ew},{quality:d},{num_sv:02d},{hdop:.2f},"
            f"{hmsl_m:.1f},M,{geoid_sep_m:.1f},M,,")
    return sentence(body)


def rmc(utc: _dt.datetime, lat_deg: float, lon_deg: float, v_east_mps: float, v_north_mps: float,
        valid: bool = True, talker: str = "GN") -> bytes:
    """RMC: time and date, position, speed over ground (knots) and course (deg, clockwise from North)."""
    lat, ns = _angle(lat_deg, 2, "N", "S")
    lon, ew = _angle(lon_deg, 3, "E", "W")
    speed_kn = math.hypot(v_east_mps, v_north_mps) / KNOT_MPS
    course = math.degrees(math.atan2(v_east_mps, v_north_mps)) % 360.0
    day = round_to_centiseconds(utc)  # the same rounding as the time field, so a carry changes the date
    date = f"{day.day:02d}{day.month:02d}{day.year % 100:02d}"
    status, mode = ("A", "A") if valid else ("V", "N")
    body = (f"{talker}RMC,{_time(utc)},{status},{lat},{ns},{lon},{ew},{speed_kn:.3f},{course:.2f},"
            f"{date},,,{mode},V")
    return sentence(body)


def gst(utc: _dt.datetime, sigma_lat_m: float, sigma_lon_m: float, sigma_alt_m: float,
        rms_m: float = 0.0, talker: str = "GN") -> bytes:
    """GST: 1-sigma position errors (m) in latitude (North), longitude (East) and altitude."""
    major, minor = max(sigma_lat_m, sigma_lon_m), min(sigma_lat_m, sigma_lon_m)
    orient = 0.0 if sigma_lat_m >= sigma_lon_m else 90.0
    body = (f"{talker}GST,{_time(utc)},{rms_m:.1f},{major:.1f},{minor:.1f},{orient:.1f},"
            f"{sigma_lat_m:.1f},{sigma_lon_m:.1f},{sigma_alt_m:.1f}")
    return sentence(body)
