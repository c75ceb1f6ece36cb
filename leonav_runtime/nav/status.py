"""The one-line terminal status of `leonav nav` (stderr), and the run's event messages.

On a terminal the line is rewritten in place (at most `refresh_s` apart): mode, position
sigma (3D, horizontal), GNSS fixes applied in the last second, Starlink records (Doppler-rate
and carrier phase) and their satellites in the last 10 s, latency from an IMU packet's arrival to the updated
solution (median / 99th percentile over the last second), bytes rejected as garbage, and any
fault. Elsewhere (a log, systemd's journal) the same line is printed as its own line every
`log_every_s`. Events (a device lost, GNSS back, the start) are printed as lines above it.
"""
from __future__ import annotations

import sys
import time


class StatusLine:
    def __init__(self, stream=None, enabled: bool = True, refresh_s: float = 0.5, log_every_s: float = 10.0) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.refresh_s = refresh_s if self.tty else log_every_s
        self._last = -1e9
        self._shown = False

    def due(self) -> bool:
        """Whether `update` would draw now (so the caller builds the text only then)."""
        return self.enabled and time.monotonic() - self._last >= self.refresh_s

    def update(self, text: str, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < self.refresh_s:
            return
        self._last = now
        if self.tty:
            self.stream.write("\r\x1b[2K" + text[:200])
            self._shown = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def event(self, text: str) -> None:
        if not self.enabled:
            return
        if self.tty and self._shown:
            self.stream.write("\r\x1b[2K")
        self.stream.write(text + "\n")
        self.stream.flush()
        self._last = -1e9        # redraw the status after the event

    def close(self) -> None:
        if self.enabled and self.tty and self._shown:
            self.stream.write("\n")
            self.stream.flush()


def format_status(s: dict) -> str:
    """The status line from the navigator's snapshot (`Navigator.snapshot`)."""
    if not s["started"]:
        return f"[nav {s['elapsed_s']:6.1f} s] waiting: {s['waiting_for']} | junk {s['junk_bytes']} B" + (
            f" | {s['faults']}" if s["faults"] else "")
    sig = s["sigma_3d_m"]
    lat = s["latency_ms"]
    lat_txt = f"{lat[0]:.1f}/{lat[1]:.1f} ms" if lat else "-"
    return (f"[nav {s['elapsed_s']:6.1f} s] {s['mode']} | sigma {sig:.2f} m (h {s['sigma_h_m']:.2f}) | "
            f"GNSS {s['gnss_1s']}/s | Starlink {s['leo_10s']}/10s ({s['leo_sats']} sats) | latency {lat_txt} | "
            f"junk {s['junk_bytes']} B" + (f" | {s['corrections']}" if s.get("corrections") else "")
            + (f" | {s['faults']}" if s["faults"] else ""))
