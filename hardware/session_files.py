"""Session folder formats shared by the recorder, `decode_session` and the synthetic writer.

Column lists of the decoded CSVs, the flushed CSV and raw-log writers, the running
monotonic -> UTC map the live CSVs use, record -> CSV row functions and the session.json
content (`session_json`). Every column is described in hardware/README.md.

`hardware.jsonfile.replace_file` writes a whole file through a temporary file renamed over it (session.json,
and the runtime's results files through `leonav_runtime.common.output`): a reader, a kill or a
full disk never sees half of it. The flushed logs (raw bytes, chunk index, CSV rows)
instead grow one whole record at a time (`RecordFile`): a write error there names the file, or,
given a `LostWrites` (as `leonav nav` does), is counted and the writer goes on.
"""
from __future__ import annotations

import csv
import io
import math
import threading
from pathlib import Path
from typing import Any, Callable, Iterable

from leonav.hardware.clock import TimeMap, utc_unix
from leonav.hardware.records import GnssFix, GnssTimeTag, ImuSample, RxmRawx

SESSION_VERSION = 1
RECORDER_CLOCK_TEXT = "time.monotonic() of the recording host, stamped when a chunk is read"
RUNNING_MAP_WINDOW = 300        # tags used by the live time map (the last 30 s at 10 Hz)

GNSS_FIX_COLUMNS = [
    "t_mono_s", "t_utc_mapped_s", "source", "fix_utc_s", "lat_deg", "lon_deg", "hmsl_m",
    "height_m", "quality", "num_sv", "hdop", "h_acc_m", "v_acc_m", "vel_n_mps", "vel_e_mps",
    "vel_d_mps",
]
GNSS_RAW_COLUMNS = [
    "t_mono_s", "t_utc_mapped_s", "rcv_tow_s", "week", "leap_s", "gnss_id", "sv_id", "sig_id",
    "freq_id", "pseudorange_m", "carrier_phase_cyc", "doppler_hz", "cno_dbhz", "locktime_s",
    "pr_std_m", "cp_std_cyc", "do_std_hz", "pr_valid", "cp_valid", "half_cyc",
]
IMU_COLUMNS = [
    "t_mono_s", "t_utc_mapped_s", "f_x_mps2", "f_y_mps2", "f_z_mps2", "w_x_radps", "w_y_radps",
    "w_z_radps", "roll_rad", "pitch_rad", "yaw_rad", "temperature_c", "mag_x_raw", "mag_y_raw",
    "mag_z_raw", "q_w", "q_x", "q_y", "q_z", "device_time_utc",
]


def fit_time_map(tags: Iterable[GnssTimeTag]) -> TimeMap:
    """`TimeMap.fit`, or an empty (invalid) map when the tags leave it nothing to fit (two
    groups of tags more than 1 s apart around their median: every tag is an outlier)."""
    try:
        return TimeMap.fit(tags)
    except ValueError:   # TimeMap's UserInputError: no majority of tags to fit
        return TimeMap()


def _named(exc: OSError, path: Path) -> OSError:
    """The OSError of a write to `path`, with `path` as its file name."""
    return exc if exc.filename else OSError(exc.errno, exc.strerror, str(path))


