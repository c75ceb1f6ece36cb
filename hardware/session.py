"""Recording sessions: one thread per device, raw logs first, decoded CSVs incrementally.

Session folder (see hardware/README.md for every column):
  gnss.raw, imu.raw            raw bytes exactly as read, flushed per chunk
  gnss.chunks.csv, imu.chunks.csv   `t_mono_s,end_offset` per chunk: the arrival stamps,
                               so `decode_session` reproduces the live decoding exactly
  gnss_fix.csv, gnss_raw.csv, imu.csv   decoded records, one flushed row at a time
  sdr.cu8, sdr.sigmf-meta      IQ capture (if an SDR was given)
  session.json                 devices, times, counts, rejects, time map; a partial one
                               ("status": "recording") is written at the start

Stopping: the duration elapsing, Ctrl-C, SIGTERM or SIGHUP (noted by a signal handler
while `run()` records; more signals during the shutdown are ignored), or every device ending
(EOF or a serial error when a device disappears). In each case the threads are stopped,
files closed and the final session.json written (through a temporary file, so it is never
half written); nothing recorded is lost. A device thread never ends on the bytes it reads
(the readers count what they reject); one that ends on an error of its own (a full disk)
makes the session "failed". Given `lost_writes` (`leonav nav`), a write that fails (a full
disk) is counted there instead and recording goes on; session.json then lists `lost_writes` and is
written best-effort.

Final `status`: "complete" (the duration elapsed), "devices ended" (every device ended
first), "interrupted" (a stop signal; `stop_signal` names it), "failed" (a device thread
ended on an error: its `error` says which). A folder that already holds a recording
(session.json, or a non-empty raw log or capture) is refused, never overwritten.

Other programs reuse the recorder as their live reader loop (`leonav nav`): `on_record(kind,
record)` sees every decoded record in its device thread ("gnss": GNSS records, "imu":
ImuSample), and `start()` / `stop(status)` replace `run()` when the caller has its own loop.
"""
from __future__ import annotations

import datetime as _dt
import json
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from leonav.hardware.errors import UserInputError
from leonav.hardware.gnss import ubx_config
from leonav.hardware.gnss.reader import GnssReader
from leonav.hardware.imu import witmotion
from leonav.hardware.imu.witmotion import ImuReader
from leonav.hardware.jsonfile import jsonable, write_json
from leonav.hardware.records import GnssTimeTag, UbxAck
from leonav.hardware.sdr import capture as sdr_capture
from leonav.hardware.session_decode import DecodedSession, decode_session, iter_raw_chunks
from leonav.hardware.session_files import (GNSS_FIX_COLUMNS, GNSS_RAW_COLUMNS, IMU_COLUMNS, SESSION_VERSION, CsvSink,
                                    LostWrites, RawLog, RunningTimeMap, gnss_rows, imu_row,  # noqa: F401
                                    session_json)

STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")   # end a recording like Ctrl-C
RECORDING_FILES = ("session.json", "gnss.raw", "imu.raw", "sdr.cu8")
JOIN_TIMEOUT_S = 5.0      # how long the shutdown waits for each device thread

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
    exception: BaseException | None = field(default=None, repr=False)   # what ended the thread, if anything


def holds_recording(folder: Path) -> str | None:
    """The file that shows `folder` already holds a recording (session.json, or a non-empty
    raw log / capture), else None. Empty raw logs are what a failed start leaves."""
    for name in RECORDING_FILES:
        path = folder / name
        if path.is_file() and (name == "session.json" or path.stat().st_size > 0):
            return name
    return None


