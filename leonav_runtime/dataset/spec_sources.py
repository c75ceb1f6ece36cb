"""The checks of a dataset description's sources ([imu], [gnss], [reference]) that one key
alone cannot make: column lists, formats, time bases, the boot clock, the reference attitude.

Each failure is one `UserInputError` naming the file, the section and the key, and what was
expected (called from `spec._finish`, which holds the rest).
"""
from __future__ import annotations

import re
from typing import Any

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import check_numbers, show_value, where_key

MAX_OFFSET_S = 3600.0
"""|[imu] time_offset_s| outside time_base = "boot" (a larger one is a clock, not an offset)."""


def check_columns(source: str, section: str, key: str, value: Any, n: int | None) -> list:
    """`value` as a list of column names or 0-based indices (`n` of them unless None)."""
    ok = isinstance(value, list) and all(isinstance(v, str) or (isinstance(v, int) and not isinstance(v, bool)
                                                                and v >= 0) for v in value)
    if not ok or (n is not None and len(value) != n):
        raise UserInputError(f"{where_key(source, section, key)} = {show_value(value)}: expected "
                             f"{n if n is not None else 'a list of'} column names or 0-based indices")
    return list(value)


def _column_keys(sec: dict, section: str) -> list[str]:
    keys = {"imu": ["time_column", "accel_time_column", "gyro_columns", "accel_columns"],
            "gnss": ["time_column", "lat_column", "lon_column", "height_column", "sigma_columns", "velocity_columns",
                     "velocity_sigma_columns"],
            "reference": ["time_column", "position_columns", "quaternion_columns", "euler_columns"]}[section]
    return keys + (["week_column"] if sec["week_column"] != "" else [])


def _arrays_take_indices(source: str, sec: dict, section: str) -> None:
    """npy/npz sources have no header: every column is a 0-based index."""
    if sec["format"] not in ("npy", "npz"):
        if sec.get("array"):
            raise UserInputError(f"{where_key(source, section, 'array')} = {sec['array']!r} with format = "
                                 f"{sec['format']!r}: expected format = 'npz' (or no array key)")
        return
    for key in _column_keys(sec, section):
        vals = sec[key] if isinstance(sec[key], list) else [sec[key]]
        if any(not isinstance(c, int) for c in vals):
            raise UserInputError(f"{where_key(source, section, key)} = {show_value(sec[key])} with format = "
                                 f"{sec['format']!r}: expected 0-based column indices (an array has no header)")


def _time_base(source: str, sec: dict, section: str) -> None:
    base = sec["time_base"]
    if base == "gps_week_tow" and sec["week_column"] == "" and sec["gps_week"] == 0:
        raise UserInputError(f"{where_key(source, section, 'time_base')} = 'gps_week_tow': expected week_column (a "
                             "column of GPS week numbers) or gps_week (the week of the first row)")
    if base != "gps_week_tow" and (sec["week_column"] != "" or sec["gps_week"]):
        key = "week_column" if sec["week_column"] != "" else "gps_week"
        raise UserInputError(f"{where_key(source, section, key)} given with time_base = {base!r}: expected "
                             "time_base = 'gps_week_tow' (or no week key)")
    if sec["format"] in ("nmea", "ubx", "pos") and base != "unix":
        raise UserInputError(f"{where_key(source, section, 'time_base')} = {base!r} with format = {sec['format']!r}: "
                             "the log's own time is decoded (UTC); expected 'unix'")


