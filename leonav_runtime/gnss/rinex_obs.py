"""RINEX 2.10/2.11 and 3.00-3.05 observation files -> `ObservationTable`.

Epochs with flag 0 (and 1, power failure before the epoch: rows get FLAG_POWER_FAILURE)
become rows; flags 2-5 (events: moving, new site, header information, external event)
are counted and their header lines skipped (a "# / TYPES OF OBSERV" / "SYS / # / OBS
TYPES" inside a flag-4 block replaces the observation types); flag 6 (cycle-slip
records) is counted and skipped.

Bad input: an unreadable epoch line, a field that is not a number, a satellite block cut
short by the next epoch or the end of the file, each becomes a `Rejection` (file, line,
field) and the reader resynchronizes at the next epoch line; blank or zero observations
are missing values (zeros counted). In RINEX 3, an epoch line shorter than its 35 columns
(flag in column 32, satellite count in 33-35) is rejected and its satellites skipped; a blank
line among the satellite lines is rejected and ignored. Unknown versions and non-observation
files raise `UserInputError` naming file, line 1 and the field.

Epoch order: epochs earlier than one before them are counted (`epochs_out_of_order`) and the
rows sorted by time (stable); an epoch whose time repeats an earlier one is rejected by line
and counted (`duplicate_epochs`), the first copy kept.

Time systems: GPS, GAL, QZS, IRN epochs are GPS seconds; BDT + 14 s; GLO (UTC) + the
GPS-UTC leap seconds of the date.
"""
from __future__ import annotations

import logging
import math
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss import rinex_obs_v2
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import Rejection
from leonav_runtime.gnss.observations import ObservationTable
from leonav_runtime.gnss.rinex_files import read_rinex_text
from leonav_runtime.gnss.rinex_obs_fields import Records, build_rows

log = logging.getLogger("leonav.gnss")

SUPPORTED = "RINEX 2.10/2.11 or 3.00-3.05 observation files ('O')"
class RejectedObservationsWarning(UserWarning):
    """Some observation lines or fields were rejected (see `ObservationTable.rejected`)."""


