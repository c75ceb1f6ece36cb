"""The capture -> `beacon_stream.BeaconStream` -> Doppler-rate tables on the navigator's road.

- Live (and paced playback): the recorder's SDR thread writes `session/sdr.cu8` (flushed per
  block); a worker thread reads the file as it grows (`tail`), in `chunk_s` pieces, so the
  navigator never waits for the SDR and the capture is recorded whatever happens.
- Fast playback: `advance_to(t_mono)` pushes the recorded samples up to that host time in the
  caller's thread, in step with the serial chunks (deterministic).
Measurements are placed on the road's axis with the capture's first-sample host stamp
(SigMF `leonav:t_mono_start_s`) through the GNSS time map, as the replay does, and get their
satellite states from `replay.beacon_table.doppler_rate_table` (SGP4, sigma floor).
"""
from __future__ import annotations

import json
import math
import queue
import threading
import time
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.beacons.predict import Site
from leonav_runtime.nav.beacon_stream import BeaconStream
from leonav_runtime.replay.beacon_table import BeaconMeasurements, default_elements, doppler_rate_table
from leonav_runtime.replay.timebase import utc_of

CHUNK_S = 0.1


def capture_meta(meta_path: Path) -> dict:
    """Sample rate, RF centre, host stamp of the first sample from a recorder's sdr.sigmf-meta."""
    doc = json.loads(Path(meta_path).read_text())
    g = doc.get("global", {})
    cap = (doc.get("captures") or [{}])[0]
    return {"sample_rate_hz": float(g["core:sample_rate"]),
            "rf_center_hz": float(g.get("leonav:rf_center_hz", cap.get("core:frequency", 0.0) +
                                        g.get("leonav:lnb_lo_hz", 0.0))),
            "lnb_lo_hz": float(g.get("leonav:lnb_lo_hz", 0.0)), "gain_db": g.get("leonav:gain_db", "auto"),
            "t_mono_start_s": g.get("leonav:t_mono_start_s")}


def carrier(rf_center_hz: float) -> tuple[float, str]:
    """Beacon carrier f_c: the capture's RF centre inside the Ku downlink band, else the default
    (the rule of `replay.beacon_table.capture_carrier`)."""
    from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
    from leonav_runtime.replay.beacon_table import KU_DOWNLINK_HZ

    if math.isfinite(rf_center_hz) and KU_DOWNLINK_HZ[0] <= rf_center_hz <= KU_DOWNLINK_HZ[1]:
        return rf_center_hz, "capture RF centre (tuned frequency + LNB LO)"
    return STARLINK_BEACON_HZ, f"default {STARLINK_BEACON_HZ / 1e9:g} GHz (capture RF centre {rf_center_hz / 1e9:.6g} GHz)"


