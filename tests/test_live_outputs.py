"""Live outputs against outside decoders: gpsd reads leonav's NMEA TCP stream, pymavlink
decodes its MAVLink, pynmea2 parses every sentence; servers stay on the loopback."""
from __future__ import annotations

import datetime as dt
import json
import math
import shutil
import socket
import subprocess
import time

import pynmea2
import pytest

from leonav_runtime.nav.sinks import nmea_out
from leonav_runtime.nav.sinks.servers import PtyOutput, TcpBroadcastServer
from leonav_runtime.nav.sinks.solution import NavSolution

UTC = dt.timezone.utc


def _solution(t: dt.datetime, **kw) -> NavSolution:
    base = dict(utc=t, lat_rad=math.radians(43.0848638), lon_rad=math.radians(-77.6786127), h_m=170.25,
                v_enu_mps=(0.3, -0.2, 0.01), rpy_rad=(0.01, -0.02, math.radians(60.0)),
                sigma_enu_m=(1.2, 1.5, 3.0), sigma_v_enu_mps=(0.05, 0.05, 0.1), mode="fix+imu",
                n_gnss=9, n_leo=4)
    base.update(kw)
    return NavSolution(**base)


def test_sentences_parse_with_pynmea2_and_carry_the_solution():
    sol = _solution(dt.datetime(2026, 2, 23, 23, 59, 59, 996000, tzinfo=UTC))
    lines = nmea_out.sentences(sol).decode().split("\r\n")[:-1]
    msgs = [pynmea2.parse(line, check=True) for line in lines]
    rmc, gga, gst, plnav = msgs
    assert gga.latitude == pytest.approx(sol.lat_deg, abs=2e-7) and gga.longitude == pytest.approx(sol.lon_deg, abs=2e-7)
    assert float(gga.altitude) + float(gga.geo_sep) == pytest.approx(170.2, abs=0.051)
    # rounding 23:59:59.996 to hundredths carries into the next day in both time and date
    assert rmc.datestamp == dt.date(2026, 2, 24) and rmc.timestamp.hour == 0
    assert float(rmc.spd_over_grnd) * 1852 / 3600 == pytest.approx(math.hypot(0.3, 0.2), abs=1e-3)
    assert float(rmc.true_course) == pytest.approx(math.degrees(math.atan2(0.3, -0.2)) % 360, abs=0.01)
    assert float(gst.std_dev_latitude) == 1.5 and float(gst.std_dev_longitude) == 1.2
    assert lines[3].startswith("$PLNAV,") and f"{sol.heading_deg:.2f}" in lines[3]
    assert sol.heading_deg == pytest.approx(30.0)  # yaw 60 deg from East towards North


def test_json_line_has_no_nan():
    sol = _solution(dt.datetime(2026, 2, 23, tzinfo=UTC), sigma_v_enu_mps=(math.nan,) * 3)
    d = json.loads(sol.json_line())
    assert d["sigma_v_enu_mps"] == [None, None, None] and d["lat_deg"] == pytest.approx(43.0848638)


def test_tcp_server_listens_on_loopback_and_drops_nobody_who_reads():
    server = TcpBroadcastServer(port=0)
    try:
        assert server.address[0] == "127.0.0.1"
        clients = [socket.create_connection(server.address, timeout=2) for _ in range(2)]
        deadline = time.monotonic() + 2
        while server.n_clients < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        payload = b"".join(nmea_out.sentences(_solution(dt.datetime(2026, 2, 23, 12, 0, s, tzinfo=UTC)))
                           for s in range(5))
        server.send(payload)
        for c in clients:
            got = b""
            while len(got) < len(payload):
                got += c.recv(65536)
            assert got == payload
        clients[0].close()
        time.sleep(0.05)
        server.send(b"x" * 10)
        server.send(b"y" * 10)
        assert server.n_clients == 1 and server.counts["clients_closed"] == 1
    finally:
        server.close()