class _Reader:
    def __init__(self, text: str, source: str):
        self.lines = text.splitlines()
        self.source = source
        self.rejected: list[Rejection] = []
        self.counts: Counter = Counter()
        self.recs = Records()   # satellite records; their fields are read at the end, all at once
        self.version = 0.0
        self.file_system = "G"
        self.time_system = "GPS"
        self.types_v2: list[str] = []
        self.types_v3: dict[str, list[str]] = {}
        self.approx = None
        self.glo_slots: dict[int, int] = {}
        self.epoch_lines: dict[float, int] = {}   # GPS time (s) of each observation epoch -> its line index
        self.last_epoch_t = -math.inf

    def reject(self, line_index: int, field_name: str, reason: str) -> None:
        self.rejected.append(Rejection(self.source, line_index + 1, field_name, reason))
        self.counts["rejected"] += 1

    def new_epoch(self, t: float, line_index: int) -> bool:
        """Register the observation epoch at GPS time t (s) of line `line_index` (0-based);
        False when t repeats an earlier epoch's time (rejected, counted `duplicate_epochs`: its
        rows are dropped, the first copy is kept, as RTKLIB's sortobs does). An epoch earlier
        than one before it is counted `epochs_out_of_order`; the table is sorted at the end."""
        first = self.epoch_lines.setdefault(t, line_index)
        if first != line_index:
            self.counts["duplicate_epochs"] += 1
            when = f"{gtime.gps_seconds_to_datetime(t):%Y-%m-%d %H:%M:%S} GPST"
            self.reject(line_index, "epoch", f"time {when} repeats the epoch of line {first + 1}; "
                        "its satellites dropped (the first copy is kept)")
            return False
        if t < self.last_epoch_t:
            self.counts["epochs_out_of_order"] += 1
        self.last_epoch_t = max(self.last_epoch_t, t)
        return True

    # -------------------------------------------------------------- header
    def header(self) -> int:
        lines, src = self.lines, self.source
        if not lines:
            raise UserInputError(f"{src}: empty file (expected {SUPPORTED})")
        first = lines[0]
        if "RINEX VERSION" not in first[60:]:
            raise UserInputError(f"{src}:1: field RINEX VERSION / TYPE: not found in columns 61-80 "
                                 f"(not a RINEX file? expected {SUPPORTED})")
        try:
            self.version = float(first[0:9])
        except ValueError:
            raise UserInputError(f"{src}:1: field RINEX VERSION: {first[0:9].strip()!r} is not a version number") from None
        if not (2.0 <= self.version < 3.06):
            raise UserInputError(f"{src}:1: field RINEX VERSION: version {self.version:g} is not supported "
                                 f"(expected {SUPPORTED})")
        if first[20:21] != "O":
            raise UserInputError(f"{src}:1: field FILE TYPE: {first[20:21]!r} (expected 'O', observation data)")
        self.file_system = first[40:41].strip() or "G"
        if self.file_system == "M":
            self.file_system = "G"  # blank satellite letters in a mixed RINEX 2 file mean GPS
        pending_sys = None
        for i, line in enumerate(lines[1:], start=1):
            label = line[60:].strip()
            if label == "END OF HEADER":
                if not self.types_v2 and not self.types_v3:
                    raise UserInputError(f"{src}: header has no observation types "
                                         f"('# / TYPES OF OBSERV' or 'SYS / # / OBS TYPES')")
                return i + 1
            pending_sys = self._header_line(i, line, label, pending_sys)
        raise UserInputError(f"{src}: no END OF HEADER line (expected a RINEX observation header)")

    def _header_line(self, i: int, line: str, label: str, pending_sys):
        try:
            if label == "# / TYPES OF OBSERV":
                if line[0:6].strip():
                    self.types_v2 = []
                    self._v2_count = int(line[0:6])
                self.types_v2 += [line[10 + 6 * k:12 + 6 * k].strip() for k in range(9)
                                  if line[10 + 6 * k:12 + 6 * k].strip()]
            elif label == "SYS / # / OBS TYPES":
                if line[0:1].strip():
                    pending_sys = line[0]
                    self.types_v3[pending_sys] = []
                    int(line[3:6])
                if pending_sys is None:
                    raise ValueError("continuation line without a system")
                self.types_v3[pending_sys] += [line[7 + 4 * k:10 + 4 * k].strip() for k in range(13)
                                               if line[7 + 4 * k:10 + 4 * k].strip()]
            elif label == "APPROX POSITION XYZ":
                self.approx = np.array([float(line[14 * k:14 * (k + 1)]) for k in range(3)])
            elif label == "TIME OF FIRST OBS":
                self.time_system = line[48:51].strip() or ("GPS" if self.file_system != "R" else "GLO")
            elif label == "GLONASS SLOT / FRQ #":
                for k in range(8):
                    chunk = line[4 + 7 * k:4 + 7 * (k + 1)]
                    if chunk.strip():
                        self.glo_slots[int(chunk[1:3])] = int(chunk[4:7])
        except ValueError as exc:
            self.reject(i, label, f"header line could not be read ({exc}); ignored")
        return pending_sys

    # -------------------------------------------------------------- time
    def to_gps(self, t_sys: float) -> float:
        ts = self.time_system
        if ts == "BDT":
            return float(gtime.bdt_to_gps_seconds(t_sys))
        if ts == "GLO":
            return t_sys + gtime.leap_seconds_at_gps(t_sys + 18)
        return t_sys

    # -------------------------------------------------------------- observations
    def add_epoch(self, t: float, sats: list[str], starts: list[int], types_by_system: dict[str, list[str]],
                  emit: bool, power_failure: bool) -> None:
        """The satellite records of an epoch at GPS time t (s), the first line of each at `starts`
        (0-based indices); emit False: their fields are read (for their rejections) but give no rows."""
        systems = [sat[0] if sat[0].strip() else self.file_system for sat in sats]
        self.recs.add_epoch(t, sats, systems, starts, types_by_system, emit, power_failure, len(self.rejected))

    def field(self, line_index: int, text: str, what: str) -> tuple[float, int, int]:
        """(value, lli, ssi) of one 16-column observation field; NaN when blank or unreadable."""
        if len(text) >= 14:  # fast path, the common case: a complete F14.3 (float() skips blanks)
            try:
                value = float(text[0:14])
            except ValueError:
                pass
            else:
                if math.isfinite(value):
                    lli_c, ssi_c = text[14:15], text[15:16]
                    return value, (int(lli_c) if lli_c.isdigit() else 0), (int(ssi_c) if ssi_c.isdigit() else 0)
        num = text[0:14].strip()
        lli_c, ssi_c = text[14:15].strip(), text[15:16].strip()
        value = math.nan
        if num and len(text.rstrip("\n")) < 14:
            self.reject(line_index, what, f"{num!r} cut short (the line ends inside the F14.3 field)")
        elif num:
            try:
                value = float(num)
            except ValueError:
                self.reject(line_index, what, f"{num!r} is not a number")
            else:
                if not math.isfinite(value):
                    self.reject(line_index, what, f"{num!r} is not a finite number")
                    value = math.nan
        lli = int(lli_c) if lli_c.isdigit() else 0
        ssi = int(ssi_c) if ssi_c.isdigit() else 0
        return value, lli, ssi

    # -------------------------------------------------------------- RINEX 3 body
    def body_v3(self, i: int) -> None:
        lines, n = self.lines, len(self.lines)
        while i < n:
            line = lines[i]
            if not line.strip():
                i += 1
                continue
            if not line.startswith(">"):
                self.reject(i, "epoch", "expected an epoch line starting with '>'; skipped to the next epoch")
                i = self._next_v3_epoch(i + 1)
                continue
            if len(line) < 35:   # the satellite count ends in column 35; a shorter line was cut
                self.reject(i, "epoch", f"epoch line cut at column {len(line)} (expected "
                            "'> yyyy mm dd hh mm ss.sssssss  f nnn', the epoch flag in column 32 and the "
                            "satellite count in columns 33-35); skipped to the next epoch")
                i = self._next_v3_epoch(i + 1)
                continue
            if line[31:32] in ("2", "3", "4", "5") and not line[2:29].strip():
                line = line[:2] + "0001 01 01 00 00  0.0000000" + line[29:]  # blank epoch of an event
            try:
                yy, mo, dd, hh, mi = int(line[2:6]), int(line[7:9]), int(line[10:12]), int(line[13:15]), int(line[16:18])
                sec = float(line[18:29])
                flag = int(line[31])
                nsat = int(line[32:35])
                t = self.to_gps(gtime.calendar_to_seconds(yy, mo, dd, hh, mi, sec)) if flag in (0, 1, 6) else 0.0
            except ValueError as exc:
                self.reject(i, "epoch", f"unreadable epoch line ({exc})")
                i = self._next_v3_epoch(i + 1)
                continue
            if 2 <= flag <= 5:
                self.counts[f"event_flag_{flag}"] += 1
                pending = None
                for k in range(i + 1, min(n, i + 1 + nsat)):
                    label = lines[k][60:].strip()
                    if label == "SYS / # / OBS TYPES":
                        pending = self._header_line(k, lines[k], label, pending)
                i += 1 + nsat
                continue
            if flag == 6:
                self.counts["cycle_slip_records"] += 1
            keep = flag == 6 or nsat == 0 or self.new_epoch(t, i)   # an empty epoch holds no time
            # the satellite lines: up to nsat, stopping at the next epoch; a blank line among them
            # is rejected and not counted as one (the satellites after it are still read)
            sat_lines: list[int] = []
            block_end = i + 1
            while len(sat_lines) < nsat and block_end < n and not lines[block_end].startswith(">"):
                if lines[block_end].strip():
                    sat_lines.append(block_end)
                else:
                    self.reject(block_end, "satellite line", f"blank line inside the {nsat} satellite lines of "
                                f"the epoch of line {i + 1} (expected 'Snn' and the observations); ignored")
                block_end += 1
            if len(sat_lines) < nsat:
                self.reject(block_end if block_end < n else i, "satellite lines",
                            f"{len(sat_lines)} of {nsat} satellite lines before the next epoch/end of file")
            sats, starts = [], []
            for k in sat_lines if keep else ():
                sat = lines[k][0:3]
                if sat[0] not in self.types_v3:
                    self.counts[f"no_obs_types_{sat[0]}"] += 1
                    continue
                sats.append(sat)
                starts.append(k)
            if sats:
                self.add_epoch(t, sats, starts, self.types_v3, flag != 6, flag == 1)
            if keep:
                self.counts["epochs" if flag != 6 else "cycle_slip_epochs"] += 1
            i = block_end

    def _next_v3_epoch(self, i: int) -> int:
        while i < len(self.lines) and not self.lines[i].startswith(">"):
            i += 1
        return i


