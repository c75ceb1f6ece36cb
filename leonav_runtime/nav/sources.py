"""Where `leonav nav` reads from, always through the devices' byte decoders.

- `LiveSource`: serial devices (or pty paths) read by the recorder's own device threads
  (`hardware.session.RecordSession`, hooked with `on_record`), so every byte is also recorded
  as `leonav record` records it; the records reach the navigator through a queue.
- `PacedPty` (used by `--from SESSION --realtime`, and by the tests as "devices"): a pty pair whose
  master side is written with a session's recorded chunks at their recorded pace (the chunk
  stamps), optionally with extra bytes (garbage) or a close (an unplugged device) at given
  times; `LiveSource` reads the slave path like a serial port. `FileRtlSdr` replays a
  recorded `sdr.cu8` as an RTL-SDR at its sample rate.
- `FastPlayback` (`--from SESSION` without `--realtime`): the recorded chunks of every device
  merged by their stamps and fed in that order, in this thread, to the same decoders
  (`GnssDecoder`, `WitMotionParser` + `SampleGrouper`) the readers use, as fast as the
  navigator takes them; deterministic. It copies what it reads into a session folder with
  the recorder's writers (`session_copy.SessionCopy`).

Given a `LostWrites`, every recorder writer counts a write that fails (a full disk) there and goes
on: a device thread never ends on its own files (`hardware.session.RecordSession`).
"""
from __future__ import annotations

import json
import os
import shutil
import queue
import threading
import time
import tty
from pathlib import Path
from typing import Callable

from leonav.hardware.gnss.reader import GnssDecoder
from leonav.hardware.imu.witmotion import SampleGrouper, WitMotionParser
from leonav.hardware.records import ImuSample
from leonav.hardware.session import RecordSession
from leonav.hardware.session_decode import iter_raw_chunks
from leonav.hardware.session_files import LostWrites
from leonav_runtime.nav.session_copy import SessionCopy, _baud  # noqa: F401 (`_baud` is used by run.py)

TICK_S = 0.05


class PacedPty:
    """A pty pair fed with `events` = [(offset s, bytes), ...] on an absolute schedule (at the
    recorded pace: the receiver's UTC in the bytes does not run faster, so neither may the
    playback); `close_at_s` closes the master then (device unplugged). `path` is the slave side."""

    def __init__(self, events: list[tuple[float, bytes]], close_at_s: float | None = None) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.events = sorted(events, key=lambda e: e[0])
        self.close_at_s = close_at_s
        self.done = threading.Event()
        self.closed = False
        self.bytes_written = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._feed, daemon=True, name="leonav-pty-feed")

    def start(self) -> None:
        self._thread.start()

    def _wait_until(self, t0: float, offset: float) -> bool:
        delay = t0 + offset - time.monotonic()
        return not (delay > 0 and self._stop.wait(delay))

    def _feed(self) -> None:
        t0 = time.monotonic()
        try:
            for offset, data in self.events:
                if self.close_at_s is not None and offset >= self.close_at_s:
                    break
                if not self._wait_until(t0, offset):
                    return
                view = memoryview(data)
                while view:
                    n = os.write(self.master, view)
                    view = view[n:]
                    self.bytes_written += n
            if self.close_at_s is not None and self._wait_until(t0, self.close_at_s):
                self.close_master()
        except OSError:
            pass
        finally:
            self.done.set()

    def close_master(self) -> None:
        if not self.closed:
            self.closed = True
            try:
                os.close(self.master)
            except OSError:
                pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0) if self._thread.is_alive() else None
        self.close_master()
        try:
            os.close(self.slave)
        except OSError:
            pass


def chunk_events(folder: Path, name: str, t0_mono: float) -> list[tuple[float, bytes]]:
    """(offset from `t0_mono` s, chunk) of a session's `<name>.raw`, from its chunk stamps."""
    if not (folder / f"{name}.raw").exists():
        return []
    return [(t - t0_mono, c) for c, t in iter_raw_chunks(folder, name)]


def session_start_mono(folder: Path) -> float:
    """The earliest chunk stamp of a session's serial logs (its playback's time zero)."""
    firsts = []
    for name in ("gnss", "imu"):
        if (folder / f"{name}.raw").exists():
            firsts += [t for _, t in iter_raw_chunks(folder, name)][:1]
    return min(firsts, default=0.0)


