"""Decoding a recorded session again from its raw logs and chunk stamps (what `leonav replay` reads)."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

from leonav.hardware.clock import TimeMap
from leonav.hardware.errors import UserInputError
from leonav.hardware.gnss.reader import GnssDecoder
from leonav.hardware.imu.witmotion import SampleGrouper, WitMotionParser
from leonav.hardware.records import GnssTimeTag, ImuSample
from leonav.hardware.session_files import (GNSS_FIX_COLUMNS, GNSS_RAW_COLUMNS, IMU_COLUMNS, CsvSink, fit_time_map, gnss_rows,
                                    imu_row)


INDEX_HEADER = "t_mono_s,end_offset"
MAX_STAMP_S = 1e10              # a monotonic clock's seconds (since boot): far below 317 years
MAX_SESSION_JSON_BYTES = 16_000_000


def _text(path: Path, what: str) -> str:
    try:
        return path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: not UTF-8 text (byte {exc.start}); expected {what}") from None


def read_chunk_index(folder: Path, name: str) -> list[tuple[int, float]]:
    """(end_offset, t_mono_s) of every chunk of `<name>.raw`, from `<name>.chunks.csv`.

    UserInputError naming the file and line for a missing index, a line that is not two
    numbers, a stamp that is not finite (or beyond MAX_STAMP_S) or goes back in time, and an
    offset that goes back. A last line without its line end (cut by a stop between the two
    writes of a chunk) is ignored."""
    idx_path = folder / f"{name}.chunks.csv"
    if not idx_path.is_file():
        raise UserInputError(f"{idx_path}: missing; the arrival stamps of {name}.raw are needed to place its "
                             f"records in time (expected lines '{INDEX_HEADER}')")
    lines = _text(idx_path, f"'{INDEX_HEADER}' lines").split("\n")
    if lines[0].strip() != INDEX_HEADER:
        raise UserInputError(f"{idx_path}:1: expected the header '{INDEX_HEADER}', got {lines[0][:40]!r}")
    out: list[tuple[int, float]] = []
    for line_no, line in enumerate(lines[1:-1], start=2):   # lines[-1]: '' or a line cut short
        parts = line.strip().split(",")
        try:
            t_mono, end = float(parts[0]), int(parts[1])
            if len(parts) != 2:
                raise ValueError(f"{len(parts)} fields")
        except (ValueError, IndexError) as exc:
            raise UserInputError(f"{idx_path}:{line_no}: expected '{INDEX_HEADER}' numbers, got {line[:60]!r} "
                                 f"({exc})") from None
        prev_t, prev_end = out[-1][1] if out else -MAX_STAMP_S, out[-1][0] if out else 0
        if not abs(t_mono) < MAX_STAMP_S:
            raise UserInputError(f"{idx_path}:{line_no}: t_mono_s {parts[0]}: expected a finite monotonic time "
                                 f"within +-{MAX_STAMP_S:g} s")
        if t_mono < prev_t:
            raise UserInputError(f"{idx_path}:{line_no}: t_mono_s {parts[0]} is earlier than the line before "
                                 f"({prev_t!r}): the stamps of a monotonic clock only grow")
        if end < prev_end:
            raise UserInputError(f"{idx_path}:{line_no}: end_offset {end} is below the line before ({prev_end}): "
                                 "expected growing byte offsets")
        out.append((end, t_mono))
    return out


def iter_raw_chunks(folder: Path, name: str) -> Iterable[tuple[bytes, float]]:
    """(chunk, t_mono_s) of `<name>.raw` as recorded, using `<name>.chunks.csv` (`read_chunk_index`).

    Bytes past the last indexed offset (a run killed between the two writes) come last,
    stamped with the last stamp (NaN without an index: `decode_session` refuses records
    without a stamp).
    """
    data = (folder / f"{name}.raw").read_bytes()
    index = read_chunk_index(folder, name) if (folder / f"{name}.chunks.csv").exists() else []
    start = 0
    for end, t_mono in index:
        end = min(end, len(data))
        if end > start:
            yield data[start:end], t_mono
        start = max(start, end)
    if start < len(data):
        yield data[start:], index[-1][1] if index else math.nan


def _stamped(folder: Path, name: str, n_records: int) -> None:
    """Records decoded from `<name>.raw` need its chunk index (without one they have no time)."""
    idx_path = folder / f"{name}.chunks.csv"
    if n_records and not (idx_path.is_file() and read_chunk_index(folder, name)):
        raise UserInputError(f"{idx_path}: missing or empty; the arrival stamps of {name}.raw are needed to place "
                             f"its {n_records} records in time (expected lines '{INDEX_HEADER}')")


def read_session_info(path: Path) -> dict:
    """session.json as a dict, checked where the replay reads it (UserInputError naming the file)."""
    if path.stat().st_size > MAX_SESSION_JSON_BYTES:
        raise UserInputError(f"{path}: more than {MAX_SESSION_JSON_BYTES / 1e6:g} MB: not a session.json")
    try:
        info = json.loads(_text(path, "a JSON object"))
    except json.JSONDecodeError as exc:
        raise UserInputError(f"{path}: line {exc.lineno}: invalid JSON ({exc.msg})") from exc
    except RecursionError:
        raise UserInputError(f"{path}: arrays or objects nested too deeply: not a session.json") from None
    problem = None
    if not isinstance(info, dict):
        kinds = {list: "an array", str: "a string", bool: "true/false", int: "a number", float: "a number"}
        problem = f"expected a JSON object, got {kinds.get(type(info), 'null')}"
    elif not (isinstance(info.get("devices", []), list) and all(isinstance(d, dict) for d in info.get("devices", []))):
        problem = "devices: expected a list of objects"
    elif "start_utc" in info and not isinstance(info["start_utc"], str):
        problem = f"start_utc: expected an ISO 8601 time as text, got {info['start_utc']!r:.40}"
    elif "t_mono_start_s" in info and not (isinstance(info["t_mono_start_s"], (int, float))
                                           and not isinstance(info["t_mono_start_s"], bool)
                                           and abs(info["t_mono_start_s"]) < MAX_STAMP_S):
        problem = f"t_mono_start_s: expected a finite monotonic time in s, got {info['t_mono_start_s']!r:.40}"
    if problem:
        raise UserInputError(f"{path}: {problem}")
    return info


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
        result.session_info = read_session_info(info_path)
    if (folder / "gnss.raw").exists():
        decoder = GnssDecoder()
        for chunk, t_mono in iter_raw_chunks(folder, "gnss"):
            result.gnss_records.extend(decoder.decode(chunk, t_mono))
        result.gnss_records.extend(decoder.close())
        _stamped(folder, "gnss", len(result.gnss_records))
        result.gnss_summary = decoder.summary()
        result.time_map = fit_time_map(r for r in result.gnss_records if isinstance(r, GnssTimeTag))
    if (folder / "imu.raw").exists():
        parser, grouper = WitMotionParser(), SampleGrouper()
        for chunk, t_mono in iter_raw_chunks(folder, "imu"):
            for packet in parser.feed(chunk, t_mono):
                result.imu_samples.extend(grouper.push(packet))
        parser.close()
        result.imu_samples.extend(grouper.flush())
        _stamped(folder, "imu", len(result.imu_samples))
        rejected = dict(parser.rejected)
        if grouper.incomplete:
            rejected["incomplete_samples"] = grouper.incomplete
        result.imu_summary = {"accepted": dict(parser.counts) | {"samples": len(result.imu_samples)},
                              "rejected": rejected}
    if not (result.gnss_records or result.imu_samples or (folder / "sdr.cu8").exists()
            or (folder / "gnss.raw").exists() or (folder / "imu.raw").exists()):
        raise UserInputError(f"{folder}: no gnss.raw, imu.raw or sdr.cu8 in this folder")
    return result
