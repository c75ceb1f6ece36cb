"""Starlink operator ephemerides: read, validate and write the operator's public text files.

Format (one satellite per file, listed in the folder's MANIFEST.txt; see docs/ephemerides.md
for where each fact was confirmed):

    created:2026-09-11 01:55:52 UTC
    ephemeris_start:2026-09-11 01:42:42 UTC ephemeris_stop:2026-09-14 01:42:42 UTC step_size:60
    ephemeris_source:blend
    UVW
    YYYYDDDhhmmss.sss x y z vx vy vz          (UTC; EME2000 km, km/s)
    c11 c21 c22 c31 c32 c33 c41               (lower triangle of the 6 x 6 [r, v] covariance,
    c42 c43 c44 c51 c52 c53 c54                row by row, in the UVW frame: radial, in-track,
    c55 c61 c62 c63 c64 c65 c66                cross-track; km^2, km^2/s, km^2/s^2)
    ... one 4-line record per step_size seconds

In memory everything is SI: m, m/s, m^2. Validation is strict: a file that is cut, garbled,
out of time order, off its declared step or missing covariance numbers is refused with one
line naming the file, the line and what was expected (`UserInputError`); a folder loads the
files that pass and counts the rest (`OperatorEphemerisSet.rejected`). `write_text` writes the
same layout with the operator's number formats, so a parsed file is written back byte for
byte and a written file parses back to the same arrays.
"""
from __future__ import annotations

import datetime as _dt
import math
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits.element_checks import MAX_ELEMENT_MB_ENV, max_element_bytes

KM = 1000.0
COVARIANCE_FRAMES = ("UVW",)              # the frame the operator publishes; others are refused
_TRIL = np.tril_indices(6)                 # row-major lower triangle: (0,0) (1,0) (1,1) (2,0) ...
_EPOCH_RE = re.compile(r"^(\d{4})(\d{3})(\d{2})(\d{2})(\d{2})\.(\d{3})$")
_HEADER_TIME = "%Y-%m-%d %H:%M:%S"
_SPAN_RE = re.compile(r"^ephemeris_start:(.*?) UTC ephemeris_stop:(.*?) UTC step_size:(\S+)$")
_STATE_FIELDS = ("x", "y", "z", "vx", "vy", "vz")
_NUMBER_RE = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$", re.ASCII)
_STEP_TOL_MS = 1                           # epochs are written to the millisecond
MANIFEST = "MANIFEST.txt"


class RejectedEphemerisWarning(UserWarning):
    """Some files of an operator-ephemeris folder were refused (listed in `rejected`)."""


@dataclass
class OperatorEphemeris:
    """One satellite's operator ephemeris (SI units).

    t_ms: (n,) int64 milliseconds since start_utc (the first epoch); r_eme2000_m, v_eme2000_mps
    (n, 3) EME2000 (J2000 mean equator and equinox) states; cov_uvw (n, 6, 6) covariance of
    [r, v] in the satellite's UVW axes (U radial, V in-track, W cross-track; m^2, m^2/s,
    m^2/s^2). step_s: the header's step. name: the object name from the file name (e.g.
    STARLINK-38128) or "" when the name carries none."""

    source: str
    name: str
    created_utc: _dt.datetime | None
    start_utc: _dt.datetime
    stop_utc: _dt.datetime
    step_s: float
    ephemeris_source: str
    covariance_frame: str
    t_ms: np.ndarray
    r_eme2000_m: np.ndarray
    v_eme2000_mps: np.ndarray
    cov_uvw: np.ndarray

    def __len__(self) -> int:
        return int(self.t_ms.size)

    def seconds_since(self, epoch_utc: _dt.datetime) -> np.ndarray:
        """(n,) the record epochs as UTC seconds since epoch_utc."""
        return (self.start_utc - epoch_utc).total_seconds() + self.t_ms * 1e-3


@dataclass
class OperatorEphemerisSet:
    """The ephemerides of a folder (or of several files), by object name, with the refused
    files as (file, one-line reason)."""

    ephemerides: dict[str, OperatorEphemeris]
    rejected: list[tuple[str, str]] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return list(self.ephemerides)


def name_from_filename(path: str | Path) -> str:
    """The object name of an operator file name MEME_<serial>_<NAME>_<...>.txt ("" if none)."""
    parts = Path(path).name.split("_")
    return parts[2] if len(parts) >= 4 and parts[0] in ("MEME", "TEME", "ITRF") else ""


# --------------------------------------------------------------------------- reading


def _fail(source: str, line: int, what: str) -> UserInputError:
    return UserInputError(f"{source} line {line}: {what}")


