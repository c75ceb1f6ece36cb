"""Byte sinks for live outputs: a TCP broadcast server and a pseudo-terminal.

`TcpBroadcastServer` serves up to `max_clients` clients (gpsd, OpenCPN, QGIS, `nc`) and sends
every line to each; it listens on 127.0.0.1 unless another host is named. A client beyond the
limit gets one NMEA TXT sentence saying so and is closed (counted). Sends never block: a client
that stops reading is dropped once its backlog passes `max_backlog_bytes` (counted), so a slow or
dead client never delays the navigator, and `close` flushes for at most `CLOSE_FLUSH_S` in all. `PtyOutput` opens a pseudo-terminal and links its
device to a path (`/tmp/leonav-nmea`), for programs that only read serial ports; what is
already at that path is replaced only when it is a link to a pty device (an earlier run's),
anything else is refused with a `UserInputError` and left as it is.
"""
from __future__ import annotations

import os
import re
import select
import selectors
import socket
import stat
import threading
import time
from pathlib import Path

from leonav.hardware.gnss.nmea_write import sentence
from leonav_runtime.common.errors import UserInputError


MAX_CLIENTS = 32
"""Default limit of simultaneous NMEA TCP clients: each holds a file descriptor, and a process that
runs out of descriptors can no longer open its own files (the trajectory, a lazy import)."""
ACCEPT_RETRY_S = 0.1
"""Pause (s) after a failed accept (descriptors exhausted): the server keeps serving, never dies."""
CLOSE_FLUSH_S = 0.5
"""At the end, the time (s) given to all clients together to take their backlog: dead clients
cannot hold up the shutdown."""


def refusal_sentence(max_clients: int) -> bytes:
    """The NMEA TXT sentence a client beyond the limit reads before its connection is closed."""
    return sentence(f"GPTXT,01,01,01,leonav nav: client limit {max_clients} reached; closing")


