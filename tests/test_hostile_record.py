"""`leonav record` under hostile input and faults: no dead device thread, no false status,
no half-written session.json, every stop signal ends like Ctrl-C, bad options in one line.

Devices are real recorded bytes: a file source (read to its end, then the device "ends")
or a pty fed by a thread; signals are real signals sent to a `leonav record` process.
Every case is bounded in time (`bounded`, subprocess timeouts).
"""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from leonav.hardware import session_files
from leonav.hardware.fakes import PtyDevice
from leonav.hardware.gnss import nmea
from leonav.hardware.session import RecordSession, decode_session
from leonav_runtime.cli import EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_IO, main
from tests.conftest import shared_file
from tests.timebox import bounded, communicate_or_stacks

REPO = Path(__file__).resolve().parents[1]
CLI = "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))"



def _one_line(capsys) -> str:
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("leonav record: "), err
    return err[0]


def sentence(body: str) -> bytes:
    return f"${body}*{nmea.nmea_checksum(body.encode()):02X}\r\n".encode()


def rtk_lines() -> list[bytes]:
    data = shared_file("nmea/gpsd/nmea-rtk.log").read_bytes()
    return [ln + b"\n" for ln in data.split(b"\n") if ln.startswith(b"$")]


def rtk_with(extra: bytes, after_bytes: int = 4400) -> bytes:
    """The Trimble 10 Hz log (21.6 kB) with `extra` inserted at the first epoch past `after_bytes`."""
    lines = rtk_lines()
    out, n, done = [], 0, False
    for k, line in enumerate(lines):
        if not done and n >= after_bytes and k % 2 == 0:
            out.append(extra)
            done = True
        out.append(line)
        n += len(line)
    return b"".join(out)


BAD_RMC = sentence("GNRMC,132830.00,A,4134.49795459,N,09345.03431408,W,0.148,124.888,321399,11.5985,E,D")


def _record_file(tmp_path: Path, data: bytes, seconds: float = 20.0) -> tuple[dict, Path]:
    src = tmp_path / "gnss.log"
    src.write_bytes(data)
    out = tmp_path / "session"
    with bounded(30):
        info = RecordSession(out, gnss=str(src), progress=False).run(seconds)
    return info, out


def test_a_bad_sentence_never_ends_the_gnss_recording(tmp_path):
    # before: the RMC's date "321399" raised in NmeaFixBuilder.fix() at the next GGA, the GNSS
    # thread died after ~4.4 kB, the rest of the log was never read, and replay crashed
    data = rtk_with(BAD_RMC)
    info, out = _record_file(tmp_path, data)
    dev = info["devices"][0]
    assert (out / "gnss.raw").read_bytes() == data and dev["bytes_read"] == len(data)
    assert dev["error"] == "" and dev["rejected"] == {"nmea_bad_date": 1}
    assert dev["accepted"]["fixes"] == 122 and dev["csv_rows"]["gnss_fix.csv"] == 122
    assert info["status"] == "devices ended"
    dec = decode_session(out)
    assert dec.gnss_summary["accepted"] == dev["accepted"] and dec.gnss_summary["rejected"] == dev["rejected"]


def test_time_tags_that_disagree_do_not_end_the_recording(tmp_path):
    # before: two RMC tags 3 s apart left the time-map fit with no tag (ValueError in the
    # GNSS thread at the second tag, and again in decode_session)
    lines = rtk_lines()
    late = lines[1].replace(b"132819.60", b"132822.60")
    late = sentence(late[1:late.index(b"*")].decode())
    data = lines[0] + lines[1] + late + b"".join(ln for ln in lines[2:40] if b"GGA" in ln)
    info, out = _record_file(tmp_path, data)
    dev = info["devices"][0]
    assert dev["error"] == "" and (out / "gnss.raw").read_bytes() == data
    assert dev["accepted"]["fixes"] == 20 and info["status"] == "devices ended"
    assert decode_session(out).gnss_summary["accepted"] == dev["accepted"]


def test_a_failed_device_thread_makes_the_session_failed(tmp_path, capsys, monkeypatch):
    # before: status "devices ended"/"complete" and exit 0 although the GNSS log stopped on a full disk
    data = rtk_with(b"")
    src = tmp_path / "gnss.log"
    src.write_bytes(data)
    init = session_files.RawLog.__init__

    class FullDisk:
        """The raw log's file on a disk that is full after 4,400 bytes."""

        def __init__(self, fh):
            self.fh, self.n = fh, 0

        def write(self, data):
            if self.n + len(data) > 4400:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            self.n += len(data)
            return self.fh.write(data)

        def __getattr__(self, name):
            return getattr(self.fh, name)

    def on_a_full_disk(self, folder, name):
        init(self, folder, name)
        self._fh = FullDisk(self._fh)

    monkeypatch.setattr(session_files.RawLog, "__init__", on_a_full_disk)
    out = tmp_path / "session"
    with bounded(30):
        rc = main(["record", "--gnss", str(src), "--seconds", "20", str(out)])
    assert rc == EXIT_IO
    line = _one_line(capsys)
    assert "gnss.raw: no space left on the device" in line, line
    info = json.loads((out / "session.json").read_text())
    assert info["status"] == "failed" and "No space left" in info["devices"][0]["error"]


@pytest.mark.parametrize("signals", [("SIGTERM",), ("SIGHUP",), ("SIGINT",) * 3],
                         ids=["sigterm", "sighup", "repeated-ctrl-c"])