class RecordSession:
    """Record GNSS, IMU and SDR into `folder` (see module doc). Use `run(seconds)`."""

    def __init__(self, folder: str | Path, gnss: str | None = None, imu: str | None = None,
                 sdr_index: int | None = None, gnss_baud: int = 38400, imu_baud: int = 9600,
                 configure: bool = False, sdr_settings: sdr_capture.SdrSettings | None = None,
                 sdr_factory: Callable[[int], Any] = sdr_capture.open_rtlsdr,
                 progress: bool = True, on_record: Callable[[str, Any], None] | None = None,
                 lost_writes: LostWrites | None = None) -> None:
        if not (gnss or imu or sdr_index is not None):
            raise UserInputError("record: give at least one device (--gnss, --imu or --sdr)")
        self.folder = Path(folder)
        taken = holds_recording(self.folder)
        if taken:
            raise UserInputError(f"{self.folder}: already holds a recording ({taken}); give a new folder "
                                 "(a recording is never overwritten)")
        self.folder.mkdir(parents=True, exist_ok=True)
        self.configure = configure
        self.progress = progress
        self.on_record = on_record
        self.lost = lost_writes         # given: a failed write is counted, never ends a device thread
        self.stop_event = threading.Event()
        self.stop_signal = ""
        self.time_map = RunningTimeMap()
        self.devices: list[DeviceRun] = []
        self.sdr_settings = sdr_settings or sdr_capture.SdrSettings()
        # Open every device before recording anything: a wrong port fails fast and clean
        # (what was opened is closed again, and no raw log is created).
        try:
            if gnss:
                self.devices.append(DeviceRun("gnss", gnss, gnss_baud, reader=GnssReader(gnss, gnss_baud)))
            if imu:
                self.devices.append(DeviceRun("imu", imu, imu_baud, reader=ImuReader(imu, imu_baud)))
            if sdr_index is not None:
                self.devices.append(DeviceRun("sdr", str(sdr_index), reader=sdr_factory(sdr_index)))
            for run in self.devices:
                if run.kind != "sdr":
                    run.raw = RawLog(self.folder, run.kind) if self.lost is None else \
                        RawLog(self.folder, run.kind, self.lost)
                    run.reader.on_bytes = run.raw.write
        except BaseException:
            self._close_devices()
            raise
        self.start_utc = _dt.datetime.now(_dt.timezone.utc)
        self.t_mono_start = time.monotonic()
        self.status = "recording"

    # -- per-device threads
    def _gnss_thread(self, run: DeviceRun, seconds: float) -> None:
        reader: GnssReader = run.reader
        fix_csv = CsvSink(self.folder / "gnss_fix.csv", GNSS_FIX_COLUMNS, self.lost)
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
                    raw_csv = CsvSink(self.folder / "gnss_raw.csv", GNSS_RAW_COLUMNS, self.lost)
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
        sink = CsvSink(self.folder / "imu.csv", IMU_COLUMNS, self.lost)
        try:
            if self.configure:
                for cmd in witmotion.configure_sequence(rate_hz=10):
                    reader.write(cmd)
                    time.sleep(0.05)   # the sensor needs a moment between register writes
                run.extra["config_commands_sent"] = len(witmotion.configure_sequence(rate_hz=10))
            for sample in reader:
                if self.on_record:
                    self.on_record("imu", sample)
                sink.write(imu_row(sample, self.time_map.utc))
        finally:
            sink.close()
            run.extra["csv_rows"] = {"imu.csv": sink.rows}

    def _sdr_thread(self, run: DeviceRun, seconds: float) -> None:
        result = sdr_capture.capture(run.reader, self.folder / "sdr", self.sdr_settings, seconds,
                                     self.stop_event, lost=self.lost)
        run.end_reason = result.end_reason
        run.extra.update({"n_samples": result.n_samples, "if_hz": self.sdr_settings.if_hz,
                          "sample_rate_hz": self.sdr_settings.sample_rate_hz,
                          "t_mono_start_s": result.t_mono_start_s, "t_mono_stop_s": result.t_mono_stop_s})

    def _thread_main(self, run: DeviceRun, target: Callable, seconds: float) -> None:
        try:
            target(run, seconds)
        except Exception as exc:  # keep the session alive and report the failure
            run.error = f"{type(exc).__name__}: {exc}"
            run.exception = exc

    # -- main loop
    def start(self, seconds: float) -> None:
        """Write the partial session.json and start one thread per device (`seconds`: the SDR's length)."""
        self._write_session_json(partial=True)
        targets = {"gnss": self._gnss_thread, "imu": self._imu_thread, "sdr": self._sdr_thread}
        for run in self.devices:
            # daemon: a thread stuck in a device driver never keeps the process from exiting
            run.thread = threading.Thread(target=self._thread_main, args=(run, targets[run.kind], seconds),
                                          name=f"leonav-record-{run.kind}", daemon=True)
            run.thread.start()

    def stop(self, status: str) -> dict:
        """Stop every device, close the files, write the final session.json with `status`
        ("failed" instead when a device thread ended on an error); returns it."""
        self._stop_all()
        self.status = "failed" if any(run.error for run in self.devices) else status
        return self._write_session_json(partial=False)

    def run(self, seconds: float) -> dict:
        """Record for `seconds` (or until a stop signal / all devices end); returns session.json's content."""
        with self.stop_signals():
            self.start(seconds)
            deadline = self.t_mono_start + seconds
            bar = None
            status = "failed"
            try:
                if self.progress:
                    from tqdm import tqdm
                    bar = tqdm(total=round(seconds, 1), unit="s", desc="recording", leave=False, disable=None)
                while (time.monotonic() < deadline and not self.stop_signal
                       and any(r.thread.is_alive() for r in self.devices)):
                    time.sleep(0.05)
                    if bar is not None:
                        bar.n = round(min(time.monotonic() - self.t_mono_start, seconds), 1)
                        bar.refresh()
                status = ("interrupted" if self.stop_signal else
                          "complete" if time.monotonic() >= deadline else "devices ended")
            except KeyboardInterrupt:   # only where no handler could be installed (not the main thread)
                self.stop_signal = self.stop_signal or "SIGINT"
                status = "interrupted"
            finally:
                if bar is not None:
                    bar.close()
                info = self.stop(status)
            return info

    @contextmanager
    def stop_signals(self):
        """While inside, SIGINT/SIGTERM/SIGHUP only note a stop request (`stop_signal`): the
        main loop of `run()` ends, the devices stop and session.json is written; further
        signals during that shutdown are ignored. The previous handlers come back at the end
        (a caller may hold it open longer, e.g. while printing the summary). Nothing is
        installed outside the main thread (Python allows handlers only there)."""
        installed = {}
        if threading.current_thread() is threading.main_thread():
            for name in STOP_SIGNALS:
                number = getattr(signal, name, None)
                if number is not None:
                    installed[number] = signal.signal(number, self._on_stop_signal)
        try:
            yield
        finally:
            for number, old in installed.items():
                # after a stop request the process is ending: a late repeat of the signal
                # (a double Ctrl-C) must not kill it during its exit (that gave exit -2)
                signal.signal(number, signal.SIG_IGN if self.stop_signal else
                              old if old is not None else signal.SIG_DFL)

    def _on_stop_signal(self, signum: int, frame) -> None:
        # a flag only: the handler runs between any two bytecodes of the main thread, so taking a
        # lock here (Event.set) deadlocks when the signal lands inside the main thread's own
        # stop_event.set() - a repeated Ctrl-C during the shutdown did that. run()'s loop reads the
        # flag within 50 ms and _stop_all sets the event for the device threads.
        if not self.stop_signal:
            self.stop_signal = signal.Signals(signum).name

    def _stop_all(self) -> None:
        self.stop_event.set()
        for run in self.devices:
            if run.kind != "sdr" and run.reader is not None:
                run.reader.stop()
        for run in self.devices:
            if run.thread is not None:
                try:
                    run.thread.join(timeout=JOIN_TIMEOUT_S)
                except KeyboardInterrupt:   # a second Ctrl-C without our handler: wait once more, then go on
                    run.thread.join(timeout=JOIN_TIMEOUT_S)
                if run.thread.is_alive() and not run.error:
                    run.error = f"the {run.kind} thread did not stop within {JOIN_TIMEOUT_S:g} s"
            if run.kind != "sdr" and run.reader is not None:
                run.end_reason = run.reader.end_reason
                run.records = run.reader.summary()
        self._close_devices()
        self.t_mono_stop = time.monotonic()

    def _close_devices(self) -> None:
        for run in self.devices:
            for closable in (run.reader, run.raw):
                if closable is not None and hasattr(closable, "close"):
                    try:
                        closable.close()
                    except (OSError, ValueError) as exc:   # a raw log that cannot flush its last bytes
                        run.error = run.error or f"{type(exc).__name__}: {exc}"
                        run.exception = run.exception or exc

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
        if self.stop_signal and not partial:
            info["stop_signal"] = self.stop_signal
        if self.lost is None:
            write_json(self.folder / "session.json", info)
            return json.loads((self.folder / "session.json").read_text())
        info["lost_writes"] = self.lost.under(self.folder)
        try:                     # best-effort: the caller reports a session.json that did not fit
            write_json(self.folder / "session.json", info)
        except OSError as exc:
            self.lost.add(self.folder / "session.json", exc)
        return jsonable(info)
