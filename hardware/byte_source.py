"""Byte sources for the readers: a serial port (pyserial, incl. `loop://` URLs), a file,
any object with `read`, or a bytes object; each chunk stamped on arrival.

The stamp is `time.monotonic()` right after `read` returns, so it is the arrival time
of the *last* byte of the chunk (up to one read timeout late for the first ones).
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterator

import serial

from leonav.hardware.errors import UserInputError

READ_TIMEOUT_S = 0.05   # serial read timeout: bounds how late a stop request is noticed
FILE_CHUNK = 4096


def open_port(port: str, baudrate: int) -> serial.SerialBase:
    """Open a serial device or pyserial URL (e.g. `/dev/ttyS0`, `loop://`) in raw 8N1."""
    try:
        return serial.serial_for_url(port, baudrate=baudrate, timeout=READ_TIMEOUT_S)
    except (serial.SerialException, ValueError) as exc:
        raise UserInputError(f"serial port {port!r}: cannot open at {baudrate} baud ({exc})") from exc


def _looks_like_port(name: str) -> bool:
    return name.startswith("/dev/") or "://" in name or name.upper().startswith("COM")


@dataclass
class ChunkSource:
    """Iterates `(chunk, t_mono_s)` from a port, file, stream or bytes until EOF/stop/error.

    After iteration `end_reason` says why it ended: "eof", "stopped", or
    "device error: ..." (a serial port that disappeared).
    """

    source: Any
    baudrate: int = 38400
    stop_event: threading.Event = field(default_factory=threading.Event)
    end_reason: str = ""
    bytes_read: int = 0

    def __post_init__(self) -> None:
        self._owned: BinaryIO | serial.SerialBase | None = None
        src = self.source
        if isinstance(src, (str, Path)):
            if isinstance(src, str) and _looks_like_port(src):
                self._owned = open_port(src, self.baudrate)
            else:
                try:
                    self._owned = open(src, "rb")
                except OSError as exc:
                    raise UserInputError(f"{src}: cannot open ({exc})") from exc
            self.source = self._owned

    @property
    def is_serial(self) -> bool:
        return isinstance(self.source, serial.SerialBase)

    def write(self, data: bytes) -> None:
        """Send bytes to the device (configuration commands)."""
        if not hasattr(self.source, "write"):
            raise UserInputError("this byte source is read-only: cannot send configuration")
        self.source.write(data)
        if hasattr(self.source, "flush"):
            self.source.flush()

    def close(self) -> None:
        if self._owned is not None:
            try:
                self._owned.close()
            except (OSError, serial.SerialException):
                pass

    def __iter__(self) -> Iterator[tuple[bytes, float]]:
        src = self.source
        if isinstance(src, (bytes, bytearray, memoryview)):
            self.bytes_read += len(src)
            yield bytes(src), time.monotonic()
            self.end_reason = "eof"
            return
        serial_port = self.is_serial
        while True:
            if self.stop_event.is_set():
                self.end_reason = "stopped"
                return
            try:
                if serial_port:
                    chunk = src.read(max(1, min(src.in_waiting, 65536)))
                else:
                    chunk = src.read(FILE_CHUNK)
            except (serial.SerialException, OSError) as exc:
                self.end_reason = f"device error: {exc}"
                return
            t_mono = time.monotonic()
            if not chunk:
                if serial_port:
                    continue        # read timeout: no data yet
                self.end_reason = "eof"
                return
            self.bytes_read += len(chunk)
            yield bytes(chunk), t_mono


class SourceReader:
    """Base of the device readers: owns a `ChunkSource` and exposes its controls.

    Subclasses iterate `self.chunks()` (which hands every raw chunk to `on_bytes` first,
    for raw logging) and decode what they need.
    """

    def __init__(self, port_or_stream: Any, baudrate: int,
                 on_bytes: "Callable[[bytes, float], None] | None" = None) -> None:
        self.source = ChunkSource(port_or_stream, baudrate)
        self.on_bytes = on_bytes

    def chunks(self) -> Iterator[tuple[bytes, float]]:
        """`(chunk, t_mono_s)` from the source, after `on_bytes` has seen each one."""
        for chunk, t_mono in self.source:
            if self.on_bytes:
                self.on_bytes(chunk, t_mono)
            yield chunk, t_mono

    def stop(self) -> None:
        """Ask the iteration to end (noticed within one read timeout)."""
        self.source.stop_event.set()

    def write(self, data: bytes) -> None:
        """Send bytes to the device (configuration commands)."""
        self.source.write(data)

    def close(self) -> None:
        self.source.close()

    @property
    def end_reason(self) -> str:
        """Why iteration ended: "eof", "stopped" or "device error: ..."."""
        return self.source.end_reason