def test_stop_signals_end_the_recording_like_ctrl_c(tmp_path, signals):
    # before: SIGTERM/SIGHUP killed the process (session.json left at "recording", no counts);
    # a second Ctrl-C during the shutdown gave exit -2, an internal error or an empty session.json
    lines = rtk_lines()
    gnss = PtyDevice([lines[i] + lines[i + 1] for i in range(0, len(lines) - 1, 2)], delay_s=0.1)
    out = tmp_path / "session"
    # PYTHONFAULTHANDLER: a recorder that does not stop is sent SIGABRT and shows where its threads are
    proc = subprocess.Popen([sys.executable, "-c", CLI, "record", "--gnss", gnss.path, "--seconds", "60", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO,
                            env=dict(os.environ, PYTHONPATH=str(REPO), PYTHONFAULTHANDLER="1"))
    try:
        deadline = time.monotonic() + 30
        while not (out / "session.json").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.3)
        gnss.start()
        time.sleep(1.0)
        for name in signals:
            proc.send_signal(getattr(signal, name))
            time.sleep(0.02)
        stdout, stderr = communicate_or_stacks(proc, 30, f"leonav record did not stop after {signals}")
    finally:
        if proc.poll() is None:
            proc.kill()
        gnss.close()
    assert proc.returncode == EXIT_INTERRUPTED, (proc.returncode, stderr.decode())
    assert "Traceback" not in stderr.decode() and "interrupted" in stdout.decode()
    info = json.loads((out / "session.json").read_text())
    assert info["status"] == "interrupted" and info["stop_signal"] == signals[0]
    dev = info["devices"][0]
    assert dev["accepted"]["fixes"] >= 3 and dev["bytes_read"] == (out / "gnss.raw").stat().st_size
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("args,option", [
    (["--seconds", "nan"], "--seconds"),
    (["--seconds", "inf"], "--seconds"),
    (["--seconds", "1e300"], "--seconds"),
    (["--seconds", "1", "--gnss-baud", "1000000000000"], "--gnss-baud"),
    (["--seconds", "1", "--gnss-baud", "0"], "--gnss-baud"),
    (["--seconds", "1", "--imu", "{gnss}", "--imu-baud", "-5"], "--imu-baud"),
    (["--seconds", "1", "--sdr-rate", "nan"], "--sdr-rate"),
    (["--seconds", "1", "--rf-hz", "inf"], "--rf-hz"),
    (["--seconds", "1", "--sdr-gain", "nan"], "--sdr-gain"),
], ids=["seconds-nan", "seconds-inf", "seconds-huge", "baud-huge", "baud-0", "baud-negative", "sdr-rate-nan",
        "rf-inf", "gain-nan"])
def test_bad_options_are_one_line_before_any_device_is_opened(tmp_path, capsys, args, option):
    src = tmp_path / "gnss.log"
    src.write_bytes(rtk_lines()[0])
    args = [a.replace("{gnss}", str(src)) for a in args]
    with bounded(10):
        rc = main(["record", "--gnss", str(src), *args, str(tmp_path / "s")])
    assert rc == EXIT_BAD_INPUT
    assert option in _one_line(capsys)
    assert not (tmp_path / "s").exists()


def test_out_folder_problems_are_one_line(tmp_path, capsys):
    src = tmp_path / "gnss.log"
    src.write_bytes(b"".join(rtk_lines()[:20]))
    a_file = tmp_path / "taken"
    a_file.write_text("x")
    for out, status, words in ((a_file, EXIT_IO, "already exists"),
                               (a_file / "sub", EXIT_IO, "a part of the path is a file")):
        with bounded(10):
            assert main(["record", "--gnss", str(src), "--seconds", "5", str(out)]) == status
        assert words in _one_line(capsys)
    assert a_file.read_text() == "x"
    if Path("/sys/kernel").is_dir():   # sysfs: no new folder at its top, not even for root
        with bounded(10):
            assert main(["record", "--gnss", str(src), "--seconds", "5", "/sys/leonav-hostile-out"]) == EXIT_IO
        assert "/sys/leonav-hostile-out" in _one_line(capsys)
    # a folder that already holds a recording is never overwritten
    out = tmp_path / "s"
    with bounded(20):
        assert main(["record", "--gnss", str(src), "--seconds", "5", str(out)]) == 0
    capsys.readouterr()
    before = (out / "gnss.raw").read_bytes()
    with bounded(10):
        assert main(["record", "--gnss", str(src), "--seconds", "5", str(out)]) == EXIT_BAD_INPUT
    assert "already holds a recording" in _one_line(capsys)
    assert (out / "gnss.raw").read_bytes() == before


def test_sdr_recording_longer_than_the_free_disk_is_refused_up_front(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "rtlsdr", None)   # it must not get as far as opening the SDR
    with bounded(10):
        rc = main(["record", "--sdr", "0", "--seconds", "2000000", str(tmp_path / "s")])
    assert rc == EXIT_BAD_INPUT
    line = _one_line(capsys)
    assert "free" in line and "--seconds" in line and "GB" in line


def test_the_stop_signal_handler_takes_no_lock():
    """The handler runs between any two bytecodes of the main thread, also inside the main thread's
    own `stop_event.set()` during the shutdown: it must not take the event's lock (a repeated
    Ctrl-C then deadlocked `leonav record`). Here the lock is held by the thread that runs it."""
    import threading
    from types import SimpleNamespace

    fake = SimpleNamespace(stop_signal=None, stop_event=threading.Event())
    returned = threading.Event()

    def inside_set():
        with fake.stop_event._cond:        # where Event.set() is when the signal lands
            RecordSession._on_stop_signal(fake, signal.SIGINT, None)
            returned.set()

    threading.Thread(target=inside_set, daemon=True).start()
    assert returned.wait(timeout=5), "the handler blocked on the stop event's lock"
    assert fake.stop_signal == "SIGINT"
