"""The base's TCP server: every connected rover gets the HDR line, then every line sent.

Listens on 127.0.0.1 unless told otherwise. Sends never block the base: each client has a
queue of bytes written with non-blocking sends by the serving thread; a client that stops
reading is dropped once `MAX_QUEUED_BYTES` wait for it (counted), so a dead rover delays
nothing.
"""
from __future__ import annotations

import selectors
import socket
import threading

MAX_QUEUED_BYTES = 1 << 20
MAX_CLIENTS = 32


class CorrectionsServer:
    def __init__(self, host: str, port: int, header: str) -> None:
        self.header = header.encode("ascii")
        self.sock = socket.create_server((host, port), reuse_port=False)
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()[:2]
        self._sel = selectors.DefaultSelector()
        self._sel.register(self.sock, selectors.EVENT_READ)
        self._clients: dict[socket.socket, bytearray] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.counts = {"clients_accepted": 0, "clients_refused_limit": 0, "clients_dropped_slow": 0,
                       "clients_closed": 0, "lines_sent": 0}
        self._thread = threading.Thread(target=self._serve, daemon=True, name="leonav-base-server")
        self._thread.start()

    @property
    def clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def send(self, text: str) -> None:
        """Queue `text` (whole lines) for every client."""
        data = text.encode("ascii")
        with self._lock:
            for c, buf in list(self._clients.items()):
                buf += data
                if len(buf) > MAX_QUEUED_BYTES:
                    self._drop(c, "clients_dropped_slow")
            self.counts["lines_sent"] += text.count("\n")
        self._flush()

    def _drop(self, c: socket.socket, why: str) -> None:
        self._clients.pop(c, None)
        try:
            self._sel.unregister(c)
        except (KeyError, ValueError):
            pass
        c.close()
        self.counts[why] += 1

    def _flush(self) -> None:
        with self._lock:
            for c, buf in list(self._clients.items()):
                if not buf:
                    continue
                try:
                    n = c.send(buf)
                    del buf[:n]
                except BlockingIOError:
                    pass
                except OSError:
                    self._drop(c, "clients_closed")

    def _serve(self) -> None:
        while not self._stop.is_set():
            for key, _ in self._sel.select(timeout=0.1):
                if key.fileobj is self.sock:
                    try:
                        c, _ = self.sock.accept()
                    except OSError:
                        continue
                    with self._lock:
                        if len(self._clients) >= MAX_CLIENTS:
                            c.close()
                            self.counts["clients_refused_limit"] += 1
                            continue
                        c.setblocking(False)
                        self._clients[c] = bytearray(self.header)
                        self._sel.register(c, selectors.EVENT_READ)
                        self.counts["clients_accepted"] += 1
                else:                       # a rover sends nothing: readable means closed (or junk)
                    c = key.fileobj
                    try:
                        data = c.recv(4096)
                    except OSError:
                        data = b""
                    if not data:
                        with self._lock:
                            self._drop(c, "clients_closed")
            self._flush()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._flush()
        with self._lock:
            for c in list(self._clients):
                self._drop(c, "clients_closed")
        self._sel.close()
        self.sock.close()
