"""RINEX 2.10/2.11 (GPS) and 3.00-3.05 (GPS, Galileo, BeiDou, QZSS) navigation files ->
`Ephemerides`.

Own reader, not georinex/gnss_lib_py (the reasons are in docs/gnss.md): fixed columns as
the RINEX standard gives them, each record checked field by field. A record that cannot
be used (a field that is not a number, a blank required field, a missing line, a value
outside its physical range, an impossible date) becomes a `Rejection` naming file, line
and field, and the rest of the file is still read. Records of systems without a
Keplerian orbit here (GLONASS, SBAS, NavIC) are skipped and counted. A file that is not
RINEX navigation, or of a version this reader does not know, raises `UserInputError`
naming file, line 1 and the version field.

Record grouping: a record starts at a line whose first columns are not blank (the PRN or
system letter) and owns the indented lines after it, so a broken record never swallows
the next one.
"""
from __future__ import annotations

import logging
import functools
import math
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import EPH_DTYPE, Ephemerides, Rejection, default_fit_s, is_bds_geo
from leonav_runtime.gnss.rinex_files import read_rinex_text   # plain or compressed files

log = logging.getLogger("leonav.gnss")

SUPPORTED = "RINEX 2.10/2.11 GPS navigation ('N') and RINEX 3.00-3.05 navigation ('N')"
RECORD_LINES = {"G": 8, "E": 8, "C": 8, "J": 8, "I": 8, "R": 4, "S": 4}
GLONASS_LINES_305 = 5   # RINEX 3.05 adds a 4th orbit line to GLONASS records (status flags, URAI, health)
KEPLER_SYSTEMS = ("G", "E", "C", "J")

# field names of the broadcast-orbit lines 2..8, per system (used in messages and for
# the values); None marks a spare field
_COMMON = (
    ("iode", "crs", "delta_n", "m0"),
    ("cuc", "e", "cus", "sqrt_a"),
    ("toe_sow", "cic", "omega0", "cis"),
    ("i0", "crc", "omega", "omega_dot"),
)
ORBIT_FIELDS = {
    "G": _COMMON + (("idot", "codes_l2", "week", "l2p_flag"), ("accuracy_m", "health", "tgd", "iodc"),
                    ("transmit_sow", "fit_hours", None, None)),
    "J": _COMMON + (("idot", "codes_l2", "week", "l2p_flag"), ("accuracy_m", "health", "tgd", "iodc"),
                    ("transmit_sow", "fit_hours", None, None)),
    "E": _COMMON + (("idot", "data_sources", "week", None), ("accuracy_m", "health", "tgd", "tgd2"),
                    ("transmit_sow", None, None, None)),
    "C": _COMMON + (("idot", None, "week", None), ("accuracy_m", "health", "tgd", "tgd2"),
                    ("transmit_sow", "iodc", None, None)),
}
# fields that may be blank (read as 0): spares and flags some writers leave out
OPTIONAL = {"codes_l2", "l2p_flag", "fit_hours", "data_sources", "iodc", "tgd2", "accuracy_m"}
DISPLAY = {"iode": "IODE/IODnav/AODE", "toe_sow": "toe", "m0": "M0", "sqrt_a": "sqrt(A)", "omega0": "OMEGA0",
           "i0": "i0", "omega": "omega", "omega_dot": "OMEGA DOT", "idot": "IDOT", "accuracy_m": "SV accuracy",
           "transmit_sow": "transmission time", "fit_hours": "fit interval", "delta_n": "Delta n",
           "tgd": "TGD/BGD", "tgd2": "TGD2/BGD E5b"}
# physical ranges: a garbled digit that still reads as a number is caught here
RANGES = {
    "sqrt_a": (2500.0, 7500.0), "e": (0.0, 0.5), "toe_sow": (0.0, 604800.0), "i0": (-math.pi, math.pi),
    "week": (0.0, 10000.0), "health": (0.0, 1023.0), "crs": (-2000.0, 2000.0), "crc": (-2000.0, 2000.0),
    "cuc": (-1e-3, 1e-3), "cus": (-1e-3, 1e-3), "cic": (-1e-3, 1e-3), "cis": (-1e-3, 1e-3),
    "delta_n": (-1e-6, 1e-6), "omega_dot": (-1e-6, 1e-6), "idot": (-1e-6, 1e-6),
    "m0": (-2 * math.pi, 2 * math.pi), "omega0": (-2 * math.pi, 2 * math.pi), "omega": (-2 * math.pi, 2 * math.pi),
    "tgd": (-1e-6, 1e-6), "tgd2": (-1e-6, 1e-6), "iode": (0.0, 1023.0), "iodc": (0.0, 1023.0),
}
CLOCK_RANGES = {"af0": (-0.1, 0.1), "af1": (-1e-6, 1e-6), "af2": (-1e-9, 1e-9)}
UNKNOWN_TRANSMIT = 0.9e9  # RINEX 3 writes 0.999999999999D+09 for an unknown transmission time


