"""Live outputs read back field by field by outside decoders (pymavlink, pynmea2), and the live
time map / IMU timing with the options no recorded session exercises (a GNSS output latency,
the UART serialization of the tag sentence and of the IMU packet)."""
from __future__ import annotations

import datetime as dt
import math
import os
import socket

import pynmea2
import pytest

from leonav_runtime.nav.sinks import nmea_out
from leonav_runtime.nav.sinks.solution import NavSolution

UTC = dt.timezone.utc
UART_BITS_PER_BYTE = 10          # 8N1: start bit, 8 data bits, stop bit
GPS_EPOCH_UNIX_S = 315964800.0   # 1980-01-06T00:00:00Z
GPS_MINUS_UTC_S = 18.0           # leap seconds since 2017-01-01 (IERS Bulletin C)
UERE_M = 1.5                     # the documented DOP <- sigma scale (nav/sinks: HDOP = sigma_h / 1.5 m)


def _solution(**kw) -> NavSolution:
    base = dict(utc=dt.datetime(2026, 2, 23, 12, 0, 1, 500000, tzinfo=UTC), lat_rad=math.radians(43.0848638),
                lon_rad=math.radians(-77.6786127), h_m=170.25, v_enu_mps=(0.3, -0.2, 0.01),
                rpy_rad=(0.05, -0.2, math.radians(60.0)), sigma_enu_m=(1.2, 1.6, 4.5),
                sigma_v_enu_mps=(0.05, 0.05, 0.1), mode="fix+imu", n_gnss=9, n_leo=4)
    base.update(kw)
    return NavSolution(**base)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _mavlink_roundtrip(sol: NavSolution):
    """(GPS_INPUT, GLOBAL_POSITION_SENSOR) as pymavlink decodes them from leonav's UDP output."""
    os.environ.setdefault("MAVLINK20", "1")
    mavutil = pytest.importorskip("pymavlink.mavutil", reason="needs pymavlink")
    from leonav_runtime.nav.sinks.mavlink_out import MavlinkOutput

    port = _free_port()
    rx = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", dialect="common")
    tx = MavlinkOutput(f"udpout:127.0.0.1:{port}")
    try:
        tx.send(sol)
        gps = rx.recv_match(type="GPS_INPUT", blocking=True, timeout=5)
        pos = rx.recv_match(type="GLOBAL_POSITION_SENSOR", blocking=True, timeout=5)
    finally:
        tx.close()
        rx.close()
    assert gps is not None and pos is not None, "no MAVLink message decoded"
    return gps, pos


def test_mavlink_dops_accuracies_and_velocity_as_pymavlink_decodes_them():
    sol = _solution()
    gps, pos = _mavlink_roundtrip(sol)
    sig_h = math.hypot(1.2, 1.6)   # 2.0 m
    # DOPs from the sigmas at the documented UERE, the same HDOP as the GGA sentence carries
    assert gps.hdop == pytest.approx(sig_h / UERE_M, rel=1e-6)
    assert gps.vdop == pytest.approx(4.5 / UERE_M, rel=1e-6)
    gga = pynmea2.parse(nmea_out.gga(sol).decode().strip(), check=True)
    assert float(gga.horizontal_dil) == pytest.approx(gps.hdop, abs=0.006)
    # accuracies in metres: horizontal is the hypot of E and N, vertical the Up sigma
    assert (gps.horiz_accuracy, gps.vert_accuracy) == pytest.approx((sig_h, 4.5), rel=1e-6)
    assert gps.speed_accuracy == pytest.approx(math.hypot(0.05, 0.05), rel=1e-6)
    assert (pos.eph, pos.epv) == pytest.approx((sig_h, 4.5), rel=1e-6)
    # NED velocity from ENU: north first, down = -up
    assert (gps.vn, gps.ve, gps.vd) == pytest.approx((-0.2, 0.3, -0.01), abs=1e-6)
    assert gps.satellites_visible == 13


