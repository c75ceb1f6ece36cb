"""Byte-level stand-ins for the devices, for tests and dry runs without hardware.

- `PtyDevice`: a pseudo-terminal pair; the slave path behaves like a serial port for
  pyserial, the master side is fed recorded bytes (optionally paced) by a thread and can
  be closed to simulate a device that is unplugged mid-run.
- `FakeRtlSdr`: the subset of pyrtlsdr's `RtlSdr` that `hardware.sdr.capture` uses,
  producing a deterministic cu8 test signal (a complex tone plus noise).
- `serial_chunks`: bytes sent over a UART and read by a host at random times, as
  (chunk, read time) pairs (the synthetic session writer, `fake_session.py`, uses it).
"""
from __future__ import annotations

import math
import os
import threading
import time
import tty
from typing import Sequence

import numpy as np

from leonav.hardware.uart import serialization_s


class PtyDevice:
    """A pty pair fed from `chunks` (bytes objects) with `delay_s` between chunks.

    `path` is the slave side to open like a serial port. After the data, the feeder
    keeps the master open (a device that goes quiet) unless `close_after_s` is given,
    in which case it closes the master that long after the last chunk (device gone).
    Call `start()` after the reader opened `path`: pyserial flushes pending input on open.
    """

    def __init__(self, chunks: Sequence[bytes], delay_s: float = 0.0,
                 close_after_s: float | None = None, start: bool = False) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)            # binary-safe before anyone opens it (no CR/LF mapping)
        self.path = os.ttyname(self.slave)
        self.chunks = list(chunks)
        self.delay_s = delay_s
        self.close_after_s = close_after_s
        self.done = threading.Event()
        self.bytes_written = 0
        self._thread = threading.Thread(target=self._feed, daemon=True)
        if start:
            self.start()

    def start(self) -> None:
        self._thread.start()

    def _feed(self) -> None:
        try:
            t0 = time.monotonic()
            for k, chunk in enumerate(self.chunks):
                view = memoryview(chunk)
                while view:                           # a tty write may be partial
                    n = os.write(self.master, view)
                    view = view[n:]
                    self.bytes_written += n
                if self.delay_s:                      # absolute schedule: no accumulated lag
                    time.sleep(max(0.0, t0 + (k + 1) * self.delay_s - time.monotonic()))
            self.done.set()
            if self.close_after_s is not None:
                time.sleep(self.close_after_s)
                self.close_master()
        except OSError:
            self.done.set()

    def close_master(self) -> None:
        try:
            os.close(self.master)
        except OSError:
            pass

    def close(self) -> None:
        self.close_master()
        try:
            os.close(self.slave)
        except OSError:
            pass


def split_bytes(data: bytes, size: int) -> list[bytes]:
    return [data[i:i + size] for i in range(0, len(data), size)]


class FakeRtlSdr:
    """Imitates pyrtlsdr's RtlSdr: settable sample_rate/center_freq/gain/freq_correction,
    `read_bytes(n)` returning cu8 IQ of a tone at `tone_hz` from the tuned centre, and
    `close()`. `fail_after_bytes` makes it raise IOError like an unplugged dongle."""

    def __init__(self, tone_hz: float = 25e3, seed: int = 0, fail_after_bytes: int | None = None,
                 realtime: bool = False) -> None:
        self.sample_rate = 2.048e6
        self.center_freq = 100e6
        self.gain = "auto"
        self.freq_correction = 0
        self.tone_hz = tone_hz
        self.closed = False
        self.fail_after_bytes = fail_after_bytes
        self.realtime = realtime
        self._rng = np.random.default_rng(seed)
        self._n = 0          # samples produced so far (phase continuity)

    def read_bytes(self, num_bytes: int) -> bytearray:
        if self.closed:
            raise IOError("device closed")
        if self.fail_after_bytes is not None and 2 * self._n >= self.fail_after_bytes:
            raise IOError("LIBUSB_ERROR_NO_DEVICE (fake unplug)")
        n = num_bytes // 2
        k = np.arange(self._n, self._n + n)
        z = 0.5 * np.exp(2j * np.pi * self.tone_hz * k / self.sample_rate)
        z += 0.05 * (self._rng.standard_normal(n) + 1j * self._rng.standard_normal(n))
        iq = np.empty(2 * n, np.float64)
        iq[0::2], iq[1::2] = z.real, z.imag
        self._n += n
        if self.realtime:
            time.sleep(n / self.sample_rate)
        return bytearray(np.clip(np.round(iq * 127.5 + 127.5), 0, 255).astype(np.uint8).tobytes())

    def close(self) -> None:
        self.closed = True


def serial_chunks(bursts: list[tuple[float, bytes]], baud: int, rng: np.random.Generator,
                  host_read_s: float, t_stop: float) -> list[tuple[bytes, float]]:
    """(chunk, t_read) as a host reading a UART would see them (times in s, any origin).

    bursts: (time the first byte starts, bytes), in time order. Bytes go out back to back
    at `baud` (a burst waits for the previous one); byte i is complete at start +
    (i+1) * `uart.serialization_s(1, baud)`. The host reads at times spaced by
    0.5 ms + Exp(host_read_s) and gets every byte complete by then; reads that find
    nothing return nothing; a last read 1 ms after the last byte collects the rest.
    """
    if not bursts:
        return []
    t_byte = serialization_s(1, baud)
    ends, data = [], []
    free = -math.inf
    for t0, payload in bursts:
        start = max(t0, free)
        e = start + t_byte * np.arange(1, len(payload) + 1)
        ends.append(e)
        data.append(payload)
        free = e[-1]
    ends_all = np.concatenate(ends)
    blob = b"".join(data)
    n_reads = int((max(t_stop, ends_all[-1]) - bursts[0][0]) / (0.0005 + host_read_s)) * 2 + 10
    reads = bursts[0][0] + np.cumsum(0.0005 + rng.exponential(host_read_s, n_reads))
    reads = reads[reads <= max(t_stop, ends_all[-1]) + 0.06]
    reads = np.append(reads, ends_all[-1] + 0.001)       # the last bytes are read
    cut = np.searchsorted(ends_all, reads, side="right")
    out, prev = [], 0
    for c, t in zip(cut, reads):
        if c > prev:
            out.append((blob[prev:c], float(t)))
            prev = c
    return out