class RejectedRecordsWarning(UserWarning):
    """Some navigation records were rejected (listed in `NavFile.ephemerides.rejected`)."""


@dataclass
class NavFile:
    """A navigation file: its ephemerides plus header items."""

    source: str
    version: float
    ephemerides: Ephemerides
    iono: dict[str, tuple[float, ...]] = field(default_factory=dict)  # "GPSA"/"GPSB"/"GAL"/"BDSA"...
    leap_seconds: int | None = None

    @property
    def rejected(self) -> list[Rejection]:
        return self.ephemerides.rejected

    @property
    def counts(self) -> Counter:
        return self.ephemerides.counts


class _Bad(Exception):
    """A record problem: (line offset within the record, field, reason)."""

    def __init__(self, offset: int, field_name: str, reason: str):
        super().__init__(reason)
        self.offset, self.field_name, self.reason = offset, field_name, reason


def _number(text: str, offset: int, name: str, *, optional: bool) -> float:
    s = text.strip()
    if not s:
        if optional:
            return 0.0
        raise _Bad(offset, name, "blank (a number is required)")
    try:
        value = float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise _Bad(offset, name, f"{s!r} is not a number") from None
    if not math.isfinite(value):
        raise _Bad(offset, name, f"{s!r} is not a finite number")
    return value


def _check_range(value: float, offset: int, name: str, ranges: dict) -> None:
    lo, hi = ranges.get(name, (-math.inf, math.inf))
    if not lo <= value <= hi:
        raise _Bad(offset, name, f"{value:.12g} outside the physical range {lo:g}..{hi:g}")


def _epoch(line: str, v3: bool) -> tuple[str, int, list]:
    """(system, prn, [y, m, d, h, mi, s]) of a record's first line."""
    if v3:
        system = line[0]
        prn_text, rest = line[1:3], line[3:23]
    else:
        system = "G"
        prn_text, rest = line[0:2], line[2:22]
    try:
        prn = int(prn_text)
    except ValueError:
        raise _Bad(0, "PRN", f"{prn_text!r} is not a satellite number") from None
    parts = rest.split()
    if len(parts) != 6:
        raise _Bad(0, "epoch (toc)", f"{rest.strip()!r}: expected 6 numbers (year month day hour minute second)")
    try:
        vals = [int(p) for p in parts[:5]] + [float(parts[5])]
    except ValueError:
        raise _Bad(0, "epoch (toc)", f"{rest.strip()!r} is not a date") from None
    if not v3:
        vals[0] += 1900 if vals[0] >= 80 else 2000
    return system, prn, vals


_ZERO_ROW = {name: np.zeros((), EPH_DTYPE)[name].item() for name in EPH_DTYPE.names}


@functools.lru_cache(maxsize=None)
def _field_plan(system: str, start: int) -> tuple[tuple[int, int, int, str, float, float], ...]:
    """(line, first column, end column, field, low, high) of each orbit field of a record, in
    reading order (the physical range, or unbounded)."""
    plan = []
    for i, names in enumerate(ORBIT_FIELDS[system], start=1):
        for k, name in enumerate(names):
            if name is not None:
                lo, hi = RANGES.get(name, (-math.inf, math.inf))
                plan.append((i, start + 19 * k, start + 19 * (k + 1), name, lo, hi))
    return tuple(plan)