def _num(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return value


class LostWrites:
    """Records a run could not write (disk full, I/O error: any OSError of a write), counted per file
    (named relative to `root`), with the first error of each. Shared by every writer of a run, thread-safe;
    a writer given one goes on after a failed write instead of raising (an output must never stop
    `leonav nav`)."""

    def __init__(self, root: Path | None = None) -> None:
        self.root = Path(root) if root is not None else None
        self.counts: dict[str, int] = {}
        self.first_error: dict[str, str] = {}
        self._lock = threading.Lock()

    def name(self, path: Path) -> str:
        path = Path(path)
        if self.root is not None:
            try:
                return path.relative_to(self.root).as_posix()
            except ValueError:
                pass
        return str(path)

    def add(self, path: Path, exc: BaseException, n: int = 1) -> None:
        """`n` records of `path` were not written because of `exc`."""
        key = self.name(path)
        with self._lock:
            self.counts[key] = self.counts.get(key, 0) + n
            self.first_error.setdefault(key, f"{type(exc).__name__}: {exc}")

    def total(self) -> int:
        with self._lock:
            return sum(self.counts.values())

    def under(self, folder: Path) -> dict[str, int]:
        """The counts of the files in `folder`, named relative to it."""
        prefix = self.name(folder).rstrip("/") + "/"
        with self._lock:
            return {k[len(prefix):]: v for k, v in self.counts.items() if k.startswith(prefix)}


class RecordFile:
    """A file grown one whole record (bytes) at a time, each written at once (unbuffered). A write that
    fails is cut back to the end of the previous record, so the file always ends on a whole record; with
    `lost` the failure is counted there (the caller goes on, a later record may fit again), without it
    the OSError, naming the file, is raised."""

    def __init__(self, path: Path, lost: LostWrites | None = None) -> None:
        self.path = Path(path)
        self.lost = lost
        self.size = 0                      # bytes of whole records in the file
        self.last_error: OSError | None = None
        self._fh = open(self.path, "wb", buffering=0)

    def write(self, data: bytes, n_records: int = 1) -> bool:
        """Write `data` (`n_records` records) whole; False (counted in `lost`) when it failed."""
        view = memoryview(data)
        try:
            while view:
                view = view[self._fh.write(view):]
        except OSError as exc:
            self.truncate(self.size)
            self.last_error = exc
            if self.lost is None:
                raise _named(exc, self.path) from exc
            self.lost.add(self.path, exc, n_records)
            return False
        self.size += len(data)
        return True

    def truncate(self, size: int) -> None:
        """Cut the file back to `size` bytes (freeing space never needs space; failures are ignored)."""
        try:
            self._fh.truncate(size)
            self._fh.seek(size)
            self.size = size
        except OSError:
            pass

    def close(self) -> None:
        self._fh.close()


class CsvSink:
    """A CSV file written one row at a time, each written at once (survives an interrupted run); with
    `lost` a row that cannot be written is counted there (`RecordFile`)."""

    def __init__(self, path: Path, columns: list[str], lost: LostWrites | None = None) -> None:
        self.path = path
        self._fh = RecordFile(path, lost)
        self._buf = io.StringIO()
        self._writer = csv.writer(self._buf)
        self._fh.write(self._line(columns))
        self.rows = 0

    def _line(self, cells: list) -> bytes:
        self._writer.writerow(cells)
        text = self._buf.getvalue()
        self._buf.seek(0)
        self._buf.truncate()
        return text.encode("utf-8")

    def write(self, row: Iterable[Any]) -> None:
        if self._fh.write(self._line([_num(v) for v in row])):
            self.rows += 1

    def close(self) -> None:
        self._fh.close()


class RawLog:
    """Raw byte log plus its chunk index (`t_mono_s,end_offset`), each chunk written at once. A chunk
    is one record of both files: when either write fails, neither keeps any of it (with `lost`, counted
    for both files; without, the OSError naming the file is raised)."""

    def __init__(self, folder: Path, name: str, lost: LostWrites | None = None) -> None:
        self.path = folder / f"{name}.raw"
        self.lost = lost
        self._fh = RecordFile(self.path, lost)
        self._idx = RecordFile(folder / f"{name}.chunks.csv", lost)
        self._idx.write(b"t_mono_s,end_offset\n")
        self.n_bytes = 0
        self._lock = threading.Lock()

    def write(self, chunk: bytes, t_mono_s: float) -> None:
        with self._lock:
            try:
                if not self._fh.write(chunk):
                    self.lost.add(self._idx.path, self._fh.last_error)     # its index line is lost with it
                    return
            except OSError as exc:
                raise _named(exc, self.path) from exc
            if not self._idx.write(f"{t_mono_s!r},{self.n_bytes + len(chunk)}\n".encode()):
                self._fh.truncate(self._fh.size - len(chunk))
                self.lost.add(self.path, self._idx.last_error)
                return
            self.n_bytes += len(chunk)

    def close(self) -> None:
        self._fh.close()
        self._idx.close()


class RunningTimeMap:
    """Thread-safe monotonic->UTC map refitted on the latest GNSS time tags."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._tags: list[GnssTimeTag] = []
        self._map = TimeMap()

    def add(self, tag: GnssTimeTag) -> None:
        with self._lock:
            self._tags.append(tag)
            self._map = fit_time_map(self._tags[-RUNNING_MAP_WINDOW:])

    def utc(self, t_mono_s: float) -> float:
        with self._lock:
            m = self._map
        return float(m.to_utc_unix(t_mono_s)) if m.valid else math.nan

    def final(self) -> TimeMap:
        with self._lock:
            return fit_time_map(self._tags)


# ------------------------------------------------------------------ record -> rows


def gnss_rows(rec: Any, utc_of: Callable[[float], float]) -> tuple[str, list[list]]:
    """(csv name, rows) for a GNSS record that goes into a CSV, else ("", [])."""
    if isinstance(rec, GnssFix):
        vel = rec.vel_ned_mps or (None, None, None)
        return "gnss_fix", [[
            rec.t_mono_s, utc_of(rec.t_mono_s), rec.source, utc_unix(rec.utc) if rec.utc else None,
            math.degrees(rec.lat_rad), math.degrees(rec.lon_rad), rec.hmsl_m, rec.height_m,
            rec.quality, rec.num_sv, rec.hdop, rec.h_acc_m, rec.v_acc_m, *vel]]
    if isinstance(rec, RxmRawx):
        t_utc = utc_of(rec.t_mono_s)
        return "gnss_raw", [[
            rec.t_mono_s, t_utc, rec.rcv_tow_s, rec.week, rec.leap_s, m.gnss_id, m.sv_id, m.sig_id,
            m.freq_id, m.pseudorange_m, m.carrier_phase_cyc, m.doppler_hz, m.cno_dbhz, m.locktime_s,
            m.pr_std_m, m.cp_std_cyc, m.do_std_hz, m.pr_valid, m.cp_valid, m.half_cyc]
            for m in rec.measurements]
    return "", []


def imu_row(s: ImuSample, utc_of: Callable[[float], float]) -> list:
    mag = s.mag_raw or (None, None, None)
    q = s.q_wxyz or (None, None, None, None)
    return [s.t_mono_s, utc_of(s.t_mono_s), *s.f_b_mps2, *s.w_b_radps, *s.rpy_rad,
            s.temperature_c, *mag, *q, s.device_time.isoformat() if s.device_time else None]


def sdr_settings_json(settings) -> dict:
    """session.json `sdr_settings` of an `hardware.sdr.capture.SdrSettings`."""
    s = settings
    return {"rf_center_hz": s.rf_center_hz, "lnb_lo_hz": s.lnb_lo_hz, "if_hz": s.if_hz,
            "sample_rate_hz": s.sample_rate_hz, "gain_db": s.gain_db, "ppm": s.ppm}


def session_json(status: str, start_utc: str, t_mono_start_s: float, devices: list[dict], sdr_settings=None,
                 stop: tuple[str, float, TimeMap] | None = None) -> dict:
    """session.json content: status, start (ISO UTC of the host clock, monotonic s), the devices,
    the SDR settings (if any), and at the end `stop` = (stop UTC, monotonic stop s, final time map)."""
    info = {
        "leonav_session_version": SESSION_VERSION,
        "status": status,
        "start_utc": start_utc,
        "t_mono_start_s": t_mono_start_s,
        "clock": RECORDER_CLOCK_TEXT,
        "devices": devices,
    }
    if sdr_settings is not None:
        info["sdr_settings"] = sdr_settings_json(sdr_settings)
    if stop is not None:
        info["stop_utc"], info["t_mono_stop_s"] = stop[0], stop[1]
        info["time_map"] = stop[2].as_dict()
    return info
