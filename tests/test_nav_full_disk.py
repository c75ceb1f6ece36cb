"""`leonav nav` on a full disk (GitHub issue 24, failure 7): an output file that cannot be written never
stops the navigator. Navigation and the NMEA/MAVLink outputs go on to the end, the records that could
not be written are counted per file (`lost_writes`, with the first error of each in `lost_write_errors`),
nav.json and session.json are written at the end when they fit (one stderr line says so when not), and
the exit code is the one of a run that navigated (0), with the loss in nav.json and on stderr.

The disk is made full without root by handing out, for files under OUT, file objects whose writes fail
with ENOSPC once a shared byte budget is spent; where mounting is allowed, a real 96 KiB tmpfs too.
"""
from __future__ import annotations

import builtins
import csv
import errno
import io
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.test_nav_live import free_port, nav_options

SECONDS = 6.0
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> Path:
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    folder = tmp_path_factory.mktemp("navfull") / "s"
    write_synthetic_session(folder, SynthSessionConfig(seconds=SECONDS, seed=9, sdr=False))
    return folder


class _FullDisk:
    """Files opened for writing under `root` share `budget` bytes; then every write fails with ENOSPC
    (an unbuffered binary file first takes what is left, as write(2) does). Names in `spare` (nav.json,
    session.json and their temporary files) are not counted: small files that still fit."""

    def __init__(self, root: Path, budget: int, spare: tuple[str, ...] = ()) -> None:
        self.root, self.left, self.spare = str(root), budget, spare
        self.first_failure_mono: float | None = None
        self.failures = 0
        self._lock = threading.Lock()

    def take(self, n: int, partial: bool) -> int:
        with self._lock:
            if n <= self.left or (partial and self.left > 0):
                k = min(n, self.left)
                self.left -= k
                return k
            self.failures += 1
            if self.first_failure_mono is None:
                self.first_failure_mono = time.monotonic()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def install(self, monkeypatch) -> None:
        real = builtins.open

        def opener(file, mode="r", *args, **kw):
            fh = real(file, mode, *args, **kw)
            path = os.path.abspath(os.fspath(file)) if isinstance(file, (str, bytes, os.PathLike)) else ""
            if (path.startswith(self.root) and any(c in mode for c in "wax+")
                    and not any(s in os.path.basename(path) for s in self.spare)):
                return _FillingFile(fh, self)
            return fh

        monkeypatch.setattr(builtins, "open", opener)
        monkeypatch.setattr(io, "open", opener)


class _FillingFile:
    """A file object whose writes take from a `_FullDisk` budget."""

    def __init__(self, fh, disk: _FullDisk) -> None:
        self._fh, self._disk = fh, disk

    def write(self, data):
        raw = isinstance(self._fh, io.FileIO)
        n = self._disk.take(len(data), partial=raw)
        if n < len(data):
            return self._fh.write(bytes(data[:n]))
        return self._fh.write(data)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._fh.close()

    def __getattr__(self, name):
        return getattr(self._fh, name)


def _client(port: int, got: list, stop: threading.Event) -> None:
    """Read NMEA from the server until `stop`: (arrival monotonic s, bytes) pieces into `got`."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
    sock.settimeout(0.1)
    try:
        while not stop.is_set():
            try:
                data = sock.recv(65536)
            except (TimeoutError, socket.timeout):
                continue
            if not data:
                break
            got.append((time.monotonic(), data))
    finally:
        sock.close()


def _check_whole_csv(path: Path) -> list[dict]:
    """Every row of a CSV has every column (a failed write never leaves half a row)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows and all(len(r) == len(rows[0]) for r in rows), path
    return [dict(zip(rows[0], r)) for r in rows[1:]]


def _served_while_full(disk: _FullDisk, got: list, solutions: int) -> None:
    """Every solution reached the NMEA client, and sentences kept coming after the disk was full."""
    text = b"".join(d for _, d in got)
    assert text.count(b"GGA,") == solutions > 0
    assert disk.first_failure_mono is not None
    after = b"".join(d for t, d in got if t > disk.first_failure_mono)
    assert after.count(b"GGA,") >= 1


