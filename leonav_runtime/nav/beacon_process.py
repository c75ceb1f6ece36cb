"""Live beacons in their own process: the growing capture -> `BeaconStream` -> Doppler-rate rows.

`BeaconProcess` starts `_child` (multiprocessing, "spawn": the parent has device threads
running, which a fork would copy half-way). The child waits for the recorder's
`sdr.sigmf-meta`, reads `sdr.cu8` as it grows (`beacon_feed.CaptureFile`, `CHUNK_S` pieces),
pushes it through the stream, and for every finished measurement sends one row of a
`DopplerRateTable` (t on the road's axis, NORAD id, rate, sigma, SGP4 satellite state) once
the parent has told it the site and the time axis ("site" message, after the road started).
It ends when the parent asks, or when the recording has ended and the file is read; its last
message is its summary. The parent (`poll`, in the navigator's loop) only moves small arrays.
"""
from __future__ import annotations

import math
import multiprocessing as mp
import queue
import time
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.inputs import DopplerRateTable

IDLE_S = 0.02


def _child(data_path: str, meta_path: str, f_c_hz: float, tle_files: tuple, sigma_floor: float,
           inbox, outbox, recording_done, stop, operator_folder: str | None = None,
           carrier_phase: bool = False) -> None:
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.nav.beacon_feed import CHUNK_S, CaptureFile, capture_meta, stream_summary
    from leonav_runtime.orbits.operator_folder import OperatorFolder
    from leonav_runtime.nav.beacon_stream import BeaconStream
    from leonav_runtime.orbits.elements import load_element_files
    from leonav_runtime.replay.beacon_table import default_elements
    from leonav_runtime.replay.timebase import utc_of

    warnings.simplefilter("ignore")
    stream, capture, error, notes = None, None, "", []
    counts = {"samples": 0, "tables": 0, "measurements": 0}
    start_unix = epoch_unix = math.nan
    site_origin = None
    try:
        elements = load_element_files(list(tle_files))
        operator = OperatorFolder(operator_folder) if operator_folder else None
        meta = None
        while meta is None and not stop.is_set():
            try:
                meta = capture_meta(Path(meta_path)) if Path(data_path).exists() else None
            except (ValueError, KeyError, OSError):
                meta = None                     # being written
            if meta is None:
                if recording_done.is_set():
                    raise RuntimeError("the SDR recording ended before its metadata was written")
                time.sleep(0.05)
        if meta is not None:
            stream = BeaconStream(meta["sample_rate_hz"], meta["rf_center_hz"], f_c_hz, elements,
                                  carrier_phase=carrier_phase)
            stream.t_mono_start = meta.get("t_mono_start_s")
            capture = CaptureFile(Path(data_path))
            chunk = int(CHUNK_S * meta["sample_rate_hz"])
        while stream is not None and not stop.is_set():
            try:
                msg = inbox.get_nowait()
            except queue.Empty:
                msg = None
            if msg is not None and msg[0] == "site":
                _, origin, start_unix, epoch_unix = msg
                site_origin = origin
                if elements is None:
                    elements = stream.elements = default_elements(utc_of(start_unix), notes)
                stream.set_site(Site(*origin), utc_of(start_unix))
            z = capture.read(chunk)
            if z is None:
                if recording_done.is_set():     # all of it read: its last block and phase epochs too
                    stream.flush()
                    counts["flushed_at_samples"] = capture.n_read
                    _send(stream, counts, elements, sigma_floor, operator, site_origin, start_unix, epoch_unix,
                          outbox)
                    break
                time.sleep(IDLE_S)
                continue
            counts["samples"] = capture.n_read
            stream.push(z)
            _send(stream, counts, elements, sigma_floor, operator, site_origin, start_unix, epoch_unix, outbox)
    except Exception as exc:      # the navigator goes on without Doppler-rate, and says why
        error = f"{type(exc).__name__}: {exc}"
    finally:
        if capture is not None:
            capture.close()
        outbox.put(("summary", stream_summary(stream, counts, error, notes, start_unix)))


def _send(stream, counts: dict, elements, sigma_floor: float, operator, site_origin, start_unix: float,
          epoch_unix: float, outbox) -> None:
    """What the stream has made since the last call, as Doppler-rate and phase tables to the parent."""
    from leonav_runtime.nav.beacon_feed import emitted_names, phase_names, stream_tables

    emitted, rate, diffs, phase = stream_tables(stream, math.isfinite(epoch_unix), start_unix, epoch_unix, elements,
                                                sigma_floor, operator, site_origin, counts)
    if rate is not None:
        outbox.put(("table", rate.t, rate.sat_id, rate.z, np.broadcast_to(rate.sigma, rate.t.shape).copy(),
                    rate.sat_ecef, emitted_names(emitted, elements)))
    if phase is not None:
        outbox.put(("phase", phase, phase_names(diffs, stream.phase_tones, elements)))


