"""The NMEA TCP server under load: a client limit, and it keeps serving when descriptors run out."""
from __future__ import annotations

import socket
import subprocess
import sys
import textwrap
import time

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
            try:
                got.append(c.recv(16))
            except OSError:
                got.append(b"")
        assert got.count(b"$GPGGA\r\n") == 3 and got.count(b"") == 2     # the refused ones see the close
        for c in clients:
            c.close()
    finally:
        srv.close()


def test_the_server_survives_running_out_of_descriptors():
    """With a descriptor limit of 64 and 200 clients, the accept thread keeps running: it serves
    again once clients leave (before, its thread ended on the first EMFILE, for good)."""
    code = textwrap.dedent("""
        import ctypes, resource, socket, time
        from leonav_runtime.nav.sinks.servers import TcpBroadcastServer
        ctypes.CDLL("libgcc_s.so.1")     # loaded now: a thread's exit needs it, and no descriptor will be left
        resource.setrlimit(resource.RLIMIT_NOFILE, (64, 64))
        srv = TcpBroadcastServer("127.0.0.1", 0, max_clients=1000)
        socks = []
        for _ in range(200):
            try:
                socks.append(socket.create_connection(srv.address, timeout=0.5))
            except OSError:
                break
        time.sleep(0.5)
        errors = srv.counts["accept_errors"]
        for s in socks:
            s.close()
        for _ in range(40):     # sends find the closed peers and drop them (the backlog drains meanwhile)
            srv.send(b"x")
            time.sleep(0.05)
        c = socket.create_connection(srv.address, timeout=2)
        t = time.monotonic()
        while srv.n_clients < 1 and time.monotonic() - t < 3:
            time.sleep(0.01)
        srv.send(b"$GPRMC\\r\\n")
        print(errors > 0, srv._thread.is_alive(), c.recv(16) == b"$GPRMC\\r\\n")
        srv.close()
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["True", "True", "True"], proc.stdout
