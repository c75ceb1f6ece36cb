"""Recording sessions: one thread per device, raw logs first, decoded CSVs incrementally.

Session folder (see hardware/README.md for every column):
  gnss.raw, imu.raw            raw bytes exactly as read, flushed per chunk
  gnss.chunks.csv, imu.chunks.csv   `t_mono_s,end_offset` per chunk: the arrival stamps,
                               so `decode_session` reproduces the live decoding exactly
  gnss_fix.csv, gnss_raw.csv, imu.csv   decoded records, one flushed row at a time
  sdr.cu8, sdr.sigmf-meta      IQ capture (if an SDR was given)
  session.json                 devices, times, counts, rejects, time map; a partial one
                               ("status": "recording") is written at the start

Stopping: the duration elapsing, Ctrl-C (KeyboardInterrupt in the main loop), or every
device ending (EOF or a serial error when a device disappears). In each case the threads
are stopped, files closed and the final session.json written; nothing recorded is lost.
"""
from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from hardware.clock import TimeMap, utc_unix
from hardware.gnss import ubx_config
from hardware.gnss.reader import GnssDecoder, GnssReader
from hardware.imu import witmotion
from hardware.imu.witmotion import ImuReader, SampleGrouper, WitMotionParser
from hardware.records import GnssFix, GnssTimeTag, ImuSample, RxmRawx, UbxAck
from hardware.sdr import capture as sdr_capture
from leonav_runtime.errors import UserInputError
from leonav_runtime.output import write_json

SESSION_VERSION = 1
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


def _num(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return value


class CsvSink:
    """A CSV file written one flushed row at a time (survives an interrupted run)."""

    def __init__(self, path: Path, columns: list[str]) -> None:
        self.path = path
        self._fh = open(path, "w", newline="")
        self._writer = csv.writer(self._fh)
        self._writer.writerow(columns)
        self.rows = 0

    def write(self, row: Iterable[Any]) -> None:
        self._writer.writerow([_num(v) for v in row])
        self._fh.flush()
        self.rows += 1

    def close(self) -> None:
        self._fh.close()


class RawLog:
    """Raw byte log plus its chunk index (`t_mono_s,end_offset`), both flushed per chunk."""

    def __init__(self, folder: Path, name: str) -> None:
        self.path = folder / f"{name}.raw"
        self._fh = open(self.path, "wb")
        self._idx = open(folder / f"{name}.chunks.csv", "w")
        self._idx.write("t_mono_s,end_offset\n")
        self.n_bytes = 0
        self._lock = threading.Lock()

    def write(self, chunk: bytes, t_mono_s: float) -> None:
        with self._lock:
            self._fh.write(chunk)
            self._fh.flush()
            self.n_bytes += len(chunk)
            self._idx.write(f"{t_mono_s!r},{self.n_bytes}\n")
            self._idx.flush()

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
            self._map = TimeMap.fit(self._tags[-RUNNING_MAP_WINDOW:])

    def utc(self, t_mono_s: float) -> float:
        with self._lock:
            m = self._map
        return float(m.to_utc_unix(t_mono_s)) if m.valid else math.nan

    def final(self) -> TimeMap:
        with self._lock:
            return TimeMap.fit(self._tags)


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
    return [s.t_mono_s, utc_of(s.t_mono_s), *s.f_b_mps2, *s.w_b_radps, *s.euler_rad,
            s.temperature_c, *mag, *q, s.device_time.isoformat() if s.device_time else None]


# ------------------------------------------------------------------ recording


@dataclass
class DeviceRun:
    """State of one device thread, reported in session.json."""

    kind: str
    port: str
    baud: int | None = None
    thread: threading.Thread | None = None
    reader: Any = None
    raw: RawLog | None = None
    end_reason: str = ""
    error: str = ""
    records: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)


