"""`leonav nav` under load (GitHub issue 24, done-when): 1,000 TCP clients opened and closed against a
running `leonav nav --realtime` started under `ulimit -n 256`, with 10 more clients that never read
held open all along. Navigation completes, nav.json is written, every IMU packet's latency to its
solution is measured, every client is either served or refused politely (one NMEA TXT
sentence) and counted, no accept ever fails for want of descriptors, and nothing is imported or
opened for the first time once the server accepts (under descriptor exhaustion that would fail).
The latency itself (goal: p99 under 50 ms while stormed) is a speed figure and is measured by
benchmarks/bench_nav_load.py, with and without the storm side by side: under a loaded test run the
scheduler, not the server, sets a percentile (123 ms was seen with the whole suite beside it).
A server that blocked on a client would fail here anyway: the rows and samples would stop."""
from __future__ import annotations

import json

import pytest

from tests.nav_storm import NavChild, dead_clients, storm

SECONDS = 8.0
CLIENTS = 1000
DEAD = 10
LIMIT = 32          # the default --nmea-max-clients


@pytest.fixture(scope="module")
def stormed(tmp_path_factory):
    """One nav run under the storm: (exit code, nav.json, audit, output, what the clients saw)."""
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    base = tmp_path_factory.mktemp("navload")
    write_synthetic_session(base / "s", SynthSessionConfig(seconds=SECONDS, seed=11, sdr=False, imu_rate_hz=100.0,
                                                           imu_baud=115200))
    child = NavChild(base / "s", base / "out", nofile=256)
    port = child.wait_serving()
    held = dead_clients(port, DEAD)
    try:
        seen = storm(port, total=CLIENTS, wave=100, pause_s=0.35)
        code, nav, audit, text = child.wait(timeout_s=60)
    finally:
        for s in held:
            s.close()
    return code, nav, audit, text, seen, base, port


@pytest.mark.slow
def test_navigation_completes_under_1000_clients_and_256_descriptors(stormed):
    code, nav, _, text, seen, *_ = stormed
    assert code == 0 and nav, text
    assert nav["end_reason"] == "playback ended" and nav["started"] and not nav["devices_lost"], text
    assert nav["trajectory_rows"] >= 10 * (SECONDS - 2), nav["trajectory_rows"]
    assert nav["latency_ms"]["p50"] <= nav["latency_ms"]["p99"], nav["latency_ms"]
    assert nav["latency_ms"]["samples"] >= 100 * (SECONDS - 2)


def test_every_client_is_served_or_refused_and_counted(stormed):
    _, nav, _, text, seen, _, port = stormed
    tcp = nav["outputs"]["tcp"]
    assert seen["connected"] == CLIENTS
    assert tcp["clients_accepted"] + tcp["clients_refused_limit"] == CLIENTS + DEAD, tcp
    assert tcp["clients_refused_limit"] > 0 and tcp["clients_accepted"] > LIMIT, tcp
    assert tcp["accept_errors"] == 0, tcp          # the limit keeps the descriptors from running out
    assert seen["refused"] > 0 and seen["nmea"] > 0, seen   # refused with a reason; served ones got NMEA
    assert nav["nmea_tcp"] == f"127.0.0.1:{port}"      # --nmea-port auto: the port printed is the one served


def test_nothing_is_imported_or_opened_first_once_serving(stormed):
    _, _, audit, text, *_ = stormed
    assert audit.get("exit_code") == 0, text
    assert audit["new_modules"] == [], audit["new_modules"]
    assert audit["opens"] == [], audit["opens"]


def test_the_end_of_the_playback_is_no_device_error(stormed):
    base = stormed[5]
    info = json.loads((base / "out" / "session" / "session.json").read_text())
    assert info["status"] == "complete"
    for dev in info["devices"]:
        assert dev["error"] == "" and "device error" not in dev["end_reason"], dev
