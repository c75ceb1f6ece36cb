"""RTL-SDR capture of the LNB's IF to an rtl_sdr-format file with SigMF metadata.

The Ku-band LNB mixes the beacon at `rf_center_hz` down by its LO (`lnb_lo_hz`, 9.75 GHz
on a universal LNB's low band), so the SDR is tuned to the IF
`rf_center_hz - lnb_lo_hz` (11.325 - 9.75 = 1.575 GHz by default).

Output: `<name>.cu8`, interleaved unsigned 8-bit I,Q (the `rtl_sdr` tool's format,
0..255 with 127.5 as zero), and `<name>.sigmf-meta` (SigMF 1.x: core:datatype "cu8",
core:sample_rate, one capture with core:frequency = the IF actually tuned and
core:datetime, plus leonav:lnb_lo_hz, leonav:rf_center_hz, leonav:gain_db, leonav:ppm).

pyrtlsdr is imported lazily: it loads librtlsdr at import time, which many machines lack.
"""
from __future__ import annotations

import datetime as _dt
import json
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from leonav.hardware.errors import UserInputError
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ

DEFAULT_RF_HZ = STARLINK_BEACON_HZ
DEFAULT_LNB_LO_HZ = 9.75e9
DEFAULT_SAMPLE_RATE = 2.4e6
READ_BLOCK_BYTES = 2 * 262144           # 262,144 complex samples per read (~0.11 s at 2.4 MS/s)
LIBRTLSDR_HINT = ("librtlsdr not found: install it (Debian/Raspberry Pi OS: "
                  "`sudo apt-get install librtlsdr0`, or `librtlsdr-dev`) and plug in the RTL-SDR")


class SdrUnavailable(UserInputError):
    """The RTL-SDR library or device cannot be used; the message says how to fix it."""


@dataclass
class SdrSettings:
    """Capture settings; frequencies in Hz, gain in dB ('auto' for AGC), ppm correction."""

    rf_center_hz: float = DEFAULT_RF_HZ
    lnb_lo_hz: float = DEFAULT_LNB_LO_HZ
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE
    gain_db: float | str = "auto"
    ppm: int = 0

    @property
    def if_hz(self) -> float:
        return self.rf_center_hz - self.lnb_lo_hz


def open_rtlsdr(device_index: int = 0) -> Any:
    """Open RTL-SDR number `device_index` with pyrtlsdr (lazy import), clear errors otherwise."""
    try:
        from rtlsdr import RtlSdr  # loads librtlsdr: only here
    except (ImportError, OSError) as exc:
        raise SdrUnavailable(f"{LIBRTLSDR_HINT} ({exc})") from exc
    try:
        return RtlSdr(device_index=device_index)
    except Exception as exc:  # pyrtlsdr raises LibUSBError/IOError subclasses per backend
        raise SdrUnavailable(f"RTL-SDR device index {device_index}: not found or busy ({exc})") from exc


def configure(sdr: Any, settings: SdrSettings) -> float:
    """Apply settings to an open RtlSdr; returns the IF frequency the device reports."""
    if not 24e6 <= settings.if_hz <= 1.766e9:
        raise UserInputError(
            f"SDR IF {settings.if_hz / 1e9:.4f} GHz (rf {settings.rf_center_hz / 1e9} GHz - LNB LO "
            f"{settings.lnb_lo_hz / 1e9} GHz) is outside the RTL-SDR tuning range 0.024-1.766 GHz")
    sdr.sample_rate = settings.sample_rate_hz
    if settings.ppm:
        sdr.freq_correction = int(settings.ppm)
    sdr.center_freq = settings.if_hz
    sdr.gain = settings.gain_db
    return float(getattr(sdr, "center_freq", settings.if_hz))