def test_fast_playback_on_a_filling_disk_goes_on_and_counts_what_was_lost(session, tmp_path, monkeypatch):
    from leonav_runtime.nav.run import run_nav

    out = tmp_path / "out"
    disk = _FullDisk(out, budget=30_000, spare=("nav.json", "session.json"))
    disk.install(monkeypatch)
    port, got, stop = free_port(), [], threading.Event()
    reader = []

    def connect() -> None:     # the server listens before the playback starts: connect then
        reader.append(threading.Thread(target=_client, args=(port, got, stop), daemon=True))
        reader[0].start()
        time.sleep(0.3)

    opts = nav_options(out, session=session)
    opts.tcp = ("127.0.0.1", port)
    try:
        res = run_nav(opts, on_started=connect)
    finally:
        time.sleep(0.3)
        stop.set()
        if reader:
            reader[0].join(timeout=3)
    assert res["exit_code"] == 0 and res["started"] and res["end_reason"] == "playback ended"
    lost = res["lost_writes"]
    assert lost.get("trajectory.csv", 0) > 0 and lost.get("solutions.jsonl", 0) > 0
    assert any(k.startswith("session/") for k in lost)
    assert "No space left" in res["lost_write_errors"]["trajectory.csv"]
    assert res["files_complete"] is False
    _served_while_full(disk, got, res["outputs"]["solutions"])
    nav = json.loads((out / "nav.json").read_text())
    assert nav["lost_writes"] == lost and nav["exit_code"] == 0
    assert json.loads((out / "session" / "session.json").read_text())["status"] == "complete"
    rows = _check_whole_csv(out / "trajectory.csv")
    assert len(rows) == res["trajectory_rows"]


def test_live_devices_on_a_filling_disk_are_not_lost(session, tmp_path, monkeypatch):
    """Before: the recorder's device threads died on the first failed raw-log write (exit 3, "device lost")."""
    from leonav_runtime.nav import sources
    from leonav_runtime.nav.run import run_nav

    out = tmp_path / "out"
    disk = _FullDisk(out, budget=25_000, spare=("nav.json", "session.json"))
    disk.install(monkeypatch)
    t0 = sources.session_start_mono(session)
    ptys = {n: sources.PacedPty(sources.chunk_events(session, n, t0)) for n in ("gnss", "imu")}
    port, got, stop = free_port(), [], threading.Event()
    reader = []

    def started() -> None:
        reader.append(threading.Thread(target=_client, args=(port, got, stop), daemon=True))
        reader[0].start()
        time.sleep(0.2)
        for p in ptys.values():
            p.start()

    opts = nav_options(out, gnss=ptys["gnss"].path, imu=ptys["imu"].path, seconds=SECONDS + 0.5)
    opts.tcp = ("127.0.0.1", port)
    try:
        res = run_nav(opts, on_started=started)
    finally:
        for p in ptys.values():
            p.close()
        stop.set()
        if reader:
            reader[0].join(timeout=3)
    assert res["exit_code"] == 0, res.get("devices_lost")
    assert res["devices_lost"] == {} and res["started"]
    lost = res["lost_writes"]
    assert any(k.startswith("session/") and k.endswith(".raw") for k in lost), lost
    _served_while_full(disk, got, res["outputs"]["solutions"])
    info = json.loads((out / "session" / "session.json").read_text())
    assert info["status"] == "complete" and all(d["error"] == "" for d in info["devices"])
    assert info["lost_writes"] == {k[len("session/"):]: v for k, v in lost.items() if k.startswith("session/")}
    _check_whole_csv(out / "session" / "imu.csv")


def test_nothing_fits_at_all_one_stderr_line_and_no_traceback(session, tmp_path, monkeypatch, capsys):
    """The disk is full from the start: not even nav.json fits; the run still ends as it should."""
    from leonav_runtime.cli import main

    out = tmp_path / "out"
    _FullDisk(out, budget=0).install(monkeypatch)
    rc = main(["nav", "--from", str(session), "--out", str(out), "--nmea-port", "0", "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert "Traceback" not in cap.err and "error" not in cap.err.lower().replace("errno", "")
    lines = [line for line in cap.err.splitlines() if "nav.json" in line]
    assert len(lines) == 1 and "not written" in lines[0] and "trajectory.csv" in lines[0], cap.err
    assert "not written" in cap.out and "trajectory.csv" in cap.out


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A real 96 KiB tmpfs (skips where mounting is not permitted, e.g. without root)."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    try:
        proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=96k", "tmpfs", str(mnt)],
                              capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"cannot run mount: {exc}")
    if proc.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted here: {proc.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True, timeout=10)


def test_real_full_tmpfs(session, tiny_tmpfs):
    """A 96 KiB filesystem fills during the run (the outputs take ~130 KB): it ends like the others."""
    out = tiny_tmpfs / "out"
    code = "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.run([sys.executable, "-c", code, "nav", "--from", str(session), "--out", str(out),
                           "--nmea-port", str(free_port()), "--quiet"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    nav = json.loads((out / "nav.json").read_text())     # room kept for it from the start
    assert nav["files_complete"] is False and sum(nav["lost_writes"].values()) > 0
    assert json.loads((out / "session" / "session.json").read_text())["lost_writes"]
    rows = _check_whole_csv(out / "trajectory.csv")
    assert len(rows) == nav["trajectory_rows"]
    _check_whole_csv(out / "session" / "imu.csv")
    assert not list(out.glob(".leonav-nav.*"))