def _imu(source: str, imu: dict) -> None:
    for key in ("gyro_columns", "accel_columns"):
        imu[key] = check_columns(source, "imu", key, imu[key], None)
        if len(imu[key]) != 3 and not (imu["format"] == "mat" and len(imu[key]) == 1):
            raise UserInputError(f"{where_key(source, 'imu', key)} = {show_value(imu[key])}: expected 3 column "
                                 "names or indices (x y z; mat: also one (n, 3) field)")
    if imu["accel_file"] and imu["format"] == "mat":
        raise UserInputError(f"{where_key(source, 'imu', 'accel_file')} with format = 'mat': expected csv, npy or "
                             "npz (a .mat holds both fields in `file`)")
    if imu["accel_array"] and not imu["accel_file"]:
        raise UserInputError(f"{where_key(source, 'imu', 'accel_array')} without accel_file: expected both or neither")
    base, off = imu["time_base"], imu["time_offset_s"]
    pair = imu["clock_pair"]
    if pair != []:
        pair = imu["clock_pair"] = check_numbers(source, "imu", "clock_pair", pair, 2, "s", limit=1e11)
        if base != "boot":
            raise UserInputError(f"{where_key(source, 'imu', 'clock_pair')} given with time_base = {base!r}: "
                                 "expected time_base = 'boot' (a clock pair maps a boot clock to unix time)")
    if base == "boot" and not pair:
        if isinstance(off, str) or off == 0.0:
            raise UserInputError(f"{where_key(source, 'imu', 'time_base')} = 'boot': expected clock_pair = [boot_s, "
                                 f"unix_s] or a number time_offset_s (unix - boot, s), got time_offset_s = "
                                 f"{show_value(off)} (calibration needs the clock pair first)")
    elif not isinstance(off, str) and abs(off) > MAX_OFFSET_S:
        raise UserInputError(f"{where_key(source, 'imu', 'time_offset_s')}: expected seconds within "
                             f"+-{MAX_OFFSET_S:g} (a clock is time_base = 'boot' with clock_pair or time_offset_s)")


def _reference(source: str, gnss: dict, ref: dict) -> None:
    ref["position_columns"] = check_columns(source, "reference", "position_columns", ref["position_columns"], 3)
    for key, n, what in (("quaternion_columns", 4, f"4 columns ({' '.join(ref['quaternion_order'])})"),
                         ("euler_columns", 3, "3 columns (roll pitch yaw, deg)")):
        ref[key] = check_columns(source, "reference", key, ref[key], None)
        if len(ref[key]) not in (0, n):
            raise UserInputError(f"{where_key(source, 'reference', key)} = {show_value(ref[key])}: expected {what} "
                                 "or none")
    euler = ref["attitude"] == "euler_deg"
    wrong, right = ("quaternion_columns", "euler_columns") if euler else ("euler_columns", "quaternion_columns")
    if ref[wrong]:
        raise UserInputError(f"{where_key(source, 'reference', wrong)} given with attitude = {ref['attitude']!r}: "
                             f"expected {right}")
    crs = ref["crs"]
    if (gnss["height_datum"] == "msl" or ref["height_datum"] == "msl") and gnss["geoid_separation_m"] == 0.0:
        raise UserInputError(f"{where_key(source, 'gnss', 'geoid_separation_m')}: heights declared msl "
                             "(height_datum): expected the site's geoid height N in m (ellipsoidal = msl + N)")
    if ref["height_datum"] == "msl" and crs == "ecef":
        raise UserInputError(f"{where_key(source, 'reference', 'height_datum')} = 'msl' with crs = 'ecef': ECEF has no "
                             "height datum; expected 'ellipsoid'")
    if gnss["height_datum"] == "msl" and gnss["format"] in ("nmea", "ubx"):
        raise UserInputError(f"{where_key(source, 'gnss', 'height_datum')} = 'msl' with format = {gnss['format']!r}: "
                             "NMEA/UBX fixes are decoded to ellipsoidal heights; expected 'ellipsoid'")
    if crs not in ("llh", "ecef") and not re.fullmatch(r"EPSG:\d{4,6}", crs):
        raise UserInputError(f"{where_key(source, 'reference', 'crs')} = {crs!r}: expected llh, ecef or EPSG:<code>")


def finish_sources(v: dict[str, dict[str, Any]], source: str) -> None:
    """Validate and convert the source keys of [imu], [gnss], [reference] in place (module doc)."""
    imu, gnss, ref = v["imu"], v["gnss"], v["reference"]
    _imu(source, imu)
    _reference(source, gnss, ref)
    for section, sec in (("imu", imu), ("gnss", gnss), ("reference", ref)):
        _time_base(source, sec, section)
        _arrays_take_indices(source, sec, section)
