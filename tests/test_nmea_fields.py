"""NMEA: checksum and '*hh' rules from NMEA 0183, every GGA fix field against pynmea2 and
gpsd (real u-blox logs), ZDA/RMC time tags, and the GGA midnight rollover.

References: the XOR checksum computed here from the definition, pynmea2's own field
accessors (`latitude`, `num_sats`, `horizontal_dil`, `gps_qual`), gpsd's decoded TPV
(altHAE = hMSL + geoid separation, the fix time).
"""
from __future__ import annotations

import datetime as dt
import functools
import json
import math

import pynmea2
import pytest

from leonav.hardware.gnss import nmea
from leonav.hardware.gnss.reader import GnssReader
from leonav.hardware.records import GnssFix, GnssTimeTag, NmeaSentence
from tests.conftest import shared_file

UTC = dt.timezone.utc
LOGS = ["ublox-neo-m9n-nmea.log", "ublox-zed-f9p-nmea.log", "ublox-8.log", "nmea-rtk.log", "neo-m8n.log"]


def xor(body: bytes) -> int:
    return functools.reduce(lambda a, b: a ^ b, body, 0)


def sentence(body: str) -> bytes:
    return f"${body}*{xor(body.encode()):02X}\r\n".encode()


def _sentences(name: str) -> list[bytes]:
    out = []
    for line in shared_file(f"nmea/gpsd/{name}").read_bytes().split(b"\n"):
        line = line.rstrip(b"\r")
        if line.startswith(b"$") and len(line) > 3 and line[-3:-2] == b"*":
            out.append(line)
    return out


@pytest.mark.parametrize("name", LOGS)
def test_checksum_is_the_xor_of_every_real_sentence(name):
    lines = _sentences(name)
    assert len(lines) > 200
    for line in lines:
        body, hh = line[1:-3], line[-2:]
        assert nmea.nmea_checksum(body) == int(hh, 16) == xor(body)


GGA = "GNGGA,123519.00,4807.03800,N,01131.00000,E,1,08,0.9,545.4,M,46.9,M,,"


@pytest.mark.parametrize("tail, reason", [
    ("", nmea.NO_CHECKSUM),                  # no '*' at all
    ("*4", nmea.NO_CHECKSUM),                # one hex digit
    ("*4B7", nmea.NO_CHECKSUM),              # three
    ("*G1", nmea.NO_CHECKSUM),               # not hex
])
def test_malformed_checksum_field_is_no_checksum(tail, reason):
    assert nmea.parse_sentence(f"${GGA}{tail}\r\n".encode(), 0.0) == reason


def test_wrong_checksum_is_rejected_and_right_one_parsed():
    good = sentence(GGA)
    s = nmea.parse_sentence(good, 1.5)
    assert isinstance(s, NmeaSentence) and s.sentence_type == "GGA" and s.talker == "GN" and s.t_mono_s == 1.5
    value = xor(GGA.encode())
    for wrong in (value ^ 1, value ^ 0x80, (value + 1) & 0xFF, sum(GGA.encode()) & 0xFF):
        if wrong == value:
            continue
        assert nmea.parse_sentence(f"${GGA}*{wrong:02X}".encode(), 0.0) == nmea.BAD_CHECKSUM
    assert nmea.parse_sentence(f"${GGA}*{value:02x}".encode(), 0.0).sentence_type == "GGA"  # lower-case hex


@pytest.mark.parametrize("name", LOGS)
def test_real_logs_with_one_corrupted_character_are_rejected(name):
    """Change one field character of each real sentence: the checksum must catch it."""
    lines = _sentences(name)[:150]
    for line in lines:
        k = line.index(b",") + 1
        ch = line[k:k + 1]
        swapped = line[:k] + (b"7" if ch != b"7" else b"3") + line[k + 1:]
        assert nmea.parse_sentence(swapped, 0.0) == nmea.BAD_CHECKSUM


def _tpv(name):
    tpv = {}
    for line in shared_file(f"nmea/gpsd/{name}.chk").read_text().splitlines():
        if '"class":"TPV"' in line:
            obj = json.loads(line)
            if "time" in obj:
                tpv[obj["time"]] = obj
    return tpv


