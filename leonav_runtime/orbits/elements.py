"""Element sets: load TLE / 3LE / OMM files into one `ElementSet` with a report of bad entries.

A file with some bad entries loads the good ones; every bad entry becomes a
`RejectedEntry` (file, line, name, reason) and is announced once per file through
`warnings` (category `RejectedElementsWarning`) and the `leonav.orbits` logger. A file with
nothing valid raises `UserInputError` naming the file and the first problems.

Limits on hostile input: an element file larger than `max_element_bytes()` (64 MB by
default; raise it with the environment variable LEONAV_MAX_ELEMENT_MB) is refused before
it is read (a TLE entry costs about 1.3 kB of memory once loaded, so 64 MB of 3LE text is
about 400,000 satellites and 0.6 GB). Fields that decode to NaN or infinity are rejected
with the field named; deeply nested JSON/XML and unreadable CSV rows are rejected and
counted (see `omm`).

`load_elements` and `parse_elements_text` keep what they parsed of a large TLE/3LE text (a file,
the built-in constellations) in the user's cache (`element_cache`: keyed by the bytes and the
parser's source; `LEONAV_ELEMENT_CACHE=off` turns it off), so the next parse rebuilds the SGP4
records from checked lines instead of checking every field again (the same set, warnings included).
"""
from __future__ import annotations

import datetime as _dt
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
from sgp4.api import WGS72, Satrec, SatrecArray

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import element_cache as _cache
from leonav_runtime.orbits import omm as _omm
from leonav_runtime.orbits import tle as _tle
from leonav_runtime.orbits.element_checks import (DEFAULT_MAX_ELEMENT_MB, MAX_ELEMENT_MB_ENV,  # noqa: F401
                                                  _check_finite, _too_large, guess_constellation,
                                                  max_element_bytes)


DEFAULT_STALE_AFTER_DAYS = 3.0
_NAME_CHARS = 80  # names are at most 24 characters in a 3LE; longer text is cut in reports
CONSTELLATIONS = ("starlink", "gps", "unknown")


class RejectedElementsWarning(UserWarning):
    """Some entries of an element file were rejected (they are listed in `ElementSet.rejected`)."""


@dataclass(frozen=True)
class RejectedEntry:
    """One entry that could not be loaded.

    `line` is the 1-based line number for TLE/3LE and OMM-CSV text, the 1-based record
    number for OMM JSON/XML (the reason then starts with "record N").
    """

    source: str
    line: int
    name: str
    reason: str

    def __str__(self) -> str:
        label = f" ({self.name})" if self.name else ""
        return f"{self.source}:{self.line}{label}: {self.reason}"


