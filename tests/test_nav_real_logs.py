"""`leonav nav` live over pty devices fed with real recordings: gpsd's u-blox NEO-M9N NMEA log
(one epoch a second, at its own pace) and the WitMotion WT901SD recording (10 Hz), ~8 s.
The two logs come from different places and days, so the check is the live path itself: no
stall, every byte fed recorded, the fixes and IMU samples decoded, and a navigated solution."""
from __future__ import annotations

import json

import pytest

from tests.conftest import shared_file
from tests.test_nav_live import nav_options

SECONDS = 8.0


def _nmea_epochs(text: str) -> list[bytes]:
    """The log's sentences grouped per epoch (an epoch starts at each RMC)."""
    epochs, cur = [], []
    for line in text.splitlines():
        if not line.startswith("$"):
            continue
        if line[3:6] == "RMC" and cur:
            epochs.append(("\r\n".join(cur) + "\r\n").encode())
            cur = []
        cur.append(line)
    return epochs


@pytest.mark.slow
def test_live_over_ptys_with_real_gnss_and_imu_logs(tmp_path):
    from leonav_runtime.nav import sources
    from leonav_runtime.nav.run import run_nav

    nmea = _nmea_epochs(shared_file("nmea/gpsd/ublox-neo-m9n-nmea.log").read_text(errors="replace"))
    imu = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()
    n_epochs = int(SECONDS) + 1
    gnss_events = [(0.2 + k * 1.0, nmea[k]) for k in range(min(n_epochs, len(nmea)))]
    group = 44  # one sample: 0x51 acc, 0x52 gyro, 0x53 angle, 0x54 mag packets of 11 bytes
    imu_events = [(0.1 * k, imu[k * group:(k + 1) * group]) for k in range(int(SECONDS * 10))]
    ptys = {"gnss": sources.PacedPty(gnss_events), "imu": sources.PacedPty(imu_events)}
    out = tmp_path / "nav"
    opts = nav_options(out, gnss=ptys["gnss"].path, imu=ptys["imu"].path, seconds=SECONDS + 0.5)
    try:
        info = run_nav(opts, on_started=lambda: [p.start() for p in ptys.values()])
    finally:
        for p in ptys.values():
            p.close()
    assert info["exit_code"] == 0, info
    # every byte fed was recorded (the live run can always be replayed)
    raw_gnss = (out / "session" / "gnss.raw").read_bytes()
    raw_imu = (out / "session" / "imu.raw").read_bytes()
    assert b"".join(c for _, c in gnss_events).startswith(raw_gnss) and len(raw_gnss) > 0.8 * sum(
        len(c) for _, c in gnss_events[:-1])
    assert b"".join(c for _, c in imu_events).startswith(raw_imu) and len(raw_imu) > 0.8 * len(imu_events) * group
    sols = [json.loads(line) for line in (out / "solutions.jsonl").read_text().splitlines()]
    assert len(sols) > 20, "no stall: solutions kept coming"
    assert abs(sols[-1]["lat_deg"] - sols[0]["lat_deg"]) < 1e-3 and sols[-1]["n_gnss"] >= 0