def test_mavlink_gps_time_carries_the_leap_seconds():
    sol = _solution(utc=dt.datetime(2026, 2, 21, 23, 59, 50, tzinfo=UTC))  # Saturday, 10 s before midnight UTC
    gps, _ = _mavlink_roundtrip(sol)
    t_gps = sol.utc.timestamp() - GPS_EPOCH_UNIX_S + GPS_MINUS_UTC_S
    # 23:59:50 UTC is Sunday 00:00:08 GPST: the 18 leap seconds move it into the next GPS week
    assert gps.time_week == int(t_gps // 604800) and gps.time_week_ms == 8000


def test_mavlink_heading_due_north_is_36000_not_the_no_yaw_value():
    gps, _ = _mavlink_roundtrip(_solution(rpy_rad=(0.0, 0.0, math.radians(90.0))))   # yaw from East: 90 = north
    assert gps.yaw == 36000        # GPS_INPUT: 0 means "yaw not available", north is 36000
    gps, _ = _mavlink_roundtrip(_solution(rpy_rad=(0.0, 0.0, math.radians(-45.0))))  # south-east
    assert gps.yaw == 13500


def test_plnav_fields_in_their_documented_order():
    sol = _solution()
    line = nmea_out.plnav(sol).decode().strip()
    msg = pynmea2.parse(line, check=True)          # checksum verified by pynmea2
    f = line.split("*")[0].split(",")
    assert f[0] == "$PLNAV" and f[1] == "120001.50"
    assert [float(x) for x in f[2:5]] == pytest.approx([0.3, -0.2, 0.01], abs=1e-3)
    assert [float(x) for x in f[5:8]] == pytest.approx([math.degrees(0.05), math.degrees(-0.2), 30.0], abs=0.006)
    assert [float(x) for x in f[8:11]] == pytest.approx([1.2, 1.6, 4.5], abs=0.006)
    assert f[11:] == ["fix+imu", "9", "4"] and msg is not None


def _tags_and_sentences(n: int, t0_mono: float):
    """Records of n seconds of RMC as the session decoder gives them: the sentence and its time tag."""
    from leonav.hardware.gnss.nmea_write import rmc
    from leonav.hardware.gnss.reader import GnssDecoder

    t0 = dt.datetime(2026, 2, 23, 12, 0, 0, tzinfo=UTC)
    dec, recs, length = GnssDecoder(), [], 0
    for k in range(n):
        text = rmc(t0 + dt.timedelta(seconds=k), 43.0, -77.0, 0.0, 0.0)
        length = len(text.strip())
        recs += dec.decode(text, t0_mono + k)
    return recs + dec.close(), length, t0


def test_streaming_time_map_adds_the_gnss_latency_and_the_tag_sentence_serialization():
    from leonav_runtime.nav.timemap import StreamingTimeMap

    recs, length, t0 = _tags_and_sentences(5, 100.0)
    baud, latency = 9600, 0.045
    plain, late = StreamingTimeMap(baud), StreamingTimeMap(baud, gnss_latency_s=latency)
    for r in recs:
        plain.add(r)
        late.add(r)
    assert plain.valid and plain.map.source == "RMC"
    # the RMC of second k was stamped at mono 100 + k on arrival; it left the receiver one sentence
    # (text + CR LF, 10 bits a byte) earlier, and the receiver computed it `latency` before that
    serial = (length + 2) * UART_BITS_PER_BYTE / baud
    assert plain.tag_serialization_s() == pytest.approx(serial, rel=1e-12)
    assert plain.to_utc(102.0) == pytest.approx(t0.timestamp() + 2.0 + serial, abs=1e-6)
    assert late.to_utc(102.0) - plain.to_utc(102.0) == pytest.approx(latency, abs=1e-6)  # POSIX s: ulp 2.4e-7
    assert late.describe()["gnss_latency_ms"] == pytest.approx(45.0)
    assert late.describe()["shift_ms"] == pytest.approx((serial + latency) * 1e3)


def test_streaming_time_map_with_a_latency_agrees_with_the_replays_map(tmp_path):
    from leonav.hardware.session import decode_session

    from leonav_runtime.nav.timemap import StreamingTimeMap
    from leonav_runtime.replay.timebase import mono_to_utc_function
    from leonav_runtime.simulation.session_synth import (
        SynthSessionConfig,
        write_synthetic_session,
    )

    write_synthetic_session(tmp_path / "s", SynthSessionConfig(seconds=4.0, sdr=False))
    dec = decode_session(tmp_path / "s")
    m = StreamingTimeMap(38400, gnss_latency_s=0.03)
    for r in dec.gnss_records:
        m.add(r)
    to_utc, _ = mono_to_utc_function(dec, gnss_latency_s=0.03)
    t = dec.gnss_records[-1].t_mono_s
    assert m.to_utc(t) == pytest.approx(float(to_utc(t)), abs=1e-9)


def test_online_imu_timing_removes_the_packet_serialization():
    from leonav_runtime.nav.imu_timing import OnlineImuTiming

    baud, packet = 9600, 11                     # WitMotion: 11-byte packets
    plain, serial = OnlineImuTiming(), OnlineImuTiming(imu_baud=baud)
    for k in range(60):
        a, b = plain.add(5.0 + 0.01 * k), serial.add(5.0 + 0.01 * k)
    # a sample is complete when its last byte arrives: it was taken one packet's UART time earlier
    assert a[0] - b[0] == pytest.approx(packet * UART_BITS_PER_BYTE / baud, abs=1e-12)