def _parse_record(lines: list[str], v3: bool, system: str, prn: int, epoch: list) -> tuple:
    """One Keplerian record (8 lines) -> an EPH_DTYPE row as a tuple; raises _Bad. (The row is a
    dict until then: setting the fields of a NumPy record one by one cost a third of the reader.)"""
    first = lines[0]
    c0 = 23 if v3 else 22
    clock = {}
    for k, name in enumerate(("af0", "af1", "af2")):
        clock[name] = _number(first[c0 + 19 * k:c0 + 19 * (k + 1)], 0, name, optional=False)
        _check_range(clock[name], 0, name, CLOCK_RANGES)
    start = 4 if v3 else 3
    values: dict[str, float] = {}
    for i, a, b, name, lo, hi in _field_plan(system, start):
        text = lines[i][a:b]
        try:   # the common case in one step; anything else (blank, 'd', not finite, out of range)
            value = float(text.replace("D", "E"))   # goes through the checks below for its message
            ok = lo <= value <= hi and value - value == 0.0
        except ValueError:
            ok = False
        if not ok:
            optional = name in OPTIONAL or (i == 7 and name == "transmit_sow")
            value = _number(text, i, DISPLAY.get(name, name), optional=optional)
            if name in RANGES:
                try:
                    _check_range(value, i, name, RANGES)
                except _Bad as bad:
                    raise _Bad(i, DISPLAY.get(name, name), bad.reason) from None
        values[name] = value
    try:
        toc_sys = gtime.calendar_to_seconds(*epoch)
    except ValueError as exc:
        raise _Bad(0, "epoch (toc)", f"impossible date {epoch}: {exc}") from None
    to_gps = gtime.bdt_to_gps_seconds if system == "C" else (lambda t: t)
    row = dict(_ZERO_ROW)
    row["system"], row["prn"] = system, prn
    row["toc"] = to_gps(toc_sys)
    row["toe_sow"] = values["toe_sow"]
    toe_sys = float(gtime.nearest_week_time(values["toe_sow"], toc_sys))
    if abs(toe_sys - toc_sys) > 7 * 86400.0 / 2:
        raise _Bad(3, "toe", "more than half a week from toc")
    row["toe"] = to_gps(toe_sys)
    row["week"] = int(values["week"])
    tx = values.get("transmit_sow", 0.0)
    if lines[7][start:start + 19].strip() == "" or abs(tx) >= UNKNOWN_TRANSMIT:
        row["transmit"] = np.nan
    else:
        row["transmit"] = to_gps(float(gtime.nearest_week_time(tx % gtime.GPS_WEEK_S, toc_sys)))
    for name in ("af0", "af1", "af2"):
        row[name] = clock[name]
    for name in ("crs", "delta_n", "m0", "cuc", "e", "cus", "sqrt_a", "cic", "omega0", "cis", "i0", "crc",
                 "omega", "omega_dot", "idot", "tgd", "accuracy_m"):
        row[name] = values[name]
    row["tgd2"] = values.get("tgd2", 0.0)
    for name in ("iode", "health"):
        if values[name] != int(values[name]):
            raise _Bad(1 if name == "iode" else 6, DISPLAY.get(name, name), f"{values[name]!r} is not an integer")
        row[name] = int(values[name])
    row["iodc"] = int(values["iodc"]) if "iodc" in values else (row["iode"] if system == "E" else -1)
    fit_hours = values.get("fit_hours", 0.0)
    row["fit_s"] = default_fit_s(system, fit_hours)
    if system == "G":
        row["fit_flag"] = 1 if fit_hours > 4.0 else 0
    elif system == "J":
        row["fit_flag"] = int(fit_hours != 0)
    else:
        row["fit_flag"] = -1
    row["codes_l2"] = int(values.get("codes_l2", 0))
    row["l2p_flag"] = int(values.get("l2p_flag", 0))
    row["data_sources"] = int(values.get("data_sources", 0))
    row["geo"] = system == "C" and bool(is_bds_geo(prn))
    return tuple(row.values())


def _header(lines: list[str], source: str) -> tuple[float, bool, int, dict, int | None]:
    """(version, is_v3, index of the first data line, iono, leap seconds)."""
    if not lines:
        raise UserInputError(f"{source}: empty file (expected a RINEX navigation file: {SUPPORTED})")
    first = lines[0]
    if "RINEX VERSION" not in first[60:]:
        raise UserInputError(f"{source}:1: field RINEX VERSION / TYPE: not found in columns 61-80 "
                             f"(not a RINEX file? expected {SUPPORTED})")
    try:
        version = float(first[0:9])
    except ValueError:
        raise UserInputError(f"{source}:1: field RINEX VERSION: {first[0:9].strip()!r} is not a version number") from None
    file_type = first[20:21]
    if 2.0 <= version < 3.0:
        if file_type != "N":
            kind = {"G": "GLONASS", "H": "SBAS/GEO", "O": "observation"}.get(file_type, repr(file_type))
            raise UserInputError(f"{source}:1: field FILE TYPE: RINEX {version:.2f} {kind} file; "
                                 f"expected {SUPPORTED}")
        v3 = False
    elif 3.0 <= version < 3.06:
        if file_type != "N":
            raise UserInputError(f"{source}:1: field FILE TYPE: {file_type!r} (expected 'N', navigation data)")
        v3 = True
    else:
        raise UserInputError(f"{source}:1: field RINEX VERSION: version {version:g} is not supported "
                             f"(expected {SUPPORTED})")
    iono: dict[str, tuple[float, ...]] = {}
    leap = None
    for i, line in enumerate(lines[1:], start=1):
        label = line[60:].strip()
        if label == "END OF HEADER":
            return version, v3, i + 1, iono, leap
        try:
            if label == "ION ALPHA":
                iono["GPSA"] = tuple(float(line[2 + 12 * k:14 + 12 * k].replace("D", "E")) for k in range(4))
            elif label == "ION BETA":
                iono["GPSB"] = tuple(float(line[2 + 12 * k:14 + 12 * k].replace("D", "E")) for k in range(4))
            elif label == "IONOSPHERIC CORR":
                iono[line[0:4].strip()] = tuple(float(line[5 + 12 * k:17 + 12 * k].replace("D", "E") or 0)
                                               for k in range(4) if line[5 + 12 * k:17 + 12 * k].strip())
            elif label == "LEAP SECONDS":
                leap = int(line[0:6])
        except ValueError:
            log.warning("%s:%d: header field %s could not be read; ignored", source, i + 1, label)
    raise UserInputError(f"{source}: no END OF HEADER line (expected a RINEX navigation header)")


