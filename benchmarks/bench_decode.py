"""Decoding throughput of the hardware readers vs the real-time data rate at the paper's
settings (GNSS and IMU at 10 Hz). Prints one line per stream with the ratio; goal >= 100x.

Real-time byte rates are measured from the real logs: bytes per navigation epoch of the
log times 10 epochs/s (the logs are 1 Hz recordings of the same message sets), and 44 B
per WitMotion cycle (acc, gyro, angle, mag packets) times 10 Hz.

Run: .venv/bin/python benchmarks/bench_decode.py
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from leonav.hardware.gnss.reader import GnssDecoder  # noqa: E402
from leonav.hardware.imu.witmotion import SampleGrouper, WitMotionParser  # noqa: E402

DATA = REPO.parent / "shared" / "data"
RATE_HZ = 10.0
CHUNK = 256          # bytes per read, like a serial read at 115200 baud every ~20 ms


def _time_decode(make, data: bytes, min_seconds: float = 0.7) -> tuple[float, int]:
    """(bytes per second, records per pass) decoding `data` in CHUNK-byte reads."""
    chunks = [data[i:i + CHUNK] for i in range(0, len(data), CHUNK)]
    passes, records, t0 = 0, 0, time.perf_counter()
    while True:
        feed = make()
        n = 0
        for k, c in enumerate(chunks):
            n += len(feed(c, float(k)))
        records = n
        passes += 1
        elapsed = time.perf_counter() - t0
        if elapsed >= min_seconds:
            return passes * len(data) / elapsed, records


def gnss_feed():
    return GnssDecoder().decode


def imu_feed():
    parser, grouper = WitMotionParser(), SampleGrouper()

    def feed(chunk, t):
        out = []
        for p in parser.feed(chunk, t):
            out.extend(grouper.push(p))
        return out
    return feed


def main() -> int:
    cases = []
    nmea = DATA / "nmea/gpsd/ublox-neo-m9n-nmea.log"          # 61 epochs, full default NMEA set
    if nmea.exists():
        data = nmea.read_bytes()
        cases.append(("NMEA (u-blox M9N default set)", gnss_feed, data, len(data) / 61 * RATE_HZ))
    ubx = DATA / "ubx/gpsd/ublox-zed-f9p_hpg1.11.log"          # 654 epochs RAWX+MEASX+NAV-CLOCK+NMEA
    if ubx.exists():
        data = ubx.read_bytes()[:400000]
        cases.append(("UBX RAWX+MEASX+NMEA (ZED-F9P)", gnss_feed, data, ubx.stat().st_size / 654 * RATE_HZ))
    pvt = DATA / "ubx/gpsd/ublox-glo.log"                      # 299 epochs NAV-PVT/SAT/SIG/... (M10)
    if pvt.exists():
        data = pvt.read_bytes()
        cases.append(("UBX NAV-PVT+SAT+SIG+SFRBX (M10)", gnss_feed, data, len(data) / 299 * RATE_HZ))
    imu = DATA / "imu/witmotion/wt901sd_example_data.TXT"      # 2017 cycles of 4 packets
    if imu.exists():
        data = imu.read_bytes()
        cases.append(("WitMotion 0x51-0x54", imu_feed, data, 44 * RATE_HZ))
    if not cases:
        print("no data under ../shared/data: nothing to measure")
        return 1
    print(f"{'stream':34s} {'real-time B/s':>14s} {'decode B/s':>12s} {'records/pass':>13s} {'x real time':>12s}")
    worst = float("inf")
    for name, make, data, realtime_bps in cases:
        bps, records = _time_decode(make, data)
        ratio = bps / realtime_bps
        worst = min(worst, ratio)
        print(f"{name:34s} {realtime_bps:14,.0f} {bps:12,.0f} {records:13,d} {ratio:12,.0f}")
    print(f"slowest stream: {worst:,.0f}x real time at 10 Hz (goal >= 100x): {'OK' if worst >= 100 else 'BELOW GOAL'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