class RecordSession:
    """Record GNSS, IMU and SDR into `folder` (see module doc). Use `run(seconds)`."""

    def __init__(self, folder: str | Path, gnss: str | None = None, imu: str | None = None,
                 sdr_index: int | None = None, gnss_baud: int = 38400, imu_baud: int = 9600,
                 configure: bool = False, sdr_settings: sdr_capture.SdrSettings | None = None,
                 sdr_factory: Callable[[int], Any] = sdr_capture.open_rtlsdr,
                 progress: bool = True) -> None:
        if not (gnss or imu or sdr_index is not None):
            raise UserInputError("record: give at least one device (--gnss, --imu or --sdr)")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.configure = configure
        self.progress = progress
        self.stop_event = threading.Event()
        self.time_map = RunningTimeMap()
        self.devices: list[DeviceRun] = []
        self.sdr_settings = sdr_settings or sdr_capture.SdrSettings()
        # Open every device before recording anything: a wrong port fails fast and clean.
        if gnss:
            run = DeviceRun("gnss", gnss, gnss_baud)
            run.raw = RawLog(self.folder, "gnss")
            run.reader = GnssReader(gnss, gnss_baud, on_bytes=run.raw.write)
            self.devices.append(run)
        if imu:
            run = DeviceRun("imu", imu, imu_baud)
            run.raw = RawLog(self.folder, "imu")
            run.reader = ImuReader(imu, imu_baud, on_bytes=run.raw.write)
            self.devices.append(run)
        if sdr_index is not None:
            run = DeviceRun("sdr", str(sdr_index))
            run.reader = sdr_factory(sdr_index)
            self.devices.append(run)
        self.start_utc = _dt.datetime.now(_dt.timezone.utc)
        self.t_mono_start = time.monotonic()
        self.status = "recording"

    # -- per-device threads
    def _gnss_thread(self, run: DeviceRun, seconds: float) -> None:
        reader: GnssReader = run.reader
        fix_csv = CsvSink(self.folder / "gnss_fix.csv", GNSS_FIX_COLUMNS)
        raw_csv: CsvSink | None = None
        acks: list[dict] = []
        try:
            if self.configure:
                for frame in ubx_config.paper_10hz_config():
                    reader.write(frame)
                run.extra["config_frames_sent"] = len(ubx_config.paper_10hz_config())
            for rec in reader:
                if isinstance(rec, GnssTimeTag):
                    self.time_map.add(rec)
                elif isinstance(rec, UbxAck):
                    acks.append({"acked": rec.acked, "class": rec.acked_class, "id": rec.acked_id})
                name, rows = gnss_rows(rec, self.time_map.utc)
                if name == "gnss_raw" and raw_csv is None:
                    raw_csv = CsvSink(self.folder / "gnss_raw.csv", GNSS_RAW_COLUMNS)
                for row in rows:
                    (fix_csv if name == "gnss_fix" else raw_csv).write(row)
        finally:
            fix_csv.close()
            if raw_csv:
                raw_csv.close()
            run.extra["acks"] = acks
            run.extra["csv_rows"] = {"gnss_fix.csv": fix_csv.rows, "gnss_raw.csv": raw_csv.rows if raw_csv else 0}

    def _imu_thread(self, run: DeviceRun, seconds: float) -> None:
        reader: ImuReader = run.reader
        sink = CsvSink(self.folder / "imu.csv", IMU_COLUMNS)
        try:
            if self.configure:
                for cmd in witmotion.configure_sequence(rate_hz=10):
                    reader.write(cmd)
                    time.sleep(0.05)   # the sensor needs a moment between register writes
                run.extra["config_commands_sent"] = len(witmotion.configure_sequence(rate_hz=10))
            for sample in reader:
                sink.write(imu_row(sample, self.time_map.utc))
        finally:
            sink.close()
            run.extra["csv_rows"] = {"imu.csv": sink.rows}

    def _sdr_thread(self, run: DeviceRun, seconds: float) -> None:
        result = sdr_capture.capture(run.reader, self.folder / "sdr", self.sdr_settings, seconds,
                                     self.stop_event)
        run.end_reason = result.end_reason
        run.extra.update({"n_samples": result.n_samples, "if_hz": self.sdr_settings.if_hz,
                          "sample_rate_hz": self.sdr_settings.sample_rate_hz,
                          "t_mono_start_s": result.t_mono_start_s, "t_mono_stop_s": result.t_mono_stop_s})

    def _thread_main(self, run: DeviceRun, target: Callable, seconds: float) -> None:
        try:
            target(run, seconds)
        except Exception as exc:  # keep the session alive and report the failure
            run.error = f"{type(exc).__name__}: {exc}"

    # -- main loop
    def run(self, seconds: float) -> dict:
        """Record for `seconds` (or until Ctrl-C / all devices end); returns session.json's content."""
        self._write_session_json(partial=True)
        targets = {"gnss": self._gnss_thread, "imu": self._imu_thread, "sdr": self._sdr_thread}
        for run in self.devices:
            run.thread = threading.Thread(target=self._thread_main, args=(run, targets[run.kind], seconds),
                                          name=f"leonav-record-{run.kind}")
            run.thread.start()
        deadline = self.t_mono_start + seconds
        bar = None
        if self.progress:
            from tqdm import tqdm
            bar = tqdm(total=round(seconds, 1), unit="s", desc="recording", leave=False, disable=None)
        try:
            while time.monotonic() < deadline and any(r.thread.is_alive() for r in self.devices):
                time.sleep(0.05)
                if bar is not None:
                    bar.n = round(min(time.monotonic() - self.t_mono_start, seconds), 1)
                    bar.refresh()
            self.status = "complete" if time.monotonic() >= deadline else "devices ended"
        except KeyboardInterrupt:
            self.status = "interrupted"
        finally:
            if bar is not None:
                bar.close()
            self._stop_all()
        return self._write_session_json(partial=False)

    def _stop_all(self) -> None:
        self.stop_event.set()
        for run in self.devices:
            if run.kind != "sdr" and run.reader is not None:
                run.reader.stop()
        for run in self.devices:
            if run.thread is not None:
                try:
                    run.thread.join(timeout=5.0)
                except KeyboardInterrupt:   # a second Ctrl-C: wait once more, then go on
                    run.thread.join(timeout=5.0)
            if run.kind != "sdr" and run.reader is not None:
                run.end_reason = run.reader.end_reason
                run.records = run.reader.summary()
                run.reader.close()
                run.raw.close()
        self.t_mono_stop = time.monotonic()

    def _write_session_json(self, partial: bool) -> dict:
        devices = []
        for run in self.devices:
            entry = {"kind": run.kind, "port": run.port, "baud": run.baud}
            if not partial:
                entry |= {"end_reason": run.end_reason, "error": run.error} | run.records | run.extra
            devices.append(entry)
        info = {
            "leonav_session_version": SESSION_VERSION,
            "status": "recording" if partial else self.status,
            "start_utc": self.start_utc.isoformat(),
            "t_mono_start_s": self.t_mono_start,
            "clock": "time.monotonic() of the recording host, stamped when a chunk is read",
            "devices": devices,
        }
        if self.sdr_settings and any(r.kind == "sdr" for r in self.devices):
            s = self.sdr_settings
            info["sdr_settings"] = {"rf_center_hz": s.rf_center_hz, "lnb_lo_hz": s.lnb_lo_hz,
                                    "if_hz": s.if_hz, "sample_rate_hz": s.sample_rate_hz,
                                    "gain_db": s.gain_db, "ppm": s.ppm}
        if not partial:
            info["stop_utc"] = _dt.datetime.now(_dt.timezone.utc).isoformat()
            info["t_mono_stop_s"] = self.t_mono_stop
            info["time_map"] = self.time_map.final().as_dict()
        write_json(self.folder / "session.json", info)
        return json.loads((self.folder / "session.json").read_text())


def record_session(folder: str | Path, seconds: float, **kwargs: Any) -> dict:
    """Convenience: `RecordSession(folder, **kwargs).run(seconds)`."""
    return RecordSession(folder, **kwargs).run(seconds)


# ------------------------------------------------------------------ decoding a session


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
        decoder.close()
        result.gnss_summary = decoder.summary()
        result.time_map = TimeMap.fit(r for r in result.gnss_records if isinstance(r, GnssTimeTag))
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
