"""Time bases of a dataset's time columns, to unix seconds (UTC) where the base allows.

`[imu]`, `[gnss]` and `[reference]` each say in `time_base` what their time column counts
(after `time_unit`):
- `unix`: unix seconds (UTC);
- `gps_week_tow`: seconds of the GPS week; the week from `week_column` (full week numbers)
  or from `gps_week` (one week for the file: a time of week that falls back by more than half
  a week is the next week, so a Sunday-midnight rollover is followed);
- `gps_seconds`: seconds since the GPS epoch 1980-01-06 (GPST, no leap seconds); UTC by the
  leap-second table (`gnss.time.gps_seconds_to_utc`);
- IMU only: `first_fix` (seconds from the first GNSS fix, left as they are) and `boot` (a
  monotonic clock since power-on): unix = boot - clock_pair[0] + clock_pair[1] with
  `clock_pair = [boot_s, unix_s]`, else left as it is and `time_offset_s` (any size) maps it.
"""
from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss import time as gtime

GPS_WEEK_S = 604800.0
UNIX_BASES = ("unix", "gps_week_tow", "gps_seconds")
IMU_BASES = UNIX_BASES + ("first_fix", "boot")


def gps_to_unix(t_gps_s: np.ndarray) -> np.ndarray:
    """Seconds since the GPS epoch (GPST) -> unix seconds (UTC), leap seconds applied per
    sample (one offset when the record holds no leap second, the common case); NaN stays NaN."""
    t = np.asarray(t_gps_s, float)
    finite = np.isfinite(t)
    if not finite.any():
        return t.copy()

    def offset(x: float) -> float:      # unix - GPST at x (s): whole seconds, exact
        whole = math.floor(x)
        return gtime.gps_seconds_to_utc(whole).timestamp() - whole

    lo, hi = offset(float(t[finite].min())), offset(float(t[finite].max()))
    if lo == hi:
        return t + lo
    out = t.copy()
    out[finite] = [x + offset(x) for x in t[finite]]
    return out


def week_tow_to_gps(tow_s: np.ndarray, week: np.ndarray | float, single_week: bool) -> np.ndarray:
    """GPS seconds of week numbers and times of week (s). `single_week`: one week for the record,
    a fall of the time of week by more than half a week starts the next week (rollover)."""
    tow = np.asarray(tow_s, float)
    weeks = np.broadcast_to(np.asarray(week, float), tow.shape).copy()
    if single_week and tow.size > 1:
        fin = np.flatnonzero(np.isfinite(tow))
        falls = np.zeros(tow.size)
        falls[fin[1:]] = np.diff(tow[fin]) < -GPS_WEEK_S / 2
        weeks += np.cumsum(falls)
    return weeks * GPS_WEEK_S + tow


def to_base(t_s: np.ndarray, sec: dict, week: np.ndarray | None, where: str) -> tuple[np.ndarray, int]:
    """A section's time column (s, after time_unit) in its time base (module doc): unix s for
    the unix bases and for `boot` with a clock pair, else unchanged. `week`: the week column's
    values (gps_week_tow with `week_column`). Returns (t, rows whose time of week or week is
    impossible: NaN, for the caller to count and skip); `where` names the time_base key."""
    base = sec.get("time_base", "unix")
    t = np.asarray(t_s, float)
    if base == "unix" or base == "first_fix":
        return t, 0
    if base == "boot":
        pair = sec.get("clock_pair") or []
        return (t - pair[0] + pair[1] if pair else t), 0
    if base == "gps_seconds":
        return gps_to_unix(t), 0
    fin = t[np.isfinite(t)]
    if fin.size and np.median(fin) > GPS_WEEK_S:
        raise UserInputError(f"{where} = 'gps_week_tow': the time column's median is {np.median(fin):.6g} s, "
                             f"expected seconds of the GPS week (0..{GPS_WEEK_S:g}): check time_base and time_unit")
    bad = ~((t >= 0) & (t < GPS_WEEK_S + 1.0))
    if week is not None:
        w = np.asarray(week, float)
        bad |= ~((w >= 0) & (w < 1e4) & (w == np.round(w)))
        t_gps = week_tow_to_gps(np.where(bad, np.nan, t), np.where(bad, 0.0, w), False)
    else:
        t_gps = week_tow_to_gps(np.where(bad, np.nan, t), float(sec["gps_week"]), True)
    n_bad = int((bad & np.isfinite(t)).sum())
    return gps_to_unix(np.where(bad, np.nan, t_gps)), n_bad


def week_key(sec: dict) -> list[tuple[str, object]]:
    """The week column to read with the time column ([] unless gps_week_tow with `week_column`)."""
    if sec.get("time_base") == "gps_week_tow" and sec.get("week_column", "") != "":
        return [("week_column", sec["week_column"])]
    return []


def gps_week_of_unix(t_unix_s: float) -> float:
    """GPS week (with its fraction) of a unix time (UTC), through the leap-second table."""
    utc = _dt.datetime.fromtimestamp(float(t_unix_s), _dt.timezone.utc)
    return gtime.utc_to_gps_seconds(utc) / GPS_WEEK_S
