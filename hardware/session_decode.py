"""Decoding a recorded session again from its raw logs and chunk stamps (what `leonav replay` reads)."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

from hardware.clock import TimeMap
from hardware.errors import UserInputError
from hardware.gnss.reader import GnssDecoder
from hardware.imu.witmotion import SampleGrouper, WitMotionParser
from hardware.records import GnssTimeTag, ImuSample
from hardware.session_files import (GNSS_FIX_COLUMNS, GNSS_RAW_COLUMNS, IMU_COLUMNS, CsvSink, fit_time_map, gnss_rows,
                                    imu_row)


def iter_raw_chunks(folder: Path, name: str) -> Iterable[tuple[bytes, float]]:
    """(chunk, t_mono_s) of `<name>.raw` as recorded, using `<name>.chunks.csv`.

    Bytes past the last indexed offset (a run killed between the two writes) come last,
    stamped with the last stamp.
    """
    data = (folder / f"{name}.raw").read_bytes()
    idx_path = folder / f"{name}.chunks.csv"
    start, t_last = 0, math.nan
    if idx_path.exists():
        with open(idx_path) as fh:
            next(fh, None)
            for line_no, line in enumerate(fh, start=2):
                parts = line.strip().split(",")
                if len(parts) != 2:
                    continue          # a line cut by an interrupted write
                try:
                    t_mono, end = float(parts[0]), int(parts[1])
                except ValueError as exc:
                    raise UserInputError(f"{idx_path}:{line_no}: expected 't_mono_s,end_offset' ({exc})") from exc
                end = min(end, len(data))
                if end > start:
                    yield data[start:end], t_mono
                start, t_last = max(start, end), t_mono
    if start < len(data):
        yield data[start:], t_last


@dataclass
class DecodedSession:
    """Everything `decode_session` recovers from a session folder's raw logs."""

    folder: Path
    gnss_records: list = field(default_factory=list)
    imu_samples: list[ImuSample] = field(default_factory=list)
    time_map: TimeMap = field(default_factory=TimeMap)
    gnss_summary: dict = field(default_factory=dict)
    imu_summary: dict = field(default_factory=dict)
    session_info: dict = field(default_factory=dict)

    def write_csvs(self, out: str | Path | None = None) -> Path:
        """gnss_fix.csv, gnss_raw.csv, imu.csv with the *final* time map into `out`."""
        out = Path(out) if out else self.folder
        out.mkdir(parents=True, exist_ok=True)
        utc = (lambda t: float(self.time_map.to_utc_unix(t))) if self.time_map.valid else (lambda t: math.nan)
        sinks: dict[str, CsvSink] = {}
        columns = {"gnss_fix": GNSS_FIX_COLUMNS, "gnss_raw": GNSS_RAW_COLUMNS}
        if self.gnss_records:
            sinks["gnss_fix"] = CsvSink(out / "gnss_fix.csv", GNSS_FIX_COLUMNS)
        for rec in self.gnss_records:
            name, rows = gnss_rows(rec, utc)
            if rows and name not in sinks:
                sinks[name] = CsvSink(out / f"{name}.csv", columns[name])
            for row in rows:
                sinks[name].write(row)
        if self.imu_samples or (self.folder / "imu.raw").exists():
            sinks["imu"] = CsvSink(out / "imu.csv", IMU_COLUMNS)
            for s in self.imu_samples:
                sinks["imu"].write(imu_row(s, utc))
        for sink in sinks.values():
            sink.close()
        return out


def decode_session(folder: str | Path) -> DecodedSession:
    """Re-decode a session from its raw logs and chunk stamps (what `leonav replay` reads)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UserInputError(f"{folder}: not a session folder (expected gnss.raw / imu.raw / session.json)")
    result = DecodedSession(folder)
    info_path = folder / "session.json"
    if info_path.exists():
        try:
            result.session_info = json.loads(info_path.read_text())
        except json.JSONDecodeError as exc:
            raise UserInputError(f"{info_path}: line {exc.lineno}: invalid JSON ({exc.msg})") from exc
    if (folder / "gnss.raw").exists():
        decoder = GnssDecoder()
        for chunk, t_mono in iter_raw_chunks(folder, "gnss"):
            result.gnss_records.extend(decoder.decode(chunk, t_mono))
        result.gnss_records.extend(decoder.close())
        result.gnss_summary = decoder.summary()
        result.time_map = fit_time_map(r for r in result.gnss_records if isinstance(r, GnssTimeTag))
    if (folder / "imu.raw").exists():
        parser, grouper = WitMotionParser(), SampleGrouper()
        for chunk, t_mono in iter_raw_chunks(folder, "imu"):
            for packet in parser.feed(chunk, t_mono):
                result.imu_samples.extend(grouper.push(packet))
        parser.close()
        result.imu_samples.extend(grouper.flush())
        rejected = dict(parser.rejected)
        if grouper.incomplete:
            rejected["incomplete_samples"] = grouper.incomplete
        result.imu_summary = {"accepted": dict(parser.counts) | {"samples": len(result.imu_samples)},
                              "rejected": rejected}
    if not (result.gnss_records or result.imu_samples or (folder / "sdr.cu8").exists()
            or (folder / "gnss.raw").exists() or (folder / "imu.raw").exists()):
        raise UserInputError(f"{folder}: no gnss.raw, imu.raw or sdr.cu8 in this folder")
    return result
