"""`leonav nav` when things go wrong: a GNSS device unplugged mid-run (with garbage bursts on both
serial lines before), the IMU unplugged, SIGINT and SIGTERM. Devices are pty pairs fed with a
synthetic session's bytes at their recorded pace; every output must stay complete and readable
and the exit codes be the documented ones (leonav_runtime/nav/run.py)."""
from __future__ import annotations

import csv
import datetime as dt
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.test_nav_live import nav_options

SECONDS = 8.0
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    base = tmp_path_factory.mktemp("navfaults")
    write_synthetic_session(base / "s", SynthSessionConfig(seconds=SECONDS, seed=7, sdr=False))
    return base


def _run_with_ptys(session: Path, out: Path, close: dict, garbage: bool = False) -> dict:
    from leonav_runtime.nav import sources
    from leonav_runtime.nav.run import run_nav

    folder = session / "s"
    t0 = sources.session_start_mono(folder)
    events = {n: sources.chunk_events(folder, n, t0) for n in ("gnss", "imu")}
    if garbage:
        rng = np.random.default_rng(11)
        for n in events:
            events[n] += [(1.5 + 0.7 * k + 0.01 * rng.random(), rng.integers(0, 256, 300, np.uint8).tobytes())
                          for k in range(4)]
    ptys = {n: sources.PacedPty(events[n], close_at_s=close.get(n)) for n in events}
    opts = nav_options(out, gnss=ptys["gnss"].path, imu=ptys["imu"].path, seconds=SECONDS + 0.5)
    try:
        return run_nav(opts, on_started=lambda: [p.start() for p in ptys.values()])
    finally:
        for p in ptys.values():
            p.close()


def _solutions(out: Path) -> list[dict]:
    """solutions.jsonl, with `t` = the solution's UTC as POSIX seconds."""
    sols = [json.loads(line) for line in (out / "solutions.jsonl").read_text().splitlines()]
    return [s | {"t": dt.datetime.fromisoformat(s["utc"]).timestamp()} for s in sols]


def _trajectory(out: Path) -> list[dict]:
    with open(out / "trajectory.csv", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_gnss_unplugged_after_garbage_goes_on_with_the_imu(session):
    from leonav.hardware.session import decode_session

    out = session / "gnss_lost"
    res = _run_with_ptys(session, out, {"gnss": 4.5}, garbage=True)
    assert res["exit_code"] == 3 and list(res["devices_lost"]) == ["gnss"]
    assert any(e["kind"] == "device_lost" and "GNSS lost" in e["text"] for e in res["events"])
    assert res["rejected"]["gnss"].get("junk_bytes", 0) > 0 and res["rejected"]["imu"].get("junk_bytes", 0) > 0
    sols = _solutions(out)
    t_lost = min(s["t"] for s in sols if s["fix_quality"] == 6)
    after = [s for s in sols if s["t"] >= t_lost]
    assert len(after) >= 20                                          # predicting on, with the IMU alone
    sig = [np.hypot(*s["sigma_enu_m"][:2]) for s in after]
    assert sig[-1] > 1.5 * sig[0]                                    # and the sigma grows
    rows = _trajectory(out)
    assert float(rows[-1]["t_s"]) > SECONDS - 1.0 and all(r["lat_deg"] for r in rows)
    rec = decode_session(out / "session")
    assert rec.gnss_summary["rejected"].get("junk_bytes", 0) > 0 and len(rec.imu_samples) > 70


@pytest.mark.slow
def test_imu_unplugged_stops_predicting_and_says_so(session):
    out = session / "imu_lost"
    res = _run_with_ptys(session, out, {"imu": 4.0})
    assert res["exit_code"] == 3 and list(res["devices_lost"]) == ["imu"]
    assert any("IMU lost" in e["text"] for e in res["events"])
    sols = _solutions(out)
    assert sols and max(s["t"] for s in sols) < min(s["t"] for s in sols) + 4.5   # nothing after the loss
    with open(out / "session" / "gnss_fix.csv", newline="") as fh:
        fixes = list(csv.DictReader(fh))
    assert len(fixes) >= 10 * (SECONDS - 1)                          # the GNSS kept being recorded
    assert json.loads((out / "nav.json").read_text())["exit_code"] == 3


def _interrupt(session: Path, out: Path, sig: int) -> tuple[int, str]:
    cmd = [sys.executable, "-c", "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))",
           "nav", "--from", str(session / "s"), "--realtime", "--mode", "fix+imu", "--nmea-port", "0", "--quiet",
           "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 20
        traj = out / "trajectory.csv"
        while time.monotonic() < deadline and (not traj.exists() or len(traj.read_text().splitlines()) < 12):
            time.sleep(0.1)
        proc.send_signal(sig)
        text, _ = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, text


@pytest.mark.parametrize("sig, code, state", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_signal_flushes_every_output_and_exits_with_its_code(session, sig, code, state):
    from leonav.hardware.session import decode_session

    out = session / f"signal_{code}"
    rc, text = _interrupt(session, out, sig)
    assert rc == code, text
    nav = json.loads((out / "nav.json").read_text())
    assert nav["exit_code"] == code and nav["status"] == state
    rows = _trajectory(out)
    assert len(rows) == nav["trajectory_rows"] >= 10
    assert len(_solutions(out)) == nav["outputs"]["solutions"] > 0
    info = json.loads((out / "session" / "session.json").read_text())
    assert info["status"] == state and decode_session(out / "session").imu_samples