def cu8_to_complex(raw: bytes) -> np.ndarray:
    """Interleaved cu8 -> complex64 with the scaling of `beacons.capture_io` (full scale ~ +-1)."""
    f = np.frombuffer(raw, np.uint8)[: len(raw) // 2 * 2].astype(np.float32)
    f -= 127.5
    f *= 1.0 / 127.5
    return f.view(np.complex64)


class BeaconFeed:
    def __init__(self, data_path: Path, meta: dict, tone_rf_hz: float, elements, sigma_floor_hz_s: float,
                 live: bool) -> None:
        self.data_path = Path(data_path)
        self.meta = meta
        self.tone_rf_hz = tone_rf_hz
        self.elements = elements
        self.sigma_floor = sigma_floor_hz_s
        self.live = live
        self.stream: BeaconStream | None = None
        self.notes: list[str] = []
        self.start_unix = math.nan
        self._fh = None
        self._n_read = 0
        self._pending = b""
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._site_set = False
        self.counts = {"samples": 0, "tables": 0, "measurements": 0}
        self.error = ""

    # -- setup
    def _open(self) -> bool:
        if self.stream is not None:
            return True
        meta = self.meta
        if meta is None or not self.data_path.exists():
            return False
        self.stream = BeaconStream(meta["sample_rate_hz"], meta["rf_center_hz"], self.tone_rf_hz, self.elements)
        if self.live and meta.get("t_mono_start_s") is not None:
            self.stream.t_mono_start = float(meta["t_mono_start_s"])
        self._fh = open(self.data_path, "rb")
        return True

    def _read(self, max_samples: int) -> np.ndarray | None:
        data = self._pending + self._fh.read(2 * max_samples - len(self._pending))
        n = len(data) // 2 * 2
        self._pending = data[n:]
        if not n:
            return None
        self._n_read += n // 2
        self.counts["samples"] = self._n_read
        return cu8_to_complex(data[:n])

    def set_site(self, navigator) -> None:
        """Once the road has started: the site (its origin) and the capture start through the time map."""
        road = navigator.road
        if self._site_set or not road.started or self.meta is None or self.meta.get("t_mono_start_s") is None:
            return
        if self.stream is None and not self._open():
            return
        self.start_unix = road.tmap.to_utc(float(self.meta["t_mono_start_s"]))
        start = utc_of(self.start_unix)
        if self.elements is None:
            self.elements = default_elements(start, self.notes)
            self.stream.elements = self.elements
        self.stream.set_site(Site(*road.origin), start)
        self._site_set = True

    # -- fast playback
    def advance_to(self, t_mono: float, navigator) -> None:
        if self.meta is None or self.meta.get("t_mono_start_s") is None or not self._open():
            return
        self.set_site(navigator)
        target = int((t_mono - float(self.meta["t_mono_start_s"])) * self.meta["sample_rate_hz"])
        chunk = int(CHUNK_S * self.meta["sample_rate_hz"])
        while self._n_read < target:
            z = self._read(min(chunk, target - self._n_read))
            if z is None:
                break
            self.stream.push(z)
        self._deliver(self.stream.take(), navigator)

    # -- live: the worker thread
    def start(self, meta_path: Path, recording_alive) -> None:
        self._thread = threading.Thread(target=self._tail, args=(meta_path, recording_alive), daemon=True,
                                        name="leonav-beacons")
        self._thread.start()

    def _tail(self, meta_path: Path, recording_alive) -> None:
        try:
            while self.meta is None and not self._stop.is_set():
                if meta_path.exists():
                    try:
                        self.meta = capture_meta(meta_path)
                    except (json.JSONDecodeError, KeyError, OSError):
                        self.meta = None          # being written: next time
                if self.meta is None:
                    time.sleep(0.05)
            while not self._stop.is_set() and not self._open():
                time.sleep(0.05)
            chunk = int(CHUNK_S * self.meta["sample_rate_hz"])
            while not self._stop.is_set():
                z = self._read(chunk)
                if z is None:
                    if not recording_alive():
                        break
                    time.sleep(0.02)
                    continue
                self.stream.push(z)
                out = self.stream.take()
                if out:
                    self._queue.put(out)
        except Exception as exc:       # the navigator goes on without Doppler-rate, and says why
            self.error = f"{type(exc).__name__}: {exc}"

    def poll(self, navigator) -> None:
        """Main thread: set the site when possible, hand finished measurements to the navigator."""
        if self.stream is not None:
            self.set_site(navigator)
        while True:
            try:
                self._deliver(self._queue.get_nowait(), navigator)
            except queue.Empty:
                return

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self._fh is not None:
            self._fh.close()

    # -- to the road
    def _deliver(self, emitted: list, navigator) -> None:
        road = navigator.road
        if not emitted or not road.started or not math.isfinite(self.start_unix):
            return
        t = np.array([self.start_unix + e.t_s - road.epoch_unix for e in emitted])
        meas = BeaconMeasurements(t, np.array([e.norad_id for e in emitted], int),
                                  np.array([e.sat_index for e in emitted], int),
                                  np.array([e.rate_hz_s for e in emitted]), np.array([e.sigma_hz_s for e in emitted]))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = doppler_rate_table(meas, self.elements, road.epoch_utc, self.sigma_floor)
        self.counts["tables"] += 1
        self.counts["measurements"] += int(t.size)
        navigator.on_doppler_rate(table)

    def summary(self) -> dict:
        s = self.stream
        return {"counts": dict(self.counts), "stream": None if s is None else dict(s.counts),
                "max_lag_s": None if s is None else s.max_lag_seen_s,
                "last_association": None if s is None else s.last_summary, "error": self.error, "notes": self.notes,
                "capture_start_utc": utc_of(self.start_unix) if math.isfinite(self.start_unix) else None}