@pytest.mark.parametrize("name", ["ublox-neo-m9n-nmea.log", "ublox-zed-f9p-nmea.log"])
def test_gga_fix_fields_match_pynmea2_and_gpsd(name):
    records = list(GnssReader(str(shared_file(f"nmea/gpsd/{name}"))))
    tpv = _tpv(name)
    n_sent = n_hae = 0
    last_gga = None
    for r in records:
        if isinstance(r, NmeaSentence) and r.sentence_type == "GGA":
            last_gga = pynmea2.parse(r.text)
        if not isinstance(r, GnssFix):
            continue
        ref = last_gga                         # the GGA this fix came from (same record stream order)
        assert r.quality == int(ref.gps_qual) > 0
        assert r.num_sv == int(ref.num_sats)
        assert r.hdop == pytest.approx(float(ref.horizontal_dil))
        assert math.degrees(r.lat_rad) == pytest.approx(ref.latitude, abs=1e-12)
        assert math.degrees(r.lon_rad) == pytest.approx(ref.longitude, abs=1e-12)
        assert r.hmsl_m == pytest.approx(float(ref.altitude))
        n_sent += 1
        key = r.utc.strftime("%Y-%m-%dT%H:%M:%S.000Z")
        if key in tpv and "altHAE" in tpv[key]:
            assert r.height_m == pytest.approx(tpv[key]["altHAE"], abs=1e-3)   # hMSL + geoid separation
            n_hae += 1
    assert n_sent > 25 and n_hae > 20


@pytest.mark.parametrize("name, day", [("ublox-neo-m9n-nmea.log", dt.date(2020, 7, 11)),
                                       ("ublox-8.log", dt.date(2017, 1, 10)),
                                       ("ublox-zed-f9p-nmea.log", dt.date(2019, 4, 12))])
def test_zda_and_rmc_time_tags_agree_with_gpsd(name, day):
    records = list(GnssReader(str(shared_file(f"nmea/gpsd/{name}"))))
    tags = [r for r in records if isinstance(r, GnssTimeTag)]
    zda = [t for t in tags if t.source == "ZDA"]
    rmc = [t for t in tags if t.source == "RMC"]
    assert len(zda) > 20 and len(rmc) > 20
    assert {t.utc.date() for t in zda} == {t.utc.date() for t in rmc} == {day}
    tpv_times = set(_tpv(name))
    hits = sum(t.utc.strftime("%Y-%m-%dT%H:%M:%S.000Z") in tpv_times for t in zda)
    assert hits >= 0.9 * len(zda)


def test_gga_after_midnight_takes_the_next_day():
    b = nmea.NmeaFixBuilder()
    rmc = nmea.parse_sentence(sentence("GNRMC,235959.00,A,4807.03800,N,01131.00000,E,0.0,,311216,,,A"), 1.0)
    tag = b.time_tag(rmc)
    assert tag.utc == dt.datetime(2016, 12, 31, 23, 59, 59, tzinfo=UTC)
    gga = nmea.parse_sentence(sentence(GGA.replace("123519.00", "000000.00")), 2.0)
    fix = b.fix(gga)
    assert fix.utc == dt.datetime(2017, 1, 1, 0, 0, 0, tzinfo=UTC)
    gga_before = nmea.parse_sentence(sentence(GGA.replace("123519.00", "235958.00")), 0.5)
    assert b.fix(gga_before).utc == dt.datetime(2016, 12, 31, 23, 59, 58, tzinfo=UTC)


def test_gga_fields_south_west_and_heights():
    body = "GPGGA,010203.00,4552.65403,S,07030.00100,W,2,11,1.27,14.2,M,1.8,M,,"
    b = nmea.NmeaFixBuilder()
    fix = b.fix(nmea.parse_sentence(sentence(body), 0.0))
    assert math.degrees(fix.lat_rad) == pytest.approx(-(45 + 52.65403 / 60), abs=1e-12)
    assert math.degrees(fix.lon_rad) == pytest.approx(-(70 + 30.001 / 60), abs=1e-12)
    assert (fix.quality, fix.num_sv, fix.hdop, fix.hmsl_m) == (2, 11, 1.27, 14.2)
    assert fix.height_m == pytest.approx(16.0) and fix.utc is None   # no date seen yet
    no_fix = body.replace(",2,11,", ",0,00,")
    assert b.fix(nmea.parse_sentence(sentence(no_fix), 0.0)) is None


def test_rmc_writer_carries_the_rounding_into_the_date():
    """23:59:59.996 is written as 00:00:00.00 of the next day: time and date agree (pynmea2)."""
    from leonav.hardware.gnss import nmea_write

    line = nmea_write.rmc(dt.datetime(2026, 12, 31, 23, 59, 59, 996000, tzinfo=dt.timezone.utc),
                          43.08, -77.67, 1.0, 0.0).decode().strip()
    msg = pynmea2.parse(line, check=True)
    assert msg.datestamp == dt.date(2027, 1, 1) and msg.timestamp.replace(tzinfo=None) == dt.time(0, 0, 0)