def parse_rinex_obs(text: str, source: str = "<string>") -> ObservationTable:
    """Parse the text of a RINEX 2/3 observation file; see the module docstring."""
    r = _Reader(text, source)
    first = r.header()
    if r.version < 3:
        rinex_obs_v2.read_body(r, first)
    else:
        r.body_v3(first)
    columns = build_rows(r, r.recs)
    table = ObservationTable(**columns, source=source, rejected=r.rejected, counts=r.counts,
                             approx_position_ecef_m=r.approx)
    if r.counts["epochs_out_of_order"]:
        # consumers group rows by epoch with sorted times (the SPP normal equations per epoch);
        # stable, so the rows of one epoch keep the file's order
        table = table.take(np.argsort(table.t_gps_s, kind="stable"))
    table.counts["rows"] = len(table)
    if r.rejected:
        shown = "; ".join(str(x) for x in r.rejected[:3]) + (" ..." if len(r.rejected) > 3 else "")
        message = f"{source}: {len(r.rejected)} observation lines/fields rejected (kept {len(table)} rows): {shown}"
        log.warning(message)
        warnings.warn(message, RejectedObservationsWarning, stacklevel=3)
    return table


def read_rinex_obs(path: str | Path) -> ObservationTable:
    """Read a RINEX observation file, plain or compressed (.gz, .Z, .bz2, Hatanaka .crx/.YYd and
    those compressed again; see `rinex_files`), with `parse_rinex_obs`."""
    return parse_rinex_obs(read_rinex_text(path, "observation"), str(path))
