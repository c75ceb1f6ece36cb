"""`leonav base` + `leonav nav` over loopback with a simulated pair sharing one ephemeris error:
corrections applied, their age reported, the error against truth smaller with them, and a clean
fallback when the base process is killed."""
from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from tests.timebox import communicate_or_stacks

CLI = [sys.executable, "-c", "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))"]
SECONDS = 12.0


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    from leonav_runtime.base.simulated import write_pair

    warnings.simplefilter("ignore")
    folder = tmp_path_factory.mktemp("basepair")
    doc = write_pair(folder / "p", seconds=SECONDS)
    return folder, doc


def _start_base(folder, *extra):
    # PYTHONFAULTHANDLER: a base that does not stop is sent SIGABRT and shows where its threads are
    base = subprocess.Popen(CLI + ["base", "--simulate", str(folder / "p"), "--listen", "127.0.0.1:0", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    line = base.stdout.readline()
    m = re.search(r"tcp://(127\.0\.0\.1:\d+)", line)
    assert m, (line, base.stderr.read() if base.poll() is not None else "")
    return base, m.group(1)


def _stop_base(base, timeout: float = 30.0, sig=signal.SIGINT) -> int:
    """A signal (SIGINT) to the base, then its exit code; its pipes are drained meanwhile (an
    undrained pipe could hold a process that writes), and a base that does not stop fails with its stderr."""
    base.send_signal(sig)
    communicate_or_stacks(base, timeout, f"leonav base did not stop after signal {sig}")
    return base.returncode


def _nav(folder, out, *extra, timeout=120):
    r = subprocess.run(CLI + ["nav", "--from", str(folder / "p" / "rover"), "--out", str(out), "--mode",
                              "leo-alpha+imu", "--nmea-port", "0", *extra],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=timeout)
    return r, json.loads((out / "nav.json").read_text())


def _errors_against_truth(rows, doc):
    """Per Doppler-rate measurement: (uncorrected, corrected) error (Hz/s) against the value the true
    orbit gives at the rover's true (static) position; corrected only where a correction was applied."""
    from leonav_runtime.base import compute
    from leonav_runtime.base.simulated import true_elements
    from leonav_runtime.core import navfuncs
    from leonav_runtime.inputs import DopplerRateTable
    from leonav_runtime.orbits import propagate_ecef
    from leonav_runtime.simulation.session_synth import builtin_starlink
    from leonav_runtime.gen.constants import STARLINK_BEACON_HZ     # the synthetic capture's carrier
    from leonav_runtime.replay.timebase import utc_of

    nav = navfuncs.NavFunctions()
    t = np.array([float(r["t_utc_s"]) for r in rows])
    sat_id = np.array([int(r["norad_id"]) for r in rows])
    z = np.array([float(r["z"]) for r in rows])
    c = np.array([float(r["correction"]) if r["status"] == "applied" else 0.0 for r in rows])
    epoch = utc_of(float(t.min()))
    nominal = builtin_starlink(epoch)
    index = {int(i): k for k, i in enumerate(nominal.norad_ids.tolist())}
    d = np.zeros(len(nominal))
    for sid, err in doc["along_track_error_m"].items():
        d[index[int(sid)]] = err
    lat, lon, h = doc["rover_site_deg_m"]
    origin = (math.radians(lat), math.radians(lon), h)
    err_raw, err_cor = [], []
    for sid in np.unique(sat_id):
        sel = sat_id == sid
        k = [index[int(sid)]]
        st = {}
        for name, el in (("true", true_elements(nominal.select(k), d[k])), ("nominal", nominal.select(k))):
            s = propagate_ecef(el, epoch, t[sel] - epoch.timestamp())
            st[name] = np.hstack([s.r_ecef_m[0], s.v_ecef_mps[0], s.a_ecef_mps2[0]])
        pred = compute.predicted(DopplerRateTable(t[sel], sat_id[sel], z[sel], 1.0, st["nominal"]), origin,
                                 STARLINK_BEACON_HZ, nav)
        truth = compute.predicted(DopplerRateTable(t[sel], sat_id[sel], z[sel], 1.0, st["true"]), origin,
                                  STARLINK_BEACON_HZ, nav)
        assert np.all(np.abs(truth - pred) > 0) or not np.any(d[k])
        # the filter, at the true position, compares z (or z - c) with the element-set prediction:
        # what is left is its error (noise, plus the orbit error's effect when uncorrected)
        err_raw.append(z[sel] - pred)
        err_cor.append(z[sel] - c[sel] - pred)
    return np.concatenate(err_raw), np.concatenate(err_cor)


def _csv_rows(path):
    import csv

    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_corrections_applied_over_loopback_reduce_the_error_against_truth(pair, tmp_path):
    folder, doc = pair
    base, address = _start_base(folder, "--pace", "fast", "--record", str(tmp_path / "rec.txt"))
    try:
        r, res = _nav(folder, tmp_path / "nav", "--corrections", address)
    finally:
        code = _stop_base(base)
    assert code == 130                               # SIGINT: the documented exit status
    assert r.returncode == 0, r.stderr[-2000:]
    corr = res["corrections"]
    assert corr["counts"]["doppler_rate_applied"] > 0 and corr["link"]["connects"] == 1
    assert corr["age"]["applied"] == corr["counts"]["doppler_rate_applied"]
    assert abs(corr["age"]["median_s"]) <= 1.0                # base and rover epochs 1 s apart at most
    assert "corr age" in r.stderr and "corrections applied" in r.stderr
    rows = _csv_rows(tmp_path / "nav" / "corrections.csv")
    applied = [row for row in rows if row["status"] == "applied"]
    assert len(applied) == corr["counts"]["doppler_rate_applied"]
    raw, cor = _errors_against_truth(applied, doc)
    rms_raw, rms_cor = float(np.sqrt(np.mean(raw ** 2))), float(np.sqrt(np.mean(cor ** 2)))
    print(f"Doppler-rate error against the nominal orbit at the true position: uncorrected RMS {rms_raw:.3f} Hz/s, "
          f"corrected {rms_cor:.3f} Hz/s ({len(applied)} records)")
    assert rms_cor < 0.5 * rms_raw


def test_replay_position_error_smaller_with_recorded_corrections(pair, tmp_path):
    from leonav_runtime.replay import ReplayOptions, replay_session

    folder, _ = pair
    base, address = _start_base(folder, "--pace", "fast", "--record", str(tmp_path / "rec.txt"), "--seconds", "0.5")
    base.wait(timeout=30)
    # one damaged line and one for another constellation in the recording: refused, counted, the rest used
    with open(tmp_path / "rec.txt", "a") as fh:
        fh.write("LNVC 1 COR starlink 1 doppler_rate 1.0 0.1 Hz/s 0.1*00\n")
        from leonav_runtime.base import protocol
        fh.write(protocol.correction_line(protocol.Correction("oneweb", 5, "doppler_rate", 1.77e9, 1.0, 0.2)))
    out = {}
    for name, corr in (("without", None), ("with", str(tmp_path / "rec.txt"))):
        m = replay_session(folder / "p" / "rover", tmp_path / name,
                           ReplayOptions(modes=("leo-alpha+imu",), corrections=corr))
        out[name] = m
    e0 = out["without"]["modes"]["leo-alpha+imu"]["rmse_position_m"]
    e1 = out["with"]["modes"]["leo-alpha+imu"]["rmse_position_m"]
    c = out["with"]["counts"]["corrections"]["counts"]
    print(f"replay leo-alpha+imu position RMSE: {e0:.2f} m without, {e1:.2f} m with corrections; refused {c}")
    assert c["rejected_garbled"] == 1 and c["rejected_other_constellation"] == 1 and c["doppler_rate_applied"] > 0
    assert e1 < e0


@pytest.mark.slow
def test_rover_falls_back_cleanly_when_the_base_is_killed(tmp_path):
    """The base is killed once the rover has applied a correction (its status line says `corr
    age`), not after a fixed sleep: under load the rover's start-up alone can outlast one. Its
    own 30 s pair leaves the rover time to run out of corrections after the kill: it lags the
    base (listening before the rover starts) by its start-up, which was 13 s with the machine
    loaded 4x, so the corrections it holds cover that much more of its session."""
    import threading

    from leonav_runtime.base.simulated import write_pair

    warnings.simplefilter("ignore")
    folder = tmp_path / "pair"
    write_pair(folder / "p", seconds=30.0)
    base, address = _start_base(folder, "--pace", "realtime")
    nav = subprocess.Popen(CLI + ["nav", "--from", str(folder / "p" / "rover"), "--realtime", "--out",
                                  str(tmp_path / "nav"), "--mode", "leo-alpha+imu", "--nmea-port", "0",
                                  "--corrections", address, "--corrections-max-age", "2"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    applied = threading.Event()

    def read_stderr():
        for line in nav.stderr:     # universal newlines: a status line ending in CR is a line too
            lines.append(line)
            if "corr age" in line:
                applied.set()
    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    assert applied.wait(timeout=90), "".join(lines)[-2000:]
    base.kill()                                       # no goodbye: the stream just stops
    base.wait(timeout=10)
    nav.wait(timeout=120)
    reader.join(timeout=10)
    err = "".join(lines)
    assert nav.returncode == 0, err[-2000:]
    res = json.loads((tmp_path / "nav" / "nav.json").read_text())
    corr = res["corrections"]
    n = corr["counts"]
    print(f"fallback run: {n}; link {corr['link']}")
    assert n.get("doppler_rate_applied", 0) > 0
    assert n.get("doppler_rate_stale", 0) + n.get("doppler_rate_none", 0) > 0
    assert corr["state"] == "fallback" and corr["link"]["disconnects"] >= 1
    assert corr["link"]["connect_failures"] >= 1             # it kept trying
    assert "went away" in err and "fallback" in err
    assert res["trajectory_rows"] > 0


def test_sigterm_stops_the_base_with_its_documented_status(pair):
    folder, _ = pair
    base, _ = _start_base(folder, "--pace", "fast")
    assert _stop_base(base, sig=signal.SIGTERM) == 143


def test_a_taken_port_gives_status_3_and_names_the_address(pair):
    import socket

    folder, _ = pair
    with socket.create_server(("127.0.0.1", 0)) as held:
        port = held.getsockname()[1]
        r = subprocess.run(CLI + ["base", "--simulate", str(folder / "p"), "--listen", f"127.0.0.1:{port}"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=120)
    assert r.returncode == 3, r.stderr
    assert f"127.0.0.1:{port}" in r.stderr and "serving" not in r.stdout


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds a running process and its reaped children have used (/proc/PID/stat)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(v) for v in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def _wait_for_cpu_s(proc: subprocess.Popen, timeout: float) -> float:
    """Wait for `proc` to end (within `timeout` s) and return the CPU seconds it and its children used.
    os.wait4 reports that one process only: RUSAGE_CHILDREN of this test process would also count any
    earlier test's child that the subprocess module happens to reap meanwhile."""
    import time

    deadline = time.monotonic() + timeout
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return usage.ru_utime + usage.ru_stime
        if time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            pytest.fail(f"the base did not end within {timeout:g} s of the signal")
        time.sleep(0.02)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads a process's CPU time from /proc")
def test_a_signal_during_the_build_stops_the_base_at_once(pair, tmp_path):
    """SIGINT while the corrections are still being built (after the base's "building" line) ends
    the build (no server yet), exits 130 and says so; the --record file is not created. "At once" in
    CPU time: after the signal the process spends well under the rest of the build's ~2 s of CPU
    (unwinding and the interpreter's exit only); the wall clock is what other tests leave of the
    machine (5 s once, beside the whole suite)."""
    import time

    folder, _ = pair
    record = tmp_path / "rec.txt"
    base = subprocess.Popen(CLI + ["base", "--simulate", str(folder / "p"), "--listen", "127.0.0.1:0",
                                   "--record", str(record)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    started = base.stderr.readline()   # the build's own line: imports are done
    assert "building the corrections" in started, started
    time.sleep(0.3)                    # the build under way (it takes ~2 s of CPU)
    assert base.poll() is None
    at_signal = _cpu_s(base.pid)
    base.send_signal(signal.SIGINT)
    total = _wait_for_cpu_s(base, 60)
    out, err = base.stdout.read(), base.stderr.read()   # a few lines: they fit the pipes' buffers
    base.stdout.close()
    base.stderr.close()
    assert base.returncode == 130, err
    assert "serving" not in out and "interrupted" in err
    assert total - at_signal < 1.0, (total, at_signal, err)
    assert not record.exists()
