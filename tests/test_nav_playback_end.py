"""The end of a realtime playback is not a device failure (GitHub issue 24, item 10): after
`leonav nav --from SESSION --realtime` ends cleanly, the copied session.json says every device
(GNSS, IMU and the SDR's recorded capture) stopped, with no "device error", and nav.json lists no
lost device. Before, the ptys were closed under the readers ("device reports readiness to read but
returned no data") and the capture's end was recorded as "device error: end of the recorded capture"."""
from __future__ import annotations

import json

from tests.test_nav_live import nav_options


def test_a_clean_end_of_a_realtime_playback_records_no_device_error(tmp_path):
    from leonav_runtime.nav.run import run_nav
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    write_synthetic_session(tmp_path / "s", SynthSessionConfig(seconds=3.0, seed=2, sdr=True, sdr_rate_hz=200e3))
    res = run_nav(nav_options(tmp_path / "out", mode="fix+leo-alpha+imu", session=tmp_path / "s", realtime=True))
    assert res["exit_code"] == 0 and res["end_reason"] == "playback ended" and res["devices_lost"] == {}, res
    info = json.loads((tmp_path / "out" / "session" / "session.json").read_text())
    assert info["status"] == "complete"
    kinds = {d["kind"]: d for d in info["devices"]}
    assert set(kinds) == {"gnss", "imu", "sdr"}
    for dev in kinds.values():
        assert dev["error"] == "" and dev["end_reason"] == "stopped", dev
    assert kinds["sdr"]["n_samples"] >= 0.9 * 3.0 * 200e3      # the whole capture was read first