def sigmf_metadata(settings: SdrSettings, tuned_if_hz: float, start: _dt.datetime,
                   sample_rate_hz: float, data_path: Path | None = None,
                   extra: dict | None = None) -> dict:
    """SigMF metadata dict (validated with the `sigmf` package); sha512 if data_path given."""
    from sigmf import SigMFFile

    global_info = {
        "core:datatype": "cu8",
        "core:sample_rate": float(sample_rate_hz),
        "core:recorder": "leonav record (pyrtlsdr)",
        "core:description": "Ku-band LNB IF captured by an RTL-SDR",
        "core:extensions": [{"name": "leonav", "version": "0.1.0", "optional": True}],
        "leonav:lnb_lo_hz": float(settings.lnb_lo_hz),
        "leonav:rf_center_hz": float(tuned_if_hz + settings.lnb_lo_hz),
        "leonav:gain_db": settings.gain_db,
        "leonav:ppm": int(settings.ppm),
    } | (extra or {})
    meta = SigMFFile(data_file=str(data_path) if data_path else None, global_info=global_info,
                     skip_checksum=data_path is None)
    stamp = start.astimezone(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    meta.add_capture(0, metadata={"core:frequency": float(tuned_if_hz), "core:datetime": stamp})
    meta.validate()
    return json.loads(meta.dumps())


@dataclass
class CaptureResult:
    data_path: Path
    meta_path: Path
    n_bytes: int
    n_samples: int
    t_mono_start_s: float
    t_mono_stop_s: float
    end_reason: str


def capture(sdr: Any, out_stem: Path, settings: SdrSettings, seconds: float,
            stop_event: threading.Event | None = None,
            on_block: Callable[[int, float], None] | None = None, lost=None) -> CaptureResult:
    """Stream `seconds` of IQ from an open RtlSdr to `<out_stem>.cu8` + `.sigmf-meta`.

    Blocks are written (unbuffered) as they arrive; a partial `.sigmf-meta` (no checksum)
    is written before the first block so an interrupted capture stays readable.
    `on_block(n_bytes, t_mono_s)` is called after each block (progress, session counts).
    With `lost` (a `session_files.LostWrites`) a write that fails (a full disk) is counted there
    and the capture goes on reading without writing: the file keeps the samples up to the
    failure (a gap would shift every later sample's time), every later block is counted lost.
    """
    from leonav.hardware.session_files import RecordFile

    def write_meta(meta: dict) -> None:
        try:
            meta_path.write_text(json.dumps(meta, indent=2))
        except OSError as exc:
            if lost is None:
                raise
            lost.add(meta_path, exc)

    stop_event = stop_event or threading.Event()
    data_path = Path(str(out_stem) + ".cu8")
    meta_path = Path(str(out_stem) + ".sigmf-meta")
    tuned = configure(sdr, settings)
    rate = float(getattr(sdr, "sample_rate", settings.sample_rate_hz))
    start_utc = _dt.datetime.now(_dt.timezone.utc)
    t0 = time.monotonic()
    write_meta(sigmf_metadata(settings, tuned, start_utc, rate, extra={"leonav:t_mono_start_s": t0}))
    target = int(round(seconds * rate)) * 2
    written = taken = 0     # bytes in the file, bytes read from the device
    end_reason = "done"
    fh = RecordFile(data_path, lost)
    failed = False
    try:
        while taken < target:
            if stop_event.is_set():
                end_reason = "stopped"
                break
            try:
                block = sdr.read_bytes(min(READ_BLOCK_BYTES, target - taken))
            except Exception as exc:  # device unplugged: keep what we have
                end_reason = f"device error: {exc}"
                break
            taken += len(block)
            if failed:
                lost.add(data_path, fh.last_error)
            elif not fh.write(bytes(block)):
                failed = True
            if not failed:
                written += len(block)
            if on_block:
                on_block(len(block), time.monotonic())
    finally:
        fh.close()
    t1 = time.monotonic()
    try:
        sdr.close()
    except Exception:
        pass
    meta = sigmf_metadata(settings, tuned, start_utc, rate, data_path,
                          extra={"leonav:t_mono_start_s": t0, "leonav:t_mono_stop_s": t1,
                                 "leonav:end_reason": end_reason})
    write_meta(meta)
    return CaptureResult(data_path, meta_path, written, written // 2, t0, t1, end_reason)