def _header_time(source: str, line: int, label: str, text: str) -> _dt.datetime:
    try:
        return _dt.datetime.strptime(text.strip(), _HEADER_TIME).replace(tzinfo=_dt.timezone.utc)
    except ValueError:
        raise _fail(source, line, f"{label} {text.strip()!r} is not a time; expected YYYY-MM-DD hh:mm:ss UTC") from None


def _epoch(source: str, line: int, text: str) -> _dt.datetime:
    m = _EPOCH_RE.match(text)
    if m is None:
        raise _fail(source, line, f"epoch {text!r} is not YYYYDDDhhmmss.sss")
    year, doy, hh, mm, ss, ms = (int(g) for g in m.groups())
    days_in_year = 366 if (year % 4 == 0 and (year % 100 != 0 or year % 400 == 0)) else 365
    if not (1 <= doy <= days_in_year and hh < 24 and mm < 60 and ss < 60):
        raise _fail(source, line, f"epoch {text!r} has a day of year, hour, minute or second out of range")
    return _dt.datetime(year, 1, 1, hh, mm, ss, ms * 1000, tzinfo=_dt.timezone.utc) + _dt.timedelta(days=doy - 1)


def _numbers(source: str, line: int, fields: list[str], labels: Sequence[str], what: str,
             first: int = 1) -> list[float]:
    """Finite floats of `fields`; `first`: the 1-based field number of fields[0] on its line."""
    if len(fields) != len(labels):
        raise _fail(source, line, f"expected {len(labels)} numbers ({what}), found {len(fields)}")
    out = []
    for k, (text, label) in enumerate(zip(fields, labels)):
        # plain decimal notation only: float() would also take '1_0', 'nan' and non-ASCII digits
        value = float(text) if _NUMBER_RE.match(text) else math.nan
        if not math.isfinite(value):
            raise _fail(source, line, f"field {k + first} ({label}) {text!r} is not a finite number")
        out.append(value)
    return out


def _cov_labels(row: int) -> list[str]:
    pairs = list(zip(*_TRIL))[7 * row: 7 * row + 7]
    return [f"c{i + 1}{j + 1}" for i, j in pairs]