class FileRtlSdr:
    """A recorded cu8 capture read back like pyrtlsdr's RtlSdr (`read_bytes`), paced at its sample
    rate. At the end of the recording it returns empty reads until the session stops it: the recording
    ended, the device did not fail."""

    IDLE_S = 0.05          # after the end: one empty read per this long (the capture loop sees its stop)

    def __init__(self, path: Path, start_delay_s: float = 0.0) -> None:
        self._fh = open(path, "rb")
        self.sample_rate, self.center_freq, self.gain, self.freq_correction = 2.4e6, 1e9, "auto", 0
        self.start_delay_s = max(0.0, start_delay_s)
        self._t0 = None
        self._n = 0

    def read_bytes(self, n: int) -> bytes:
        if self._t0 is None:
            time.sleep(self.start_delay_s)     # the capture started this long after the serial logs
            self._t0 = time.monotonic()
        data = self._fh.read(n)
        if not data:        # the recording ended, the device did not: idle until the session stops it
            time.sleep(self.IDLE_S)
            return b""
        self._n += len(data) // 2
        delay = self._t0 + self._n / self.sample_rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        return data

    def close(self) -> None:
        self._fh.close()


class LiveSource:
    """Devices read by the recorder's threads into `record_dir`; records handed to a navigator."""

    def __init__(self, record_dir: Path, gnss: str | None, imu: str | None, sdr_index: int | None = None,
                 gnss_baud: int = 38400, imu_baud: int = 9600, configure: bool = False, sdr_settings=None,
                 sdr_factory: Callable | None = None, playback: list[PacedPty] | None = None, beacons=None,
                 lost: LostWrites | None = None) -> None:
        self.queue: queue.SimpleQueue = queue.SimpleQueue()
        self.beacons = beacons
        self.record_dir = Path(record_dir)
        kw = {} if sdr_factory is None else {"sdr_factory": sdr_factory}
        self.session = RecordSession(record_dir, gnss=gnss, imu=imu, sdr_index=sdr_index, gnss_baud=gnss_baud,
                                     imu_baud=imu_baud, configure=configure, sdr_settings=sdr_settings,
                                     progress=False, on_record=self._put, lost_writes=lost, **kw)
        self.playback = playback or []
        self.reported: set[str] = set()
        self.info: dict = {}

    def _put(self, kind: str, rec) -> None:
        """From a device thread: the record and when it was handed over (its last byte read and decoded)."""
        self.queue.put((kind, rec, time.monotonic()))

    def rejected(self) -> dict:
        out = {}
        for d in self.session.devices:
            if d.kind in ("gnss", "imu") and d.reader is not None:
                try:
                    out[d.kind] = dict(d.reader.summary().get("rejected", {}))
                except RuntimeError:          # counters changing under us: next tick
                    pass
        return out

    def run(self, navigator, seconds: float | None, sdr_seconds: float = 1e7, on_started=None,
            should_stop: Callable[[], bool] = lambda: False) -> str:
        """Read until `seconds` pass, every device ends, the playback (if any) is over, or `should_stop()`."""
        self.session.start(seconds if seconds else sdr_seconds)
        if self.beacons is not None:
            sdr = next((d for d in self.session.devices if d.kind == "sdr"), None)
            self.beacons.start(self.record_dir / "sdr.sigmf-meta",
                               lambda: sdr is not None and sdr.thread is not None and sdr.thread.is_alive())
        for p in self.playback:
            p.start()
        if on_started:
            on_started()
        t_end = time.monotonic() + seconds if seconds else float("inf")
        quiet_since = None
        last_tick = 0.0
        while True:
            now = time.monotonic()
            if now >= t_end:
                return "complete"
            if should_stop():
                return "stopped"
            items = []
            try:
                items.append(self.queue.get(timeout=TICK_S))
                while True:
                    items.append(self.queue.get_nowait())
            except queue.Empty:
                pass
            self._dispatch(items, navigator)
            if self.beacons is not None:
                self.beacons.poll(navigator)
            now = time.monotonic()
            if now - last_tick >= TICK_S:
                last_tick = now
                self._check_devices(navigator)
                navigator.tick(now, self.rejected())
            alive = [d for d in self.session.devices if d.thread is not None and d.thread.is_alive()]
            if not alive:
                return self._ended("devices ended", navigator)
            if self.playback and all(p.done.is_set() for p in self.playback):
                quiet_since = quiet_since or now
                if items:
                    quiet_since = now
                if now - quiet_since > 0.5:
                    return self._ended("playback ended", navigator)

    def _ended(self, reason: str, navigator) -> str:
        """Every device (or the playback) ended: the beacon process's last records, its stream
        flushed, reach the navigator before it settles."""
        if self.beacons is not None:
            self.beacons.finish(navigator)
        return reason

    def _dispatch(self, items: list, navigator) -> None:
        """Records in arrival order; IMU samples of one read (one stamp) go together, with the time
        the last of them was handed over as their arrival."""
        group: list[ImuSample] = []
        arrived = 0.0
        for kind, rec, handed in items:
            if kind == "imu":
                if group and rec.t_mono_s != group[-1].t_mono_s:
                    navigator.on_imu(group, group[-1].t_mono_s, arrived)
                    group = []
                group.append(rec)
                arrived = handed
                continue
            if group:
                navigator.on_imu(group, group[-1].t_mono_s, arrived)
                group = []
            navigator.on_gnss(rec)
        if group:
            navigator.on_imu(group, group[-1].t_mono_s, arrived)

    def _check_devices(self, navigator) -> None:
        for d in self.session.devices:
            if d.kind in self.reported or d.thread is None or d.thread.is_alive():
                continue
            self.reported.add(d.kind)
            reason = d.error or (d.reader.end_reason if d.kind != "sdr" and d.reader is not None else d.end_reason)
            if "device error" in (reason or "") or d.error:
                navigator.device_ended(d.kind, reason)

    def stop(self, status: str) -> dict:
        # the readers first: a pty closed under a reader is a device error, the end of a playback is not
        self.info = self.session.stop(status)
        for p in self.playback:
            p.close()
        if self.beacons is not None:
            self.beacons.stop()
        return self.info