class TcpBroadcastServer:
    """Send bytes to every connected client (at most `max_clients`; more are closed at once and
    counted); accept in a background thread that survives accept errors. The port is bound at
    once (port 0: a free one, in `address`); with `start=False` accepting waits for `start()`
    (connections wait in the listen backlog meanwhile), so a caller can prepare everything first."""

    def __init__(self, host: str = "127.0.0.1", port: int = 10110, max_backlog_bytes: int = 1 << 20,
                 max_clients: int = MAX_CLIENTS, start: bool = True) -> None:
        self._listener = socket.create_server((host, port), reuse_port=False)
        self._listener.settimeout(0.2)
        self.address = self._listener.getsockname()[:2]
        self.max_backlog_bytes = max_backlog_bytes
        self.max_clients = int(max_clients)
        self._clients: dict[socket.socket, bytearray] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.counts = {"clients_accepted": 0, "clients_dropped_slow": 0, "clients_closed": 0, "bytes_sent": 0,
                       "clients_refused_limit": 0, "accept_errors": 0, "bytes_unsent_at_close": 0}
        self._refusal = refusal_sentence(self.max_clients)
        self._thread = threading.Thread(target=self._accept_loop, name="leonav-tcp-accept", daemon=True)
        if start:
            self.start()

    def start(self) -> None:
        """Start accepting (once)."""
        if self._thread.ident is None and not self._stop.is_set():
            self._thread.start()

    def _accept_loop(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                if self._stop.is_set() or self._listener.fileno() < 0:
                    return
                self.counts["accept_errors"] += 1      # e.g. EMFILE: wait for descriptors, keep serving
                self._stop.wait(ACCEPT_RETRY_S)
                continue
            with self._lock:
                full = len(self._clients) >= self.max_clients
                if full:
                    self.counts["clients_refused_limit"] += 1
                else:
                    conn.setblocking(False)
                    self._clients[conn] = bytearray()
                    self.counts["clients_accepted"] += 1
            if full:      # politely: one line saying why (a fresh socket takes it without blocking), then close
                try:
                    conn.setblocking(False)
                    conn.send(self._refusal)
                    conn.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                conn.close()

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
                    self._send_some(conn, backlog)
                except BlockingIOError:
                    pass
                except OSError:
                    self._drop(conn, "clients_closed")
                    continue
                if len(backlog) > self.max_backlog_bytes:
                    self._drop(conn, "clients_dropped_slow")

    def _send_some(self, conn: socket.socket, backlog: bytearray) -> None:
        """Write what `conn` takes now and remove it from `backlog` (BlockingIOError, OSError: the caller's)."""
        n = conn.send(backlog)
        del backlog[:n]
        self.counts["bytes_sent"] += n

    def _drop(self, conn: socket.socket, reason: str) -> None:
        self._clients.pop(conn, None)
        self.counts[reason] += 1
        try:
            conn.close()
        except OSError:
            pass

    def close(self) -> None:
        """Give the clients `CLOSE_FLUSH_S` in all to take their backlogs (what is left is counted in
        `bytes_unsent_at_close`), then close everything."""
        self._stop.set()
        with self._lock:
            self._flush(time.monotonic() + CLOSE_FLUSH_S)
            for conn in self._clients:
                conn.close()
            self._clients.clear()
        self._listener.close()
        if self._thread.ident is not None:
            self._thread.join(timeout=1.0)

    def _flush(self, deadline: float) -> None:
        pending = {conn: backlog for conn, backlog in self._clients.items() if backlog}
        with selectors.DefaultSelector() as sel:      # not select.select: descriptors may be above 1024
            for conn in pending:
                sel.register(conn, selectors.EVENT_WRITE)
            while pending and (left := deadline - time.monotonic()) > 0:
                for key, _ in sel.select(left):
                    conn, backlog = key.fileobj, pending[key.fileobj]
                    try:
                        self._send_some(conn, backlog)
                    except BlockingIOError:
                        continue
                    except OSError:
                        backlog.clear()
                    if not backlog:
                        sel.unregister(conn)
                        del pending[conn]
        self.counts["bytes_unsent_at_close"] += sum(len(b) for b in pending.values())


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
        try:
            _make_link(self.link, self.device)
        except BaseException:
            self._close_fds()
            raise
        self.counts = {"bytes_written": 0, "bytes_dropped": 0}

    def send(self, data: bytes) -> None:
        try:
            _, writable, _ = select.select([], [self._master], [], 0)
            n = os.write(self._master, data) if writable else 0
        except (BlockingIOError, OSError):
            n = 0
        self.counts["bytes_written"] += n
        self.counts["bytes_dropped"] += len(data) - n

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def close(self) -> None:
        self._close_fds()
        # Only our own link: someone may have put something else at the path meanwhile.
        if _link_target(self.link) == self.device:
            self.link.unlink()


# pty devices: Linux (/dev/pts/N) and BSD/macOS (/dev/ttysNNN, /dev/ttypN)
_PTY_DEVICE = re.compile(r"/dev/(pts/\d+|ttys\d+|ttyp[0-9a-f])")


def _link_target(path: Path) -> str | None:
    """Where the symbolic link `path` points, or None when `path` is not a symbolic link."""
    try:
        return os.readlink(path)
    except OSError:
        return None


def _make_link(link: Path, device: str) -> None:
    """Link `device` at `link`. Only a link to a pty device (one a killed run left; its pty may be
    gone) is replaced: anything else there is somebody's file and is refused, untouched."""
    target = _link_target(link)
    if target is not None:
        if not _PTY_DEVICE.fullmatch(target):
            raise UserInputError(f"--nmea-pty {link}: is a symbolic link to {target}, not to a pty device; "
                                 "expected a free path or a link an earlier `leonav nav` left (remove it or "
                                 "give another path)")
        link.unlink(missing_ok=True)
    elif os.path.lexists(link):
        raise UserInputError(f"--nmea-pty {link}: is {_what_is(link)}; expected a free path or a link an "
                             "earlier `leonav nav` left (nothing there is removed: give another path)")
    try:
        link.symlink_to(device)
    except FileExistsError:     # created by someone else since the check above: theirs, left alone
        raise UserInputError(f"--nmea-pty {link}: something appeared there while linking; expected a free "
                             "path") from None
    except OSError as exc:
        raise UserInputError(f"--nmea-pty {link}: cannot create the link ({exc.strerror}); expected a "
                             "writable folder") from None


def _what_is(path: Path) -> str:
    """'a regular file', 'a directory', ... for a message."""
    mode = os.lstat(path).st_mode
    for test, name in ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a directory"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISFIFO, "a named pipe"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "an existing file"
