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

Other programs reuse the recorder as their live reader loop (`leonav nav`): `on_record(kind,
record)` sees every decoded record in its device thread ("gnss": GNSS records, "imu":
ImuSample), and `start()` / `stop(status)` replace `run()` when the caller has its own loop.
"""
from __future__ import annotations

import datetime as _dt
import json
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from hardware.errors import UserInputError
from hardware.gnss import ubx_config
from hardware.gnss.reader import GnssReader
from hardware.imu import witmotion
from hardware.imu.witmotion import ImuReader
from hardware.jsonfile import write_json
from hardware.records import GnssTimeTag, UbxAck
from hardware.sdr import capture as sdr_capture
from hardware.session_decode import DecodedSession, decode_session, iter_raw_chunks
from hardware.session_files import (GNSS_FIX_COLUMNS, GNSS_RAW_COLUMNS, IMU_COLUMNS, SESSION_VERSION, CsvSink,
                                    RawLog, RunningTimeMap, gnss_rows, imu_row, session_json)  # noqa: F401

__all__ = ["RecordSession", "DeviceRun", "decode_session", "DecodedSession", "iter_raw_chunks", "CsvSink", "RawLog",
           "RunningTimeMap", "gnss_rows", "imu_row", "GNSS_FIX_COLUMNS", "GNSS_RAW_COLUMNS", "IMU_COLUMNS",
           "SESSION_VERSION"]


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
                 progress: bool = True, on_record: Callable[[str, Any], None] | None = None) -> None:
        if not (gnss or imu or sdr_index is not None):
            raise UserInputError("record: give at least one device (--gnss, --imu or --sdr)")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.configure = configure
        self.progress = progress
        self.on_record = on_record
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
                if self.on_record:
                    self.on_record("gnss", rec)
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
                if self.on_record:
                    self.on_record("imu", sample)
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
    def start(self, seconds: float) -> None:
        """Write the partial session.json and start one thread per device (`seconds`: the SDR's length)."""
        self._write_session_json(partial=True)
        targets = {"gnss": self._gnss_thread, "imu": self._imu_thread, "sdr": self._sdr_thread}
        for run in self.devices:
            run.thread = threading.Thread(target=self._thread_main, args=(run, targets[run.kind], seconds),
                                          name=f"leonav-record-{run.kind}")
            run.thread.start()

    def stop(self, status: str) -> dict:
        """Stop every device, close the files, write the final session.json with `status`; returns it."""
        self.status = status
        self._stop_all()
        return self._write_session_json(partial=False)

    def run(self, seconds: float) -> dict:
        """Record for `seconds` (or until Ctrl-C / all devices end); returns session.json's content."""
        self.start(seconds)
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
        has_sdr = self.sdr_settings and any(r.kind == "sdr" for r in self.devices)
        stop = None if partial else (_dt.datetime.now(_dt.timezone.utc).isoformat(), self.t_mono_stop,
                                     self.time_map.final())
        info = session_json("recording" if partial else self.status, self.start_utc.isoformat(), self.t_mono_start,
                            devices, self.sdr_settings if has_sdr else None, stop)
        write_json(self.folder / "session.json", info)
        return json.loads((self.folder / "session.json").read_text())