def test_pty_output_reaches_a_reader(tmp_path):
    out = PtyOutput(tmp_path / "leonav-nmea")
    try:
        import os
        fd = os.open(out.link, os.O_RDONLY | os.O_NOCTTY)
        out.send(b"$GNGGA,test\r\n")
        assert os.read(fd, 100) == b"$GNGGA,test\r\n"
        os.close(fd)
    finally:
        out.close()
    assert not (tmp_path / "leonav-nmea").exists()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_gpsd_reports_leonavs_position(tmp_path):
    gpsd = shutil.which("gpsd") or ("/usr/sbin/gpsd" if shutil.os.path.exists("/usr/sbin/gpsd") else None)
    if not gpsd:
        pytest.skip("needs gpsd (Debian package gpsd): the outside NMEA reader")
    server = TcpBroadcastServer(port=0)
    gpsd_port = _free_port()
    proc = subprocess.Popen([gpsd, "-N", "-n", "-S", str(gpsd_port), "-F", str(tmp_path / "gpsd.sock"),
                             f"tcp://127.0.0.1:{server.address[1]}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 10
        watch = None
        while watch is None and time.monotonic() < deadline:
            try:
                watch = socket.create_connection(("127.0.0.1", gpsd_port), timeout=1)
            except OSError:
                time.sleep(0.1)
        assert watch is not None, "gpsd did not open its port"
        watch.sendall(b'?WATCH={"enable":true,"json":true};\n')
        watch.settimeout(0.2)
        t0 = dt.datetime(2026, 2, 23, 12, 0, 0, tzinfo=UTC)
        tpv, buf, k = None, b"", 0
        while tpv is None and time.monotonic() < deadline:
            sol = _solution(t0 + dt.timedelta(seconds=0.2 * k))
            server.send(nmea_out.sentences(sol))
            k += 1
            try:
                buf += watch.recv(65536)
            except (TimeoutError, socket.timeout):
                pass
            *lines, buf = buf.split(b"\n")
            for line in lines:
                msg = json.loads(line)
                if msg.get("class") == "TPV" and msg.get("mode", 0) >= 3 and "lat" in msg:
                    tpv = msg
        assert tpv is not None, "gpsd reported no 3D TPV from leonav's stream"
        assert tpv["lat"] == pytest.approx(43.0848638, abs=2e-7)
        assert tpv["lon"] == pytest.approx(-77.6786127, abs=2e-7)
        assert tpv.get("altHAE", tpv.get("alt")) == pytest.approx(170.2, abs=0.051)
        assert tpv["time"].startswith("2026-02-23T12:00:")
        watch.close()
    finally:
        proc.terminate()
        proc.wait(timeout=5)
        server.close()


def test_pymavlink_receiver_decodes_gps_input():
    import os

    os.environ.setdefault("MAVLINK20", "1")
    mavutil = pytest.importorskip("pymavlink.mavutil", reason="needs pymavlink")
    from leonav_runtime.gnss.time import utc_to_gps_seconds
    from leonav_runtime.nav.sinks.mavlink_out import MavlinkOutput

    port = _free_port()
    rx = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", dialect="common")
    tx = MavlinkOutput(f"udpout:127.0.0.1:{port}")
    sol = _solution(dt.datetime(2026, 2, 23, 12, 0, 1, 500000, tzinfo=UTC))
    try:
        tx.send(sol)
        gps = rx.recv_match(type="GPS_INPUT", blocking=True, timeout=5)
        pos = rx.recv_match(type="GLOBAL_POSITION_SENSOR", blocking=True, timeout=5)
    finally:
        tx.close()
        rx.close()
    assert gps is not None and pos is not None
    assert gps.lat == round(43.0848638e7) and gps.lon == round(-77.6786127e7)
    assert gps.alt == pytest.approx(170.25, abs=1e-4)
    assert (gps.vn, gps.ve, gps.vd) == pytest.approx((-0.2, 0.3, -0.01), abs=1e-6)
    assert gps.horiz_accuracy == pytest.approx(math.hypot(1.2, 1.5), rel=1e-6)
    assert gps.vert_accuracy == pytest.approx(3.0, rel=1e-6)
    t_gps = utc_to_gps_seconds(sol.utc)
    assert gps.time_week == int(t_gps // 604800) and gps.time_week_ms == round((t_gps % 604800) * 1000)
    assert gps.yaw == 3000 and gps.fix_type == 3
    assert pos.source == tx.source and pos.eph == pytest.approx(math.hypot(1.2, 1.5), rel=1e-6)
