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
