"""GLONASS strings of a real u-blox M10 log (ublox-glo.log, 2023-06-28, Moscow; SOURCES.md):
RXM-SFRBX strings 1-4 -> ephemerides -> orbit integration per the GLONASS ICD -> azimuth and
elevation at the receiver's NAV-PVT position, against the receiver's own NAV-SAT (whole
degrees) at the same epochs.

NAV-SAT is parsed here from the u-blox interface description (iTOW U4, version U1, numSvs U1,
2 reserved; per satellite 12 bytes: gnssId U1, svId U1, cno U1, elev I1 deg, azim I2 deg,
prRes I2, flags X4), a second reader kept apart from the code under test.
"""
from __future__ import annotations

import datetime as _dt
import math
import struct

import numpy as np
import pytest

from leonav.hardware.gnss.reader import GnssSplitter
from leonav.hardware.gnss.ubx import decode_nav_pvt
from leonav_runtime.orbits import geometry
from leonav_runtime.gnss import glonass
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.sfrbx import parse_sfrbx_payload
from tests.conftest import shared_file


def nav_sat(payload: bytes) -> tuple[float, list[tuple[int, int, int, int]]]:
    itow, _version, n = struct.unpack_from("<IBB", payload, 0)
    sats = []
    for i in range(n):
        gnss_id, sv_id, _cno, elev, azim = struct.unpack_from("<BBBbh", payload, 8 + 12 * i)
        sats.append((gnss_id, sv_id, elev, azim))
    return itow * 1e-3, sats


@pytest.fixture(scope="module")
def log():
    data = shared_file("ubx/gpsd/ublox-glo.log").read_bytes()
    splitter = GnssSplitter()
    frames, pvts, sats = [], [], []
    for kind, item, _t in splitter.feed(data, 0.0):
        if kind != "ubx":
            continue
        if (item.msg_class, item.msg_id) == (0x02, 0x13):
            frames.append(parse_sfrbx_payload(item.payload))
        elif (item.msg_class, item.msg_id) == (0x01, 0x07):
            pvts.append(decode_nav_pvt(item))
        elif (item.msg_class, item.msg_id) == (0x01, 0x35):
            sats.append(nav_sat(item.payload))
    return frames, pvts, sats


def test_strings_decode_to_ephemerides(log):
    frames, pvts, _ = log
    ephs, counts = glonass.ephemerides_from_sfrbx(frames, pvts[0].utc)
    print(counts, [(e.slot, e.tb_utc.isoformat(), e.k) for e in ephs])
    assert counts["strings"] == 584 and counts["slot_mismatch"] == 0 and counts["frames"] >= 30
    slots = sorted({e.slot for e in ephs})
    assert slots == [2, 3, 11, 12]
    for e in ephs:
        r = np.linalg.norm(e.r_m)
        # a GLONASS orbit: radius 25,440-25,560 km, speed about 3.9 km/s (ECEF, with rotation terms)
        assert 25.3e6 < r < 25.7e6 and 3.0e3 < np.linalg.norm(e.v_mps) < 4.5e3
        assert abs((e.tb_utc - pvts[0].utc).total_seconds()) < 3600 and e.health == 0 and e.nt == 1275
        assert -7 <= e.k <= 6 and abs(e.tau_n_s) < 1e-3


def test_orbit_gives_the_receivers_azimuth_and_elevation(log):
    """Every NAV-SAT report of the four slots over the 5 minutes: integrated position seen
    from the NAV-PVT position, compared with NAV-SAT's whole degrees (rounded: +-0.5 deg, plus
    the receiver's own orbit): elevation within 1 deg, azimuth within 1 deg of arc on the sky
    (|d_az| cos(el): slot 3 passes at 76-78 deg, where 1.5 deg of azimuth are 0.34 deg of arc).
    Measured: elevation within 0.67 deg, azimuth within 0.72 deg below 30 deg elevation."""
    frames, pvts, sats = log
    ephs, _ = glonass.ephemerides_from_sfrbx(frames, pvts[0].utc)
    pvt_by_itow = {round(p.itow_s, 3): p for p in pvts}
    d_el, d_az = [], []
    for itow, entries in sats:
        p = pvt_by_itow.get(round(itow, 3))
        if p is None or p.utc is None:
            continue
        r_rx = np.asarray(geometry.geodetic_to_ecef(p.lat_rad, p.lon_rad, p.height_m), float)
        C = geometry.C_enu_ecef(p.lat_rad, p.lon_rad)
        for gnss_id, sv_id, elev, azim in entries:
            if gnss_id != glonass.GLONASS_ID or elev < 0 or elev > 90:
                continue
            eph = glonass.nearest(ephs, sv_id, p.utc)
            if eph is None:
                continue
            r_sat, _ = glonass.state_at(eph, p.utc)
            e, n, u = C @ (r_sat - r_rx)
            el = math.degrees(math.atan2(u, math.hypot(e, n)))
            az = math.degrees(math.atan2(e, n)) % 360.0
            d_el.append(el - elev)
            d_az.append((((az - azim + 180.0) % 360.0) - 180.0) * math.cos(math.radians(el)))
    d_el, d_az = np.array(d_el), np.array(d_az)
    print(f"\n{d_el.size} comparisons: elevation diff max {np.abs(d_el).max():.3f} deg, "
          f"azimuth diff on the sky max {np.abs(d_az).max():.3f} deg")
    assert d_el.size >= 1000
    assert np.abs(d_el).max() <= 1.0 and np.abs(d_az).max() <= 1.0
    # the rounding is to the nearest degree: the mean differences are near 0, not 0.5
    assert abs(d_el.mean()) < 0.2 and abs(d_az.mean()) < 0.2


def test_tb_resolution_and_bad_strings():
    """tb is put on the Moscow day nearest the reference; a short payload and a string 4 of
    another slot are counted, not decoded."""
    ref = _dt.datetime(2023, 6, 28, 22, 50, tzinfo=_dt.timezone.utc)     # 01:50 Moscow, next day
    assert glonass.tb_utc(4, ref) == _dt.datetime(2023, 6, 28, 22, 0, tzinfo=_dt.timezone.utc)
    assert glonass.tb_utc(95, ref) == _dt.datetime(2023, 6, 28, 20, 45, tzinfo=_dt.timezone.utc)

    class F:
        def __init__(self, words, sv=3):
            self.gnss_id, self.sv_id, self.freq_id, self.words = 6, sv, 12, words

    _, counts = glonass.ephemerides_from_sfrbx([F([1, 2])], ref)
    assert counts["short_string"] == 1 and counts["ephemerides"] == 0
    assert gtime.leap_seconds_at_utc(ref) == 18
