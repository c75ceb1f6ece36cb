"""The rover's corrections reader: TCP to a base, lines -> `DifferentialCorrections`.

A thread connects to HOST:PORT, reads lines, parses them (`protocol.parse_line`) and adds
corrections to the store. Bad input never stops it: a garbled line (bad checksum, wrong field
count, a non-number, unknown observable or unit, a line over 256 bytes) is counted under
`rejected_garbled` with the first reason kept; a correction for another constellation or
observable is refused by the store (counted); a late or stale one is the store's to judge.
When the base goes away (connection refused, reset, closed) the reader says so once
(`events`), counts it, and tries again every `RETRY_S` seconds for as long as the rover runs;
meanwhile the rover's measurements fall back to uncorrected ones as their corrections age.
"""
from __future__ import annotations

import socket
import threading
import time

from leonav_runtime.base import protocol
from leonav_runtime.inputs.corrections import DifferentialCorrections

RETRY_S = 1.0
SILENT_S = 3.0      # no line (not even a heartbeat) for this long: the stream is silent


def parse_address(text: str, option: str = "--corrections") -> tuple[str, int]:
    """'HOST:PORT' -> (host, port); a ValueError names the option and what was expected."""
    host, sep, port = str(text).rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"{option} {text!r}: expected HOST:PORT, e.g. 127.0.0.1:2101")
    return host.strip("[]"), int(port)


def feed_lines(store: DifferentialCorrections, lines, counts: dict | None = None) -> None:
    """Parse byte lines into the store (also for a recorded corrections file); counts gets
    `lines`, `heartbeats`, `headers`."""
    counts = counts if counts is not None else {}
    for raw in lines:
        if not raw.strip():
            continue
        counts["lines"] = counts.get("lines", 0) + 1
        try:
            rec = protocol.parse_line(raw)
        except protocol.LineError as exc:
            store.reject("garbled", str(exc))
            continue
        if isinstance(rec, protocol.Correction):
            store.add(rec.constellation, rec.norad_id, rec.observable, rec.t_utc_s, rec.value, rec.sigma)
        elif isinstance(rec, protocol.Heartbeat):
            counts["heartbeats"] = counts.get("heartbeats", 0) + 1
        else:
            counts["headers"] = counts.get("headers", 0) + 1
            counts["base_position_deg_m"] = [rec.lat_deg, rec.lon_deg, rec.h_m]


class CorrectionsClient:
    """The reader thread (module doc); `describe()` for nav.json, `status_text()` for the status line."""

    def __init__(self, host: str, port: int, store: DifferentialCorrections, on_event=None) -> None:
        self.host, self.port, self.store = host, port, store
        self.on_event = on_event or (lambda text, kind: None)
        self.counts: dict = {"connects": 0, "disconnects": 0, "connect_failures": 0, "lines": 0}
        self.connected = False
        self.last_line_mono = -1e18
        self._stop = threading.Event()
        self._sock: socket.socket | None = None
        self._thread = threading.Thread(target=self._run, daemon=True, name="leonav-corrections")

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        said_down = False
        while not self._stop.is_set():
            try:
                sock = socket.create_connection((self.host, self.port), timeout=2.0)
            except OSError as exc:
                self.counts["connect_failures"] += 1
                if not said_down:
                    self.on_event(f"corrections: no base at {self.host}:{self.port} ({exc.strerror or exc}); "
                                  f"retrying every {RETRY_S:g} s, measurements uncorrected", "corrections_down")
                    said_down = True
                self._stop.wait(RETRY_S)
                continue
            self._sock = sock
            sock.settimeout(0.5)
            self.connected, said_down = True, False
            self.counts["connects"] += 1
            self.on_event(f"corrections: connected to base {self.host}:{self.port}", "corrections_up")
            buf = b""
            try:
                while not self._stop.is_set():
                    try:
                        data = sock.recv(65536)
                    except socket.timeout:
                        continue
                    if not data:
                        break
                    buf += data
                    *lines, buf = buf.split(b"\n")
                    if len(buf) > protocol.MAX_LINE_BYTES:        # no line end in sight: junk
                        lines.append(buf)
                        buf = b""
                    if lines:
                        self.last_line_mono = time.monotonic()
                        feed_lines(self.store, lines, self.counts)
            except OSError:
                pass
            finally:
                sock.close()
                self._sock = None
                self.connected = False
            if not self._stop.is_set():
                self.counts["disconnects"] += 1
                self.on_event(f"corrections: base {self.host}:{self.port} went away; reconnecting, measurements "
                              f"fall back to uncorrected as corrections age past {self.store.max_age_s:g} s",
                              "corrections_down")
                said_down = True
                self._stop.wait(RETRY_S)

    def status_text(self) -> str:
        """'corr age 0.8 s' / 'corr FALLBACK ...' for the status line."""
        s = self.store
        link = "" if self.connected else " (base down)"
        if s.state == "applied":
            return f"corr age {s.last_age_s:.1f} s{link}"
        if s.state == "fallback":
            return f"corr FALLBACK{link}"
        return f"corr waiting{link}"

    def describe(self) -> dict:
        silent = time.monotonic() - self.last_line_mono
        return {"address": f"{self.host}:{self.port}", "connected": self.connected,
                "silent_s": None if silent > 1e17 else round(silent, 3),
                "link": dict(self.counts)} | self.store.describe()

    def stop(self) -> None:
        self._stop.set()
        if self._sock is not None:
            try:
                self._sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        self._thread.join(timeout=2.0)
