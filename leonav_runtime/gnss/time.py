"""GNSS time scales as continuous seconds: GPS time, Galileo system time, BeiDou time, UTC.

Inside `leonav_runtime.gnss` every epoch is a float64 count of GPS seconds since the GPS
epoch 1980-01-06 00:00:00 (GPST, no leap seconds, no week rollover), called `t_gps_s`.
Its resolution is 2.4e-7 s around 2020 (float64 ulp at 1.3e9 s): 1 mm of GPS satellite
motion, below anything the pseudorange model resolves. Week/time-of-week pairs and RINEX
calendar epochs convert exactly through integer days and seconds.

Galileo system time (GST) keeps GPS seconds (its week number in RINEX 3 navigation files
is aligned with the GPS week). BeiDou time (BDT) = GPST - 14 s, BDT week 0 = GPS week
1356. UTC = GPST - (GPS-UTC leap seconds), from the table in `hardware.gnss.leap` (IERS Bulletin C),
shared with the device layer.
"""
from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from leonav.hardware.gnss.leap import (_GPS_EPOCH_ORDINAL, DAY_S, leap_seconds_at_gps,  # noqa: F401 (the one table,
                                leap_seconds_at_utc)                         # re-exported)
from leonav_runtime.gen.constants import BDT_MINUS_GPST_S, BDT_WEEK_OFFSET, GPS_WEEK_S

GPS_EPOCH = _dt.datetime(1980, 1, 6, tzinfo=_dt.timezone.utc)


def calendar_to_seconds(year: int, month: int, day: int, hour: int = 0, minute: int = 0,
                        second: float = 0.0) -> float:
    """Seconds since 1980-01-06 00:00 of a calendar epoch in the same (leap-free) scale.

    Raises ValueError for an impossible date (month 13, day 32, ...).
    """
    days = _dt.date(year, month, day).toordinal() - _GPS_EPOCH_ORDINAL
    if not (0 <= hour <= 24 and 0 <= minute <= 60 and 0.0 <= second <= 61.0):
        raise ValueError(f"time of day {hour}:{minute}:{second} out of range")
    return days * DAY_S + hour * 3600.0 + minute * 60.0 + second


def gps_seconds(week: int | np.ndarray, tow_s: float | np.ndarray) -> float | np.ndarray:
    """Continuous GPS seconds of a full (not mod 1024) GPS week and time of week."""
    return np.asarray(week, dtype=np.float64) * GPS_WEEK_S + tow_s


def week_tow(t_gps_s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(GPS week, time of week s) of continuous GPS seconds."""
    t = np.asarray(t_gps_s, dtype=np.float64)
    week = np.floor(t / GPS_WEEK_S)
    return week.astype(np.int64), t - week * GPS_WEEK_S


def bdt_to_gps_seconds(t_bdt_s: float | np.ndarray) -> float | np.ndarray:
    """BDT seconds since 1980-01-06 in BDT's own calendar -> GPS seconds (+14 s)."""
    return t_bdt_s - BDT_MINUS_GPST_S


def bdt_week_to_gps_week(bdt_week: int) -> int:
    return int(bdt_week + BDT_WEEK_OFFSET)


def utc_to_gps_seconds(utc: _dt.datetime) -> float:
    """A UTC datetime (naive = UTC) -> continuous GPS seconds."""
    if utc.tzinfo is not None:
        utc = utc.astimezone(_dt.timezone.utc).replace(tzinfo=None)
    t = calendar_to_seconds(utc.year, utc.month, utc.day, utc.hour, utc.minute,
                            utc.second + utc.microsecond * 1e-6)
    return t + leap_seconds_at_utc(utc)


def gps_seconds_to_utc(t_gps_s: float) -> _dt.datetime:
    """Continuous GPS seconds -> tz-aware UTC datetime (microsecond resolution)."""
    leap = leap_seconds_at_gps(t_gps_s)
    whole = math.floor(t_gps_s)
    frac_us = round((t_gps_s - whole) * 1e6)
    return GPS_EPOCH + _dt.timedelta(seconds=whole - leap, microseconds=frac_us)


def gps_seconds_to_datetime(t_gps_s: float) -> _dt.datetime:
    """Continuous GPS seconds -> GPST calendar datetime (tz-aware, no leap seconds applied)."""
    whole = math.floor(t_gps_s)
    return GPS_EPOCH + _dt.timedelta(seconds=whole, microseconds=round((t_gps_s - whole) * 1e6))


def resolve_week(week_mod: int | np.ndarray, reference_week: int, bits: int = 10) -> int | np.ndarray:
    """Full week number from a truncated one (10-bit LNAV week, 13-bit CNAV week).

    The answer is the week equal to `week_mod` modulo 2**bits nearest to
    `reference_week` (the full GPS week of a date known to be within 2**(bits-1) weeks of
    the data: a receiver time tag, the file date, or the processing date). A reference
    that is wrong by more than 512 weeks (9.8 years) gives a result off by 1024 weeks.
    """
    span = 1 << bits
    w = np.asarray(week_mod, dtype=np.int64) % span
    k = np.round((reference_week - w) / span).astype(np.int64)
    out = w + k * span
    return int(out) if np.ndim(out) == 0 else out


def nearest_week_time(sow: float | np.ndarray, t_ref_s: float | np.ndarray) -> np.ndarray:
    """Continuous seconds of a seconds-of-week value in the week that puts it nearest `t_ref_s`.

    Used for toe, toc and transmit times given as seconds of week next to a full epoch
    (week crossovers: toe may lie in the week after the transmission).
    """
    if isinstance(sow, (float, int)) and isinstance(t_ref_s, (float, int)):  # scalars (readers): plain floats
        t = math.floor(t_ref_s / GPS_WEEK_S) * GPS_WEEK_S + float(sow)
        if t - t_ref_s > GPS_WEEK_S / 2:
            t -= GPS_WEEK_S
        elif t - t_ref_s < -GPS_WEEK_S / 2:
            t += GPS_WEEK_S
        return np.float64(t)
    t_ref = np.asarray(t_ref_s, dtype=np.float64)
    week_start = np.floor(t_ref / GPS_WEEK_S) * GPS_WEEK_S
    t = week_start + np.asarray(sow, dtype=np.float64)
    t = np.where(t - t_ref > GPS_WEEK_S / 2, t - GPS_WEEK_S, t)
    t = np.where(t - t_ref < -GPS_WEEK_S / 2, t + GPS_WEEK_S, t)
    return t
