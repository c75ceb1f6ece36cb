"""`leonav nav` under a client storm: the nav child process (under a descriptor limit, auditing what it
imports and opens once it serves) and the storm of TCP clients (used by tests/test_nav_load.py and
benchmarks/bench_nav_load.py).

The child runs the real CLI. Its audit starts when the NMEA server starts accepting
(`TcpBroadcastServer.start`) and records every module imported and every file opened from then on,
except files inside OUT, the played-back session and /dev (the run's own outputs and devices);
it is written as JSON to the path in $LEONAV_NAV_AUDIT when the CLI returns.
"""
from __future__ import annotations

import json
import os
import resource
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

NAV_CHILD = r"""
import json, os, sys
from leonav_runtime.nav.sinks import servers

allowed = tuple(os.path.realpath(p) + os.sep for p in sys.argv[1:3]) + ("/dev/",)
audit = {"serving": False, "modules": None, "opens": []}
_start = servers.TcpBroadcastServer.start

def start(self):
    audit["modules"] = set(sys.modules)
    audit["serving"] = True
    _start(self)

servers.TcpBroadcastServer.start = start

def hook(event, args):
    if event == "open" and audit["serving"] and isinstance(args[0], (str, bytes, os.PathLike)):
        path = os.path.realpath(os.fsdecode(args[0]))
        if not path.startswith(allowed):
            audit["opens"].append(path)

sys.addaudithook(hook)
from leonav_runtime.cli import main
code = main(sys.argv[3:])
audit["serving"] = False
new = sorted(set(sys.modules) - audit["modules"]) if audit["modules"] is not None else None
with open(os.environ["LEONAV_NAV_AUDIT"], "w") as fh:
    json.dump({"exit_code": code, "new_modules": new, "opens": sorted(set(audit["opens"]))}, fh)
sys.exit(code)
"""

PORT_LINE = "leonav nav: NMEA server on tcp://"


def _limit_descriptors(n: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (n, n))
    return apply


class NavChild:
    """`leonav nav --from SESSION [--realtime] --nmea-port auto --quiet` as a child process under
    `ulimit -n nofile`; `port` once it serves, `wait()` -> (exit code, nav.json, audit, stdout)."""

    def __init__(self, session: Path, out: Path, nofile: int = 256, extra: tuple = (), realtime: bool = True) -> None:
        self.out = Path(out)
        self.audit_path = self.out.parent / f"{self.out.name}.audit.json"
        argv = [sys.executable, "-c", NAV_CHILD, str(self.out), str(session), "nav", "--from", str(session),
                *(["--realtime"] if realtime else []), "--out", str(self.out), "--nmea-port", "auto", "--quiet",
                *extra]
        env = os.environ | {"LEONAV_NAV_AUDIT": str(self.audit_path)}
        self.proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, preexec_fn=_limit_descriptors(nofile))
        self.lines: list[str] = []
        self._port = threading.Event()
        self.port: int | None = None
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        # stderr in its own thread: communicate() would also read (and close) the stdout this
        # class's reader iterates
        self._err: list[str] = []
        self._err_reader = threading.Thread(target=lambda: self._err.extend(self.proc.stderr), daemon=True)
        self._err_reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            if line.startswith(PORT_LINE):
                self.port = int(line.strip().rsplit(":", 1)[1])
                self._port.set()
        self._port.set()

    def wait_serving(self, timeout_s: float = 60.0) -> int:
        if not self._port.wait(timeout_s) or self.port is None:
            self.proc.kill()
            self._err_reader.join(timeout=5)
            raise AssertionError(f"nav never said its port: {self.lines} {''.join(self._err)}")
        return self.port

    def wait(self, timeout_s: float = 60.0) -> tuple[int, dict, dict, str]:
        try:
            self.proc.wait(timeout=timeout_s)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
        self._reader.join(timeout=5)
        self._err_reader.join(timeout=5)
        err = "".join(self._err)
        nav = json.loads((self.out / "nav.json").read_text()) if (self.out / "nav.json").exists() else {}
        audit = json.loads(self.audit_path.read_text()) if self.audit_path.exists() else {}
        return self.proc.returncode, nav, audit, "\n".join(self.lines) + "\n" + err


def dead_clients(port: int, n: int) -> list[socket.socket]:
    """`n` clients that connect and never read (a small receive buffer, so the server's sends back up)."""
    out = []
    for _ in range(n):
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.settimeout(5)
        s.connect(("127.0.0.1", port))
        out.append(s)
    return out


def storm(port: int, total: int = 1000, wave: int = 100, pause_s: float = 0.4) -> dict:
    """Open and close `total` clients, `wave` at a time; the first and last of each wave read a line.
    Returns what the readers saw: {"nmea": n, "refused": n, "nothing": n, "connected": n}."""
    seen = {"nmea": 0, "refused": 0, "nothing": 0, "connected": 0}
    done = 0
    while done < total:
        socks = []
        for _ in range(min(wave, total - done)):
            socks.append(socket.create_connection(("127.0.0.1", port), timeout=10))
        seen["connected"] += len(socks)
        done += len(socks)
        for reader in {socks[0], socks[-1]}:     # the first is likely served, the last of 100 refused
            seen[_first_line_kind(reader)] += 1
        for s in socks:
            s.close()
        time.sleep(pause_s)
    return seen


def _first_line_kind(sock: socket.socket) -> str:
    sock.settimeout(2.0)
    try:
        line = sock.makefile("rb").readline()
    except OSError:
        line = b""
    if line.startswith(b"$GPTXT") and b"client limit" in line:
        return "refused"
    return "nmea" if line.startswith((b"$GP", b"$GN", b"$PL")) else "nothing"