@dataclass
class ElementSet:
    """SGP4 element sets of many satellites, in file order.

    Attributes: `names`, `norad_ids` (int array), `epochs_utc` (tz-aware UTC datetimes of
    the element epochs), `satrecs` (sgp4 `Satrec`, WGS-72), `sources` ("file:line" of each
    entry), `rejected` (entries that failed to load), `constellation` ("starlink", "gps"
    or "unknown"), `stale_after_days` (age beyond which propagation warns).
    """

    names: list[str]
    norad_ids: np.ndarray
    epochs_utc: list[_dt.datetime]
    satrecs: list[Satrec]
    sources: list[str]
    rejected: list[RejectedEntry] = field(default_factory=list)
    constellation: str = "unknown"
    stale_after_days: float = DEFAULT_STALE_AFTER_DAYS
    _satrec_array: SatrecArray | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.norad_ids = np.asarray(self.norad_ids, dtype=np.int64).reshape(-1)
        n = len(self.names)
        if not (len(self.norad_ids) == len(self.epochs_utc) == len(self.satrecs) == len(self.sources) == n):
            raise ValueError("ElementSet fields must all have one entry per satellite")

    def __len__(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        return (f"ElementSet({len(self)} satellites, constellation={self.constellation!r}, "
                f"{len(self.rejected)} rejected)")

    @property
    def satrec_array(self) -> SatrecArray:
        """The vectorized SGP4 object over all satellites (built once, cached)."""
        if self._satrec_array is None:
            self._satrec_array = SatrecArray(self.satrecs)
        return self._satrec_array

    def select(self, indices_or_mask: Sequence[int] | np.ndarray | slice) -> "ElementSet":
        """Subset by integer indices, a boolean mask or a slice (rejected entries are kept)."""
        index = np.arange(len(self))[indices_or_mask]
        index = np.atleast_1d(index)
        return ElementSet(
            names=[self.names[i] for i in index],
            norad_ids=self.norad_ids[index],
            epochs_utc=[self.epochs_utc[i] for i in index],
            satrecs=[self.satrecs[i] for i in index],
            sources=[self.sources[i] for i in index],
            rejected=list(self.rejected),
            constellation=self.constellation,
            stale_after_days=self.stale_after_days,
        )

    def concat(self, other: "ElementSet") -> "ElementSet":
        """Both sets, self first; constellation kept when equal, else 'unknown'."""
        return ElementSet(
            names=self.names + other.names,
            norad_ids=np.concatenate([self.norad_ids, other.norad_ids]),
            epochs_utc=self.epochs_utc + other.epochs_utc,
            satrecs=self.satrecs + other.satrecs,
            sources=self.sources + other.sources,
            rejected=self.rejected + other.rejected,
            constellation=self.constellation if self.constellation == other.constellation else "unknown",
            stale_after_days=min(self.stale_after_days, other.stale_after_days),
        )

    def epoch_jd(self) -> tuple[np.ndarray, np.ndarray]:
        """Element epochs as split Julian dates (whole, fraction), UTC, from the SGP4 records."""
        whole = np.array([s.jdsatepoch for s in self.satrecs], dtype=float)
        frac = np.array([s.jdsatepochF for s in self.satrecs], dtype=float)
        return whole, frac

    def ages_s(self, epoch_utc: _dt.datetime) -> np.ndarray:
        """Scenario epoch minus element epoch for every satellite, s (positive = elements older)."""
        jd_whole, jd_frac = julian_date_split(epoch_utc)
        sat_whole, sat_frac = self.epoch_jd()
        return ((jd_whole - sat_whole) + (jd_frac - sat_frac)) * 86400.0


def as_utc(epoch: _dt.datetime) -> _dt.datetime:
    """A tz-aware UTC datetime; naive datetimes are taken to be UTC already."""
    if epoch.tzinfo is None:
        return epoch.replace(tzinfo=_dt.timezone.utc)
    return epoch.astimezone(_dt.timezone.utc)


def julian_date_split(epoch_utc: _dt.datetime) -> tuple[float, float]:
    """(whole, fraction) UTC Julian date: whole is the JD of the preceding 0h (ends in .5)."""
    epoch = as_utc(epoch_utc)
    midnight = epoch.replace(hour=0, minute=0, second=0, microsecond=0)
    whole = midnight.toordinal() + 1721424.5  # toordinal(1 Jan 1 AD) = 1 -> JD 1721425.5
    frac = (epoch - midnight) / _dt.timedelta(days=1)
    return float(whole), float(frac)


# --------------------------------------------------------------------------- parsing


def _parse_tle_text(text: str, source: str, strict_checksum: bool = True
                    ) -> tuple[list[tuple], list[RejectedEntry]]:
    """TLE (2-line) and 3LE (name + 2 lines) text -> entries and rejections.

    Each corrupted entry yields exactly one RejectedEntry, at the line where it broke.
    With strict_checksum=False, entries whose only fault is the checksum load, and their
    line numbers are logged as a warning.
    """
    checksum_only: list[int] = []
    entries: list[tuple] = []
    rejected: list[RejectedEntry] = []
    name, name_line = "", 0
    name_waiting = False  # a name line was read and no element line has followed yet
    pending: tuple[int, str] | None = None  # (line number, text) of a line 1 waiting for line 2
    swallow_next_line2 = False  # a bad line 1 was already reported: its line 2 belongs to it

    def reject(line_no: int, reason: str) -> None:
        rejected.append(RejectedEntry(source, line_no, name, reason))

    for line_no, raw in enumerate(text.splitlines(), start=1):
        line = raw.rstrip()
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if not _tle.is_element_line(line):
            if pending is not None:
                reject(pending[0], f"line 1 is not followed by line 2 (line {line_no} is a name line)")
                pending = None
            elif name_waiting:
                reject(name_line, f"name line is not followed by element lines (line {line_no} is text)")
            swallow_next_line2 = False
            text_name = line.strip()
            name = (text_name[2:].strip() if text_name.startswith("0 ") else text_name)[:_NAME_CHARS]
            name_line, name_waiting = line_no, True
            continue
        name_waiting = False
        number = line[0]
        if number == "1":
            if pending is not None:
                reject(pending[0], f"line 1 is not followed by line 2 (line {line_no} is another line 1)")
            pending = (line_no, line)
            swallow_next_line2 = False
        elif number == "2":
            if pending is None:
                if not swallow_next_line2:
                    reject(line_no, "line 2 without a line 1 before it")
                swallow_next_line2 = False
                name = ""
                continue
            l1_no, l1 = pending
            pending = None
            try:
                fields = _tle.parse_fields(l1, line, verify_checksum=strict_checksum)
                _check_finite(fields)
                satrec = Satrec.twoline2rv(l1[:69], line[:69], WGS72)
            except _tle.TLEFieldError as exc:
                reject(line_no if exc.which_line == 2 else l1_no, str(exc))
            except ValueError as exc:  # sgp4's own reader disagreed with ours
                reject(l1_no, f"SGP4 could not read the element lines: {exc}")
            else:
                if not strict_checksum and (_tle.checksum(l1) != int(l1[68]) or _tle.checksum(line) != int(line[68])):
                    checksum_only.append(l1_no)
                # the two checked lines and line 1's number follow: what the element cache keeps
                entries.append((name or str(fields.norad_id), fields.norad_id, fields.epoch_utc, satrec,
                                f"{source}:{l1_no}", l1[:69], line[:69], l1_no))
            name = ""
        else:
            if pending is not None:
                reject(line_no, f"wrong line number {number!r}: expected line 2 after line 1 at line {pending[0]}")
                pending = None
                name = ""
            else:
                reject(line_no, f"wrong line number {number!r}: expected line 1")
                swallow_next_line2 = True
    if pending is not None:
        reject(pending[0], "line 1 is not followed by line 2 (end of file)")
    elif name_waiting:
        reject(name_line, "name line is not followed by element lines (end of file)")
    if checksum_only:
        message = (f"{source}: {len(checksum_only)} entries loaded despite a bad checksum "
                   f"(strict_checksum=False), lines {', '.join(map(str, checksum_only))}")
        warnings.warn(message, RejectedElementsWarning, stacklevel=4)
    return entries, rejected


def _parse_omm_text(text: str, fmt: str, source: str) -> tuple[list[tuple], list[RejectedEntry]]:
    entries: list[tuple] = []
    rejected: list[RejectedEntry] = []
    try:
        for record in _omm.iter_records(text, fmt):
            prefix = "" if fmt == "csv" else f"{record.where}: "
            name = record.fields.get("OBJECT_NAME", "")[:_NAME_CHARS]
            if record.problem:
                rejected.append(RejectedEntry(source, record.line, name, f"OMM {fmt.upper()} {record.problem}"))
                continue
            try:
                name, norad_id, epoch, satrec = _omm.record_to_satrec(record.fields)
            except _omm.OMMRecordError as exc:
                rejected.append(RejectedEntry(source, record.line, name, f"OMM {fmt.upper()} {prefix}{exc}"))
            else:
                entries.append((name, norad_id, epoch, satrec, f"{source}:{record.line}"))
    except _omm.OMMRecordError as exc:
        raise UserInputError(f"{source}: OMM {fmt.upper()} file could not be read: {exc}") from None
    return entries, rejected


def parse_elements_text(
    text: str,
    source: str = "<string>",
    *,
    stale_after_days: float = DEFAULT_STALE_AFTER_DAYS,
    constellation: str | None = None,
    strict_checksum: bool = True,
) -> ElementSet:
    """Parse TLE / 3LE / OMM (XML, JSON, CSV) text, auto-detected.

    Good entries load; bad ones are listed in `.rejected` and announced with a warning.
    Raises UserInputError (naming `source`) when the text is empty or nothing is valid.
    `constellation` overrides the guess from the names. `strict_checksum=False` loads TLE
    entries whose checksum is wrong but are otherwise valid (hand-edited test sets such as
    Vallado's SGP4-VER.TLE), with a warning listing their lines.
    """
    if strict_checksum and _cache.wanted(len(text)):    # a large text (the built-in constellations) parsed before
        return _parse_cached(text.encode("utf-8", errors="replace"), source, stale_after_days, constellation,
                             stacklevel=4)
    entries, rejected, kind = _parse_text(text, source, strict_checksum)
    return _element_set(entries, rejected, kind, source, stale_after_days, constellation, stacklevel=4)


def _parse_cached(data: bytes, source: str, stale_after_days: float, constellation: str | None,
                  stacklevel: int) -> ElementSet:
    """Parse element bytes (strict checksums; bad bytes become U+FFFD, their entries rejected)
    through the element cache: the same bytes parsed before come from it, a TLE/3LE text is stored."""
    hit = _cache.lookup(key := _cache.cache_key(data, {"strict_checksum": True}))
    if hit is None:
        entries, rejected, kind = _parse_text(data.decode("utf-8", errors="replace"), source, True)
        if kind == "TLE/3LE":
            _cache.store(key, [(e[0], e[1], e[2], e[5], e[6], e[7]) for e in entries],
                         [(r.line, r.name, r.reason) for r in rejected])
    else:
        entries = [(name, norad, epoch, satrec, f"{source}:{line}") for name, norad, epoch, satrec, line in hit[0]]
        rejected = [RejectedEntry(source, line, name, reason) for line, name, reason in hit[1]]
        kind = "TLE/3LE"
    return _element_set(entries, rejected, kind, source, stale_after_days, constellation, stacklevel=stacklevel + 1)


def _parse_text(text: str, source: str, strict_checksum: bool) -> tuple[list[tuple], list[RejectedEntry], str]:
    """(entries, rejected, 'TLE/3LE' or 'OMM ...') of element text, auto-detected."""
    limit = max_element_bytes()
    if len(text) > limit:
        raise _too_large(source, len(text), limit)
    if not text.strip():
        raise UserInputError(f"{source}: empty element file (expected TLE/3LE lines or an OMM XML/JSON/CSV file)")
    fmt = _omm.detect_omm_format(text)
    if fmt is None:
        entries, rejected = _parse_tle_text(text, source, strict_checksum)
        return entries, rejected, "TLE/3LE"
    entries, rejected = _parse_omm_text(text, fmt, source)
    return entries, rejected, f"OMM {fmt.upper()}"


def _element_set(entries: list[tuple], rejected: list[RejectedEntry], kind: str, source: str,
                 stale_after_days: float, constellation: str | None, stacklevel: int) -> ElementSet:
    """The ElementSet of parsed entries; warns about rejected ones (`stacklevel` counted from here)."""
    if not entries:
        detail = "; ".join(str(r) for r in rejected[:3]) or "no element lines found"
        more = f" (and {len(rejected) - 3} more)" if len(rejected) > 3 else ""
        raise UserInputError(f"{source}: no valid {kind} element set: {detail}{more}")
    if rejected:
        lines = ", ".join(str(r.line) for r in rejected[:20]) + (" ..." if len(rejected) > 20 else "")
        message = (f"{source}: rejected {len(rejected)} of {len(rejected) + len(entries)} entries "
                   f"(lines {lines}); first: {rejected[0].reason}")
        warnings.warn(message, RejectedElementsWarning, stacklevel=stacklevel)
    names = [e[0] for e in entries]
    if constellation is not None and constellation not in CONSTELLATIONS:
        raise UserInputError(f"constellation {constellation!r}: expected one of {', '.join(CONSTELLATIONS)}")
    return ElementSet(
        names=names,
        norad_ids=np.array([e[1] for e in entries], dtype=np.int64),
        epochs_utc=[e[2] for e in entries],
        satrecs=[e[3] for e in entries],
        sources=[e[4] for e in entries],
        rejected=rejected,
        constellation=constellation or guess_constellation(names),
        stale_after_days=stale_after_days,
    )


def load_elements(
    path: str | Path,
    *,
    stale_after_days: float = DEFAULT_STALE_AFTER_DAYS,
    constellation: str | None = None,
    strict_checksum: bool = True,
) -> ElementSet:
    """Load a TLE / 3LE / OMM (XML, JSON, CSV) file; see `parse_elements_text`."""
    path = Path(path)
    limit = max_element_bytes()
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > limit:
                raise _too_large(str(path), size, limit)
            data = fh.read(limit + 1)  # bounded also for pipes and devices, whose size says nothing
    except FileNotFoundError:
        raise UserInputError(f"{path}: element file not found") from None
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, expected a TLE/3LE/OMM file") from None
    if len(data) > limit:
        raise _too_large(str(path), len(data), limit)
    source = str(path)
    # a TLE/3LE file parsed before (same bytes, same parser) comes from the element cache; not with
    # strict_checksum=False, whose entries with a bad checksum are announced at every load
    if strict_checksum and _cache.wanted(len(data)):
        return _parse_cached(data, source, stale_after_days, constellation, stacklevel=3)
    text = data.decode("utf-8", errors="replace")  # bad bytes become U+FFFD: their entries are rejected
    del data
    entries, rejected, kind = _parse_text(text, source, strict_checksum)
    return _element_set(entries, rejected, kind, source, stale_after_days, constellation, stacklevel=3)


def load_element_files(paths: Sequence[str | Path], option: str = "--tle") -> ElementSet | None:
    """Load and concatenate several element files (None for no paths); `option` names the
    command-line option in errors (a missing file, or files that give no usable element set)."""
    es = None
    for path in paths:
        if not Path(path).is_file():
            raise UserInputError(f"{option}: {path}: no such file")
        loaded = load_elements(path)
        es = loaded if es is None else es.concat(loaded)
    if paths and (es is None or len(es) == 0):
        raise UserInputError(f"{option}: no usable element sets in {', '.join(map(str, paths))}")
    return es