def parse_text(text: str, source: str = "<text>", name: str = "") -> OperatorEphemeris:
    """Parse one operator file's text; `UserInputError` naming `source`, the line and what
    was expected on the first problem."""
    lines = text.splitlines()
    if len(lines) < 4:
        raise _fail(source, len(lines) + 1, "file ends inside the header; expected 4 header lines "
                    "(created:, ephemeris_start: ... step_size:, ephemeris_source:, covariance frame)")
    if not lines[0].startswith("created:"):
        raise _fail(source, 1, f"expected 'created:YYYY-MM-DD hh:mm:ss UTC', found {lines[0][:60]!r}")
    created_text = lines[0][len("created:"):].strip()
    created = None
    if created_text:
        if not created_text.endswith(" UTC"):
            raise _fail(source, 1, f"created time {created_text!r} must end in ' UTC'")
        created = _header_time(source, 1, "created", created_text[:-4])
    span = _SPAN_RE.match(lines[1].strip())
    if span is None:
        raise _fail(source, 2, "expected 'ephemeris_start:<time> UTC ephemeris_stop:<time> UTC step_size:<s>', "
                    f"found {lines[1][:80]!r}")
    start = _header_time(source, 2, "ephemeris_start", span.group(1))
    stop = _header_time(source, 2, "ephemeris_stop", span.group(2))
    try:
        step_s = float(span.group(3))
    except ValueError:
        step_s = math.nan
    if not (math.isfinite(step_s) and step_s > 0):
        raise _fail(source, 2, f"step_size {span.group(3)!r} is not a positive number of seconds")
    if not lines[2].startswith("ephemeris_source:"):
        raise _fail(source, 3, f"expected 'ephemeris_source:<text>', found {lines[2][:60]!r}")
    frame = lines[3].strip()
    if frame not in COVARIANCE_FRAMES:
        raise _fail(source, 4, f"covariance frame {frame!r} is not supported; expected one of {', '.join(COVARIANCE_FRAMES)}")

    body = lines[4:]
    while body and not body[-1].strip():       # a trailing newline or blank lines end the file
        body.pop()
    if not body:
        raise _fail(source, 5, "no records after the header; expected 'YYYYDDDhhmmss.sss x y z vx vy vz'")
    epochs: list[_dt.datetime] = []
    states: list[list[float]] = []
    covs: list[list[float]] = []
    i = 0
    while i < len(body):
        ln = i + 5                              # 1-based line number in the file
        fields = body[i].split()
        if not fields or _EPOCH_RE.match(fields[0]) is None:
            raise _fail(source, ln, f"expected a state line 'YYYYDDDhhmmss.sss x y z vx vy vz', found {body[i][:60]!r}")
        epoch = _epoch(source, ln, fields[0])
        state = _numbers(source, ln, fields[1:], _STATE_FIELDS, "x y z in km and vx vy vz in km/s", first=2)
        if epochs and epoch <= epochs[-1]:
            raise _fail(source, ln, f"epoch {fields[0]} is not after the previous record's "
                        f"{epochs[-1].strftime('%Y-%m-%d %H:%M:%S.%f')[:-3]} UTC (epochs must increase)")
        cov: list[float] = []
        for row in range(3):
            cl = ln + 1 + row
            if i + 1 + row >= len(body):
                raise _fail(source, cl, f"file ends inside the record of line {ln}: expected covariance line "
                            f"{row + 1} of 3 (7 numbers each, 21 in all)")
            cfields = body[i + 1 + row].split()
            if cfields and _EPOCH_RE.match(cfields[0]):
                raise _fail(source, cl, f"found a state line where covariance line {row + 1} of 3 of the record "
                            f"of line {ln} was expected (21 covariance numbers per record)")
            cov += _numbers(source, cl, cfields, _cov_labels(row), f"covariance line {row + 1} of 3")
        for k, (a, b) in enumerate(zip(*_TRIL)):
            if a == b and cov[k] < 0:
                raise _fail(source, ln + 1 + k // 7, f"variance c{a + 1}{b + 1} = {cov[k]:g} is negative")
        epochs.append(epoch)
        states.append(state)
        covs.append(cov)
        i += 4

    t_ms = np.array([round((e - epochs[0]).total_seconds() * 1000) for e in epochs], dtype=np.int64)
    _check_span(source, epochs, t_ms, start, stop, step_s)
    state_arr = np.array(states) * KM
    cov_uvw = np.zeros((len(covs), 6, 6))
    cov_uvw[:, _TRIL[0], _TRIL[1]] = np.array(covs) * (KM * KM)
    cov_uvw[:, _TRIL[1], _TRIL[0]] = cov_uvw[:, _TRIL[0], _TRIL[1]]
    return OperatorEphemeris(source, name, created, start, stop, step_s, lines[2][len("ephemeris_source:"):],
                             frame, t_ms, state_arr[:, 0:3], state_arr[:, 3:6], cov_uvw)


def _check_span(source: str, epochs: list[_dt.datetime], t_ms: np.ndarray, start: _dt.datetime,
                stop: _dt.datetime, step_s: float) -> None:
    """The records must run from ephemeris_start to ephemeris_stop at step_size."""
    def line_of(k: int) -> int:
        return 5 + 4 * k
    if abs((epochs[0] - start).total_seconds()) * 1000 > _STEP_TOL_MS:
        raise _fail(source, 5, f"first epoch {epochs[0]:%Y-%m-%d %H:%M:%S} UTC is not the header's "
                    f"ephemeris_start {start:%Y-%m-%d %H:%M:%S} UTC (line 2)")
    gaps = np.diff(t_ms)
    off = np.flatnonzero(np.abs(gaps - step_s * 1000) > _STEP_TOL_MS)
    if off.size:
        k = int(off[0]) + 1
        raise _fail(source, line_of(k), f"epoch is {gaps[k - 1] / 1000:g} s after the previous one; "
                    f"expected the header's step_size of {step_s:g} s (a record missing?)")
    late_ms = (epochs[-1] - stop).total_seconds() * 1000
    if late_ms < -_STEP_TOL_MS:
        raise _fail(source, line_of(len(epochs) - 1) + 3,
                    f"file ends at epoch {epochs[-1]:%Y-%m-%d %H:%M:%S} UTC but its header (line 2) declares "
                    f"ephemeris_stop {stop:%Y-%m-%d %H:%M:%S} UTC (truncated file?)")
    if late_ms > _STEP_TOL_MS:
        k = int(np.searchsorted(t_ms, (stop - epochs[0]).total_seconds() * 1000 + _STEP_TOL_MS, side="right"))
        raise _fail(source, line_of(k), f"epoch {epochs[k]:%Y-%m-%d %H:%M:%S} UTC is after the header's "
                    f"ephemeris_stop {stop:%Y-%m-%d %H:%M:%S} UTC (line 2)")


def load_file(path: str | Path) -> OperatorEphemeris:
    """Read one operator file (size-limited like element files); the name comes from the file name."""
    path = Path(path)
    try:
        size = path.stat().st_size
        limit = max_element_bytes()
        if size > limit:
            raise UserInputError(
                f"{path}: {size / 1e6:.1f} MB is more than the orbit-file limit of {limit / 1e6:g} MB (a 72 h "
                f"operator ephemeris is about 2 MB; set {MAX_ELEMENT_MB_ENV} to a larger number of megabytes)")
        raw = path.read_bytes()
    except OSError as exc:
        raise UserInputError(f"{path}: cannot read the operator ephemeris ({exc.strerror or exc})") from None
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise _fail(str(path), line, "a byte that is not ASCII text; expected an operator ephemeris text file") from None
    return parse_text(text, str(path), name_from_filename(path))


def load_folder(folder: str | Path, names: Sequence[str] | None = None) -> OperatorEphemerisSet:
    """Read the files a folder's MANIFEST.txt lists (every *.txt but the manifest without one),
    only those of `names` when given. Bad files are refused and counted, one warning for all;
    a folder with nothing usable is a `UserInputError`."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserInputError(f"{folder}: not a folder of operator ephemerides (expected MANIFEST.txt and MEME_*.txt files)")
    manifest = folder / MANIFEST
    if manifest.exists():
        listed = [ln.strip() for ln in manifest.read_text(encoding="ascii", errors="replace").splitlines() if ln.strip()]
    else:
        listed = sorted(p.name for p in folder.glob("*.txt"))
    wanted = None if names is None else set(names)
    out = OperatorEphemerisSet({})
    for k, entry in enumerate(listed):
        if "/" in entry or "\\" in entry or entry.startswith("."):
            out.rejected.append((f"{manifest} line {k + 1}", f"{entry!r} is not a file name in the folder"))
            continue
        name = name_from_filename(entry)
        if wanted is not None and name not in wanted:
            continue
        try:
            eph = load_file(folder / entry)
        except UserInputError as exc:
            out.rejected.append((entry, str(exc)))
            continue
        key = eph.name or entry
        if key in out.ephemerides:
            out.rejected.append((entry, (f"{folder / entry}: a second file for {key} "
                                 f"(first: {out.ephemerides[key].source}); the first is kept")))
            continue
        out.ephemerides[key] = eph
    if out.rejected:
        warnings.warn(f"{folder}: {len(out.rejected)} operator-ephemeris file(s) refused; first: {out.rejected[0][1]}",
                      RejectedEphemerisWarning, stacklevel=2)
    if not out.ephemerides:
        what = f" for {', '.join(sorted(wanted)[:5])}" if wanted else ""
        first = f"; first refusal: {out.rejected[0][1]}" if out.rejected else ""
        raise UserInputError(f"{folder}: no usable operator ephemeris{what} "
                             f"({len(listed)} listed, {len(out.rejected)} refused){first}")
    return out


# --------------------------------------------------------------------------- writing


def _epoch_text(epoch: _dt.datetime) -> str:
    doy = epoch.timetuple().tm_yday
    return f"{epoch.year:04d}{doy:03d}{epoch:%H%M%S}.{epoch.microsecond // 1000:03d}"


def write_text(eph: OperatorEphemeris) -> str:
    """The operator's text layout of `eph` (states with 10 decimals in km and km/s, covariance
    with 11 significant digits in km units, as the operator writes them)."""
    def header_time(t: _dt.datetime) -> str:
        return f"{t:{_HEADER_TIME}} UTC"
    step = f"{eph.step_s:g}"
    out = [f"created:{header_time(eph.created_utc) if eph.created_utc else ''}",
           f"ephemeris_start:{header_time(eph.start_utc)} ephemeris_stop:{header_time(eph.stop_utc)} step_size:{step}",
           f"ephemeris_source:{eph.ephemeris_source}", eph.covariance_frame]
    states = np.concatenate([eph.r_eme2000_m, eph.v_eme2000_mps], axis=1) / KM
    tril = eph.cov_uvw[:, _TRIL[0], _TRIL[1]] / (KM * KM)
    for k in range(len(eph)):
        epoch = eph.start_utc + _dt.timedelta(milliseconds=int(eph.t_ms[k]))
        out.append(_epoch_text(epoch) + " " + " ".join(f"{x:.10f}" for x in states[k]))
        for row in range(3):
            out.append(" ".join(f"{c:.10e}" for c in tril[k, 7 * row: 7 * row + 7]))
    return "\n".join(out) + "\n"


def write_file(eph: OperatorEphemeris, folder: str | Path, serial: int = 0) -> Path:
    """Write `eph` into folder as MEME_<serial>_<name>_..._UNCLASSIFIED.txt and list it in the
    folder's MANIFEST.txt; returns the path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = eph.name or "UNNAMED"
    stamp = f"{eph.start_utc.timetuple().tm_yday:03d}{eph.start_utc:%H%M}"   # DDDhhmm of the start, as published
    path = folder / f"MEME_{serial}_{name}_{stamp}_Operational_0_UNCLASSIFIED.txt"
    path.write_text(write_text(eph), encoding="ascii")
    manifest = folder / MANIFEST
    listed = manifest.read_text(encoding="ascii").splitlines() if manifest.exists() else []
    if path.name not in listed:
        manifest.write_text("\n".join([*listed, path.name]) + "\n", encoding="ascii")
    return path