STOP_WAIT_S = 10.0
"""Longest wait (s) at stop for the beacon process's summary before it is terminated."""


class BeaconProcess:
    """The parent side (module doc)."""

    def __init__(self, data_path: Path, f_c_hz: float, tle_files: tuple, sigma_floor_hz_s: float,
                 operator=None, carrier_phase: bool = False) -> None:
        """operator: an `orbits.operator_folder.OperatorFolder`: the child reads the same folder for the
        states, this side for the road's consider term (the names come with each table)."""
        self.data_path = Path(data_path)
        self.operator = operator
        self.carrier_phase = carrier_phase
        self.f_c_hz = f_c_hz
        self.tle_files = tuple(str(p) for p in tle_files)
        self.sigma_floor = sigma_floor_hz_s
        ctx = mp.get_context("spawn")
        self._inbox, self._outbox = ctx.Queue(), ctx.Queue()
        self._recording_done, self._stop = ctx.Event(), ctx.Event()
        self._ctx = ctx
        self._proc = None
        self._recording_alive = lambda: True
        self._site_sent = False
        self._summary: dict = {}
        self.tables = 0

    def start(self, meta_path: Path, recording_alive) -> None:
        self._recording_alive = recording_alive
        self._meta_path = Path(meta_path)
        self._proc = self._ctx.Process(
            target=_child, name="leonav-beacons", daemon=True,
            args=(str(self.data_path), str(meta_path), self.f_c_hz, self.tle_files, self.sigma_floor,
                  self._inbox, self._outbox, self._recording_done, self._stop,
                  None if self.operator is None else str(self.operator.folder), self.carrier_phase))
        self._proc.start()

    def _send_site(self, navigator) -> None:
        from leonav_runtime.nav.beacon_feed import capture_meta

        road = navigator.road
        if self._site_sent or not road.started or not self._meta_path.exists():
            return
        try:
            t0 = capture_meta(self._meta_path).get("t_mono_start_s")
        except (ValueError, KeyError, OSError):
            return
        if t0 is None:
            return
        self._inbox.put(("site", tuple(road.origin), road.tmap.to_utc(float(t0)), road.epoch_unix))
        self._site_sent = True

    def poll(self, navigator) -> None:
        self._send_site(navigator)
        if not self._recording_alive():
            self._recording_done.set()
        while True:
            try:
                msg = self._outbox.get_nowait()
            except queue.Empty:
                return
            self._handle(msg, navigator)

    def _handle(self, msg, navigator) -> None:
        if msg[0] == "summary":
            self._summary = msg[1]
            return
        if msg[0] == "phase":
            _, table, names = msg
            if self.operator is not None:
                self.operator.ensure(names)
            if navigator is not None:
                navigator.on_carrier_phase(table)
            return
        _, t, sat_id, z, sigma, sat_ecef, names = msg
        self.tables += 1
        if self.operator is not None:
            self.operator.ensure(names)
        if navigator is not None:
            navigator.on_doppler_rate(DopplerRateTable(t, sat_id, z, sigma, sat_ecef))

    def finish(self, navigator) -> None:
        """The recording is over and all of it is to be used: the process reads to its end, flushes
        its stream and stops; what it sends meanwhile reaches the navigator (`STOP_WAIT_S` at most)."""
        self._recording_done.set()
        self._drain(navigator)

    def stop(self) -> None:
        self._stop.set()
        self._recording_done.set()
        self._drain(None)
        if self._proc is not None:
            self._proc.join(timeout=2.0)
            if self._proc.is_alive():
                self._proc.terminate()

    def _drain(self, navigator) -> None:
        """Messages until the process's summary: the process drains what it has read first, and on
        a loaded machine (or a Pi) that takes seconds."""
        deadline = time.monotonic() + STOP_WAIT_S
        while not self._summary and time.monotonic() < deadline and self._proc is not None:
            try:
                self._handle(self._outbox.get(timeout=0.2), navigator)
            except queue.Empty:
                if not self._proc.is_alive():
                    break

    def summary(self) -> dict:
        return self._summary or {"error": "the beacon process sent no summary"}
