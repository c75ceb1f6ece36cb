"""The NMEA TCP server under load: a client limit, and it keeps serving when descriptors run out."""
from __future__ import annotations

import socket
import subprocess
import sys
import textwrap
import time

import pynmea2

from leonav_runtime.nav.sinks.servers import TcpBroadcastServer


def _wait(cond, timeout_s: float = 5.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def test_clients_beyond_the_limit_are_closed_and_counted():
    srv = TcpBroadcastServer("127.0.0.1", 0, max_clients=3)
    try:
        clients = [socket.create_connection(srv.address, timeout=2) for _ in range(5)]
        assert _wait(lambda: srv.counts["clients_accepted"] + srv.counts["clients_refused_limit"] == 5)
        assert srv.n_clients == 3 and srv.counts["clients_refused_limit"] == 2
        srv.send(b"$GPGGA\r\n")
        got = []
        for c in clients:
            data = b""
            try:
                while chunk := c.recv(256):       # the refused ones: one TXT sentence, then the close
                    data += chunk
                    if data == b"$GPGGA\r\n":
                        break
            except OSError:
                pass
            got.append(data)
        refused = [pynmea2.parse(g.decode().strip(), check=True) for g in got if g != b"$GPGGA\r\n"]
        assert got.count(b"$GPGGA\r\n") == 3 and len(refused) == 2, got
        assert all(r.sentence_type == "TXT" and "client limit 3 reached" in r.text for r in refused), refused
        for c in clients:
            c.close()
    finally:
        srv.close()


SERVER = textwrap.dedent("""
    import ctypes, json, resource, sys, threading, time
    from leonav_runtime.nav.sinks.servers import TcpBroadcastServer
    ctypes.CDLL("libgcc_s.so.1")     # loaded now: a thread's exit needs it, and no descriptor may be left
    resource.setrlimit(resource.RLIMIT_NOFILE, (32, 32))
    srv = TcpBroadcastServer("127.0.0.1", 0, max_clients=1000)
    print(srv.address[1], flush=True)
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    while not done.is_set():
        srv.send(b"$GPRMC\\r\\n")
        time.sleep(0.02)
    print(json.dumps(srv.counts | {"accept_thread_alive": srv._thread.is_alive()}), flush=True)
    srv.close()
""")


def test_the_server_survives_running_out_of_descriptors():
    """A server process limited to 32 descriptors, 80 clients from this process: its accepts fail
    with EMFILE, and once the clients leave it serves a new one (before, its accept thread ended on
    the first EMFILE, for good)."""
    import json

    proc = subprocess.Popen([sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        port = int(proc.stdout.readline())
        clients = []
        for _ in range(80):
            try:
                clients.append(socket.create_connection(("127.0.0.1", port), timeout=2))
            except OSError:
                break
        time.sleep(1.0)
        for c in clients:
            c.close()
        fresh = None
        end = time.monotonic() + 10
        while time.monotonic() < end:      # the server drops the closed clients as its sends fail
            try:
                fresh = socket.create_connection(("127.0.0.1", port), timeout=2)
                fresh.settimeout(2)
                if fresh.recv(16).startswith(b"$GPRMC"):
                    break
            except OSError:
                pass
            if fresh is not None:
                fresh.close()
                fresh = None
            time.sleep(0.2)
        assert fresh is not None, "no client served after the others left"
        fresh.close()
        out, err = proc.communicate("", timeout=30)
    finally:
        proc.kill()
    counts = json.loads(out.strip().splitlines()[-1])
    assert counts["accept_errors"] > 0 and counts["accept_thread_alive"], (counts, err)


def test_clients_that_never_read_delay_neither_the_sender_nor_the_shutdown():
    """32 clients that never read (tiny receive buffers) and 4 MB sent to each: every send returns
    at once (none blocks on a full socket), each client is dropped once its backlog passes
    max_backlog_bytes (counted), and close() ends within CLOSE_FLUSH_S plus a margin although what
    is left cannot be delivered (counted in bytes_unsent_at_close). (Before, close() waited 0.5 s per
    client.)"""
    from leonav_runtime.nav.sinks.servers import CLOSE_FLUSH_S

    srv = TcpBroadcastServer("127.0.0.1", 0, max_backlog_bytes=2 << 20, max_clients=32)
    dead = []
    try:
        for _ in range(32):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.connect(srv.address)
            dead.append(s)
        assert _wait(lambda: srv.n_clients == 32)
        line = b"$GPGGA," + b"0" * 57 + b"\r\n"
        worst = 0.0
        for _ in range(4096 * 16):          # 4 MB per client, more than the backlog allows
            t0 = time.monotonic()
            srv.send(line * 16)
            worst = max(worst, time.monotonic() - t0)
            if srv.n_clients == 0:
                break
        assert srv.counts["clients_dropped_slow"] == 32 and srv.n_clients == 0, srv.counts
        assert worst < 0.5, worst            # a blocking send would wait for the reader forever
        # shutdown with backlogs that cannot be delivered: 8 new dead clients, 6 MB queued for each
        # (more than the loopback's socket buffers take); the old close needed 8 x 0.5 s
        srv.max_backlog_bytes = 64 << 20
        for s in dead:
            s.close()
        dead = []
        for _ in range(8):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.connect(srv.address)
            dead.append(s)
        assert _wait(lambda: srv.n_clients == 8)
        for _ in range(6 * 1024):
            srv.send(line * 16)
        t0 = time.monotonic()
        srv.close()
        took = time.monotonic() - t0
        assert took < CLOSE_FLUSH_S + 1.5, took
        assert srv.counts["bytes_unsent_at_close"] > 0, srv.counts
    finally:
        for s in dead:
            s.close()
        srv.close()
