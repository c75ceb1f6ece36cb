"""GPS - UTC leap seconds (IERS Bulletin C): the one table of the project.

The device layer needs it to tag RXM-RAWX epochs whose leapS is not yet valid
(`hardware.gnss.reader`); the runtime's GNSS time scale (`leonav_runtime.gnss.time`)
uses the same table, so both place GPS week/TOW on UTC identically.
"""
from __future__ import annotations

import datetime as _dt

_GPS_EPOCH_ORDINAL = _dt.date(1980, 1, 6).toordinal()
DAY_S = 86400.0

# GPS - UTC in seconds from the given UTC date on (IERS Bulletin C announcements).
LEAP_SECONDS = (
    (_dt.date(1981, 7, 1), 1), (_dt.date(1982, 7, 1), 2), (_dt.date(1983, 7, 1), 3),
    (_dt.date(1985, 7, 1), 4), (_dt.date(1988, 1, 1), 5), (_dt.date(1990, 1, 1), 6),
    (_dt.date(1991, 1, 1), 7), (_dt.date(1992, 7, 1), 8), (_dt.date(1993, 7, 1), 9),
    (_dt.date(1994, 7, 1), 10), (_dt.date(1996, 1, 1), 11), (_dt.date(1997, 7, 1), 12),
    (_dt.date(1999, 1, 1), 13), (_dt.date(2006, 1, 1), 14), (_dt.date(2009, 1, 1), 15),
    (_dt.date(2012, 7, 1), 16), (_dt.date(2015, 7, 1), 17), (_dt.date(2017, 1, 1), 18),
)


def leap_seconds_at_utc(utc: _dt.datetime | _dt.date) -> int:
    """GPS - UTC (s) in force at a UTC date (0 before 1981-07-01)."""
    date = utc.date() if isinstance(utc, _dt.datetime) else utc
    leap = 0
    for start, value in LEAP_SECONDS:
        if date >= start:
            leap = value
    return leap


def leap_seconds_at_gps(t_gps_s: float) -> int:
    """GPS - UTC (s) in force at a GPS time, s since 1980-01-06 (the step is applied at UTC midnight)."""
    leap = 0
    for start, value in LEAP_SECONDS:
        step_gps = (start.toordinal() - _GPS_EPOCH_ORDINAL) * DAY_S + value
        if t_gps_s >= step_gps:
            leap = value
    return leap