def parse_rinex_nav(text: str, source: str = "<string>") -> NavFile:
    """Parse the text of a RINEX navigation file; see the module docstring."""
    lines = text.splitlines()
    version, v3, first_data, iono, leap = _header(lines, source)
    rows: list[tuple] = []
    sources: list[str] = []
    rejected: list[Rejection] = []
    counts: Counter = Counter()

    def is_start(line: str) -> bool:
        return bool(line[:1].strip()) if v3 else bool(line[:2].strip())

    i = first_data
    n = len(lines)
    while i < n:
        line = lines[i]
        if not line.strip():
            counts["blank_lines"] += 1
            i += 1
            continue
        if not is_start(line):
            rejected.append(Rejection(source, i + 1, "", "continuation line without a record start before it"))
            counts["rejected"] += 1
            i += 1
            continue
        j = i + 1
        while j < n and lines[j].strip() and not is_start(lines[j]):
            j += 1
        group = lines[i:j]
        line_no = i + 1
        i = j
        try:
            system, prn, epoch = _epoch(group[0], v3)
            if system not in RECORD_LINES:
                raise _Bad(0, "system", f"unknown satellite system letter {system!r}")
            want = GLONASS_LINES_305 if system == "R" and version >= 3.05 else RECORD_LINES[system]
            if system not in KEPLER_SYSTEMS:
                counts[f"skipped_{system}"] += 1
                if len(group) != want:
                    raise _Bad(0, "record", f"{len(group)} lines, expected {want} for system {system}")
                continue
            if len(group) != want:
                raise _Bad(min(len(group), want - 1), "record",
                           f"{len(group)} lines, expected {want} (truncated or extra lines)")
            row = _parse_record(group, v3, system, prn, epoch)
        except _Bad as bad:
            rejected.append(Rejection(source, line_no + bad.offset, bad.field_name, bad.reason))
            counts["rejected"] += 1
            continue
        rows.append(row)
        sources.append(f"{source}:{line_no}")
        counts["records"] += 1
    data = np.array(rows, dtype=EPH_DTYPE) if rows else np.zeros(0, EPH_DTYPE)
    eph = Ephemerides(data, sources, rejected, counts).deduplicate()
    if rejected:
        shown = "; ".join(str(r) for r in rejected[:3]) + (" ..." if len(rejected) > 3 else "")
        message = f"{source}: rejected {len(rejected)} navigation records/lines (kept {len(rows)}): {shown}"
        if not rows:
            raise UserInputError(f"{source}: no usable navigation record: {shown}")
        log.warning(message)
        warnings.warn(message, RejectedRecordsWarning, stacklevel=3)
    return NavFile(source, version, eph, iono, leap)


def read_rinex_nav(path: str | Path) -> NavFile:
    """Read a RINEX navigation file, plain or compressed (.gz, .Z, .bz2; see `rinex_files`), with
    `parse_rinex_nav`; UserInputError when unreadable."""
    return parse_rinex_nav(read_rinex_text(path, "navigation"), str(path))


def read_rinex_navs(paths) -> Ephemerides:
    """Ephemerides of several navigation files, concatenated and deduplicated."""
    out = Ephemerides.empty()
    for p in paths:
        out = out.concat(read_rinex_nav(p).ephemerides)
    return out.deduplicate()
