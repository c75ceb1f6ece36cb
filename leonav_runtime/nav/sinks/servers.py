"""Byte sinks for live outputs: a TCP broadcast server and a pseudo-terminal.

`TcpBroadcastServer` accepts any number of clients (gpsd, OpenCPN, QGIS, `nc`) and sends
every line to each; it listens on 127.0.0.1 unless another host is named. A client that
stops reading is dropped once its backlog passes `max_backlog_bytes` (counted), so a slow
client never blocks the navigator. `PtyOutput` opens a pseudo-terminal and links its
device to a path (`/tmp/leonav-nmea`), for programs that only read serial ports.
"""
from __future__ import annotations

import os
import select
import socket
import threading
from pathlib import Path


class TcpBroadcastServer:
    """Send bytes to every connected client; accept in a background thread."""

    def __init__(self, host: str = "127.0.0.1", port: int = 10110, max_backlog_bytes: int = 1 << 20) -> None:
        self._listener = socket.create_server((host, port), reuse_port=False)
        self._listener.settimeout(0.2)
        self.address = self._listener.getsockname()[:2]
        self.max_backlog_bytes = max_backlog_bytes
        self._clients: dict[socket.socket, bytearray] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.counts = {"clients_accepted": 0, "clients_dropped_slow": 0, "clients_closed": 0, "bytes_sent": 0}
        self._thread = threading.Thread(target=self._accept_loop, name="leonav-tcp-accept", daemon=True)
        self._thread.start()

    def _accept_loop(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return
            conn.setblocking(False)
            with self._lock:
                self._clients[conn] = bytearray()
                self.counts["clients_accepted"] += 1

    @property
    def n_clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def send(self, data: bytes) -> None:
        """Queue `data` for every client and write what each socket takes now."""
        with self._lock:
            for conn, backlog in list(self._clients.items()):
                backlog += data
                try:
                    n = conn.send(backlog)
                    del backlog[:n]
                    self.counts["bytes_sent"] += n
                except BlockingIOError:
                    pass
                except OSError:
                    self._drop(conn, "clients_closed")
                    continue
                if len(backlog) > self.max_backlog_bytes:
                    self._drop(conn, "clients_dropped_slow")

    def _drop(self, conn: socket.socket, reason: str) -> None:
        self._clients.pop(conn, None)
        self.counts[reason] += 1
        try:
            conn.close()
        except OSError:
            pass

    def close(self) -> None:
        """Flush what each client takes within a short time, then close everything."""
        self._stop.set()
        with self._lock:
            for conn, backlog in list(self._clients.items()):
                try:
                    conn.setblocking(True)
                    conn.settimeout(0.5)
                    if backlog:
                        conn.sendall(backlog)
                except OSError:
                    pass
                conn.close()
            self._clients.clear()
        self._listener.close()
        self._thread.join(timeout=1.0)


class PtyOutput:
    """A pseudo-terminal whose device path is linked at `link` (bytes written to it are
    read by whoever opens the link). Output while nobody reads is discarded by the line
    discipline's buffer limit, never blocking the writer."""

    def __init__(self, link: str | Path) -> None:
        import tty

        self._master, slave = os.openpty()
        tty.setraw(slave)
        self.device = os.ttyname(slave)
        self._slave = slave
        os.set_blocking(self._master, False)
        self.link = Path(link)
        if self.link.is_symlink() or self.link.exists():
            self.link.unlink()
        self.link.symlink_to(self.device)
        self.counts = {"bytes_written": 0, "bytes_dropped": 0}

    def send(self, data: bytes) -> None:
        try:
            _, writable, _ = select.select([], [self._master], [], 0)
            n = os.write(self._master, data) if writable else 0
        except (BlockingIOError, OSError):
            n = 0
        self.counts["bytes_written"] += n
        self.counts["bytes_dropped"] += len(data) - n

    def close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        if self.link.is_symlink():
            self.link.unlink()