def read_session_info(folder: Path) -> dict:
    path = folder / "session.json"
    info = json.loads(path.read_text()) if path.exists() else {}
    info["_folder"] = str(folder)
    return info


def same_stamp_groups(samples: list[ImuSample]) -> list[list[ImuSample]]:
    """Consecutive samples with one arrival stamp (one read) grouped: a sample carries the stamp of
    its acceleration packet, which the grouper may hand over one read later."""
    groups: list[list[ImuSample]] = []
    for s in samples:
        if groups and groups[-1][-1].t_mono_s == s.t_mono_s:
            groups[-1].append(s)
        else:
            groups.append([s])
    return groups


class FastPlayback:
    """A session's chunks through the decoders in stamp order, as fast as possible (module doc)."""

    def __init__(self, folder: Path, record_dir: Path | None, beacons=None, lost: LostWrites | None = None) -> None:
        self.folder = Path(folder)
        self.beacons = beacons
        self.lost = lost
        self.info = read_session_info(self.folder)
        self.copy = SessionCopy(record_dir, self.info, lost) if record_dir is not None else None
        self.gnss = GnssDecoder()
        self.parser, self.grouper = WitMotionParser(), SampleGrouper()

    def rejected(self) -> dict:
        imu = dict(self.parser.rejected)
        if self.grouper.incomplete:
            imu["incomplete_samples"] = self.grouper.incomplete
        return {"gnss": dict(self.gnss.rejected), "imu": imu}

    def run(self, navigator, seconds: float | None = None, on_started=None,
            should_stop: Callable[[], bool] = lambda: False) -> str:
        events = [(t, 0, "gnss", c) for c, t in (iter_raw_chunks(self.folder, "gnss")
                                                  if (self.folder / "gnss.raw").exists() else [])]
        events += [(t, 1, "imu", c) for c, t in (iter_raw_chunks(self.folder, "imu")
                                                  if (self.folder / "imu.raw").exists() else [])]
        events.sort(key=lambda e: (e[0], e[1]))
        if on_started:
            on_started()
        reason = self._play(events, navigator, seconds, should_stop)
        if self.beacons is not None:    # the capture's last measurements, before the navigator settles
            self.beacons.finish(navigator)
        return reason

    def _play(self, events: list, navigator, seconds: float | None, should_stop: Callable[[], bool]) -> str:
        t_first = events[0][0] if events else 0.0
        last_tick = -float("inf")
        for t, _, kind, chunk in events:
            if should_stop():
                return "stopped"
            if seconds is not None and t - t_first > seconds:
                return "complete"
            if self.beacons is not None:
                self.beacons.advance_to(t, navigator)
            if self.copy:
                self.copy.chunk(kind, chunk, t)
            if kind == "gnss":
                for rec in self.gnss.decode(chunk, t):
                    if self.copy:
                        self.copy.gnss(rec)
                    navigator.on_gnss(rec)
            else:
                samples = [s for p in self.parser.feed(chunk, t) for s in self.grouper.push(p)]
                for s in samples:
                    if self.copy:
                        self.copy.imu(s)
                for group in same_stamp_groups(samples):
                    navigator.on_imu(group, group[-1].t_mono_s, time.monotonic())
            if t - last_tick >= TICK_S:
                last_tick = t
                navigator.tick(t, self.rejected())
        for group in same_stamp_groups(self.grouper.flush()):
            navigator.on_imu(group, group[-1].t_mono_s, time.monotonic())
        return "playback ended"

    def stop(self, status: str) -> dict:
        self.gnss.close()
        self.parser.close()
        if self.beacons is not None:
            self.beacons.stop()
        if self.copy is None:
            return {}
        for name in ("sdr.cu8", "sdr.sigmf-meta"):     # the capture is copied as it is
            if (self.folder / name).exists():
                try:
                    shutil.copyfile(self.folder / name, self.copy.folder / name)
                except OSError as exc:
                    if self.lost is None:
                        raise
                    self.lost.add(self.copy.folder / name, exc)
        summaries = {"gnss": self.gnss.summary(), "imu": {"rejected": self.rejected()["imu"],
                                                          "accepted": dict(self.parser.counts)}}
        return self.copy.close(status, summaries)
