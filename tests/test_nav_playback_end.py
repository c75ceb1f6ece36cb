"""A session with a Starlink capture played back by `leonav nav` in a child process that audits
what it imports and opens once its NMEA server accepts (tests/nav_storm.py):

- the end of a realtime playback is not a device failure (GitHub issue 24, item 10): the copied
  session.json says every device (GNSS, IMU and the SDR's recorded capture) stopped, with no
  "device error", and nav.json lists no lost device. Before, the ptys were closed under the readers
  ("device reports readiness to read but returned no data") and the capture's end was recorded as
  "device error: end of the recorded capture";
- the beacon paths import and open nothing new once serving (realtime: the spawned beacon process
  and the SDR thread's SigMF metadata; fast playback: the built-in Starlink set and the EOP table
  its predictions use).
"""
from __future__ import annotations

import json

import pytest

from tests.nav_storm import NavChild

SECONDS = 8.0


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    folder = tmp_path_factory.mktemp("navend") / "s"
    # 8 s: long enough for the fast playback's beacon predictions (the EOP table) to start
    write_synthetic_session(folder, SynthSessionConfig(seconds=SECONDS, seed=2, sdr=True, sdr_rate_hz=200e3))
    return folder


@pytest.mark.slow
def test_a_clean_end_of_a_realtime_playback_records_no_device_error(session):
    child = NavChild(session, session.parent / "rt")
    child.wait_serving()
    code, nav, audit, text = child.wait()
    assert code == 0 and nav["end_reason"] == "playback ended" and nav["devices_lost"] == {}, text
    assert nav["mode"] == "fix+leo-alpha+imu"
    info = json.loads((session.parent / "rt" / "session" / "session.json").read_text())
    assert info["status"] == "complete"
    kinds = {d["kind"]: d for d in info["devices"]}
    assert set(kinds) == {"gnss", "imu", "sdr"}
    for dev in kinds.values():
        assert dev["error"] == "" and dev["end_reason"] == "stopped", dev
    assert kinds["sdr"]["n_samples"] >= 0.9 * SECONDS * 200e3      # the whole capture was read first
    assert audit["new_modules"] == [] and audit["opens"] == [], audit


def test_fast_playback_with_beacons_loads_nothing_once_serving(session):
    child = NavChild(session, session.parent / "fast", realtime=False)
    child.wait_serving()
    code, nav, audit, text = child.wait()
    assert code == 0 and nav["beacons"]["counts"]["samples"] > 0, text
    assert any("built-in Walker Starlink" in n for n in nav["beacons"]["notes"]), nav["beacons"]  # made once serving
    assert audit["new_modules"] == [] and audit["opens"] == [], audit
