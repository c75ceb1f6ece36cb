"""GNSS ingest: NMEA/UBX splitting and decoding against real u-blox logs, pynmea2 and gpsd.

References are independent of the code under test: pynmea2 applied line by line to the
file, gpsd's own decoded JSON (.chk files), and physical constraints (carrier/code ratio).
"""
from __future__ import annotations

import datetime as dt
import json
import math
import random
import threading

import pynmea2
import pytest
import serial

from leonav.hardware.fakes import PtyDevice, split_bytes
from leonav.hardware.gnss import ubx, ubx_config
from leonav.hardware.gnss.reader import GnssDecoder, GnssReader, GnssSplitter
from leonav.hardware.records import GnssFix, NavPvt, NmeaSentence, RxmMeasx, RxmRawx, UbxAck, UbxFrame
from tests.conftest import shared_file

NMEA_LOGS = {  # name: (valid sentences, rejected sentence lines) from SOURCES.md
    "ublox-neo-m9n-nmea.log": (1403, 0),
    "ublox-8.log": (1008, 1),          # 1,009 lines, the last truncated on purpose
    "neo-m8n.log": (293, 0),
    "ublox-zed-f9p-nmea.log": (1015, 0),
    "nmea-rtk.log": (244, 0),
}
NMEA_REJECT_KEYS = ("nmea_truncated", "nmea_too_long", "nmea_non_ascii", "nmea_no_checksum",
                    "nmea_bad_checksum", "nmea_parse_error", "truncated_at_end")


def strip_comment_header(data: bytes) -> bytes:
    """gpsd logs start with '#' lines that a receiver never sends."""
    lines = data.split(b"\n")
    i = 0
    while i < len(lines) and lines[i].startswith(b"#"):
        i += 1
    return b"\n".join(lines[i:])


def pynmea2_reference(data: bytes) -> tuple[list[str], int, int]:
    """(valid sentence texts, rejected '$' lines, GGA fixes) by pynmea2 on each line."""
    valid, rejected, fixes = [], 0, 0
    for line in data.split(b"\n"):
        start = line.find(b"$")
        if start < 0:
            continue
        text = line[start:].rstrip(b"\r")
        try:
            msg = pynmea2.parse(text.decode("ascii"), check=True)
        except (pynmea2.ParseError, UnicodeDecodeError, ValueError):
            rejected += 1
            continue
        valid.append(text.decode("ascii"))
        if msg.sentence_type == "GGA" and int(msg.gps_qual or 0) > 0 and msg.lat:
            fixes += 1
    return valid, rejected, fixes


def decode_chunks(chunks) -> tuple[list, GnssDecoder]:
    decoder = GnssDecoder()
    out = []
    for k, chunk in enumerate(chunks):
        out.extend(decoder.decode(chunk, float(k)))
    decoder.close()
    return out, decoder


def nmea_rejected(decoder: GnssDecoder) -> int:
    return sum(decoder.rejected.get(k, 0) for k in NMEA_REJECT_KEYS)


@pytest.mark.parametrize("name", sorted(NMEA_LOGS))
def test_nmea_logs_agree_with_pynmea2_line_by_line(name):
    data = strip_comment_header(shared_file(f"nmea/gpsd/{name}").read_bytes())
    ref_valid, ref_rejected, ref_fixes = pynmea2_reference(data)
    expected_valid, expected_rejected = NMEA_LOGS[name]
    assert (len(ref_valid), ref_rejected) == (expected_valid, expected_rejected)

    # Random chunking (seeded): frames split across reads must not matter.
    rng = random.Random(1)
    chunks, i = [], 0
    while i < len(data):
        n = rng.randint(1, 300)
        chunks.append(data[i:i + n])
        i += n
    records, decoder = decode_chunks(chunks)
    sentences = [r for r in records if isinstance(r, NmeaSentence)]
    assert [s.text for s in sentences] == ref_valid
    for s in sentences[::37]:  # field-level agreement with pynmea2's own parse
        assert s.msg.data == pynmea2.parse(s.text).data
    assert decoder.counts["nmea_sentences"] == expected_valid
    assert nmea_rejected(decoder) == expected_rejected
    assert sum(isinstance(r, GnssFix) for r in records) == ref_fixes == decoder.counts["fixes"]


def test_comment_headers_are_counted_not_parsed():
    data = shared_file("nmea/gpsd/neo-m8n.log").read_bytes()
    records, decoder = decode_chunks([data])
    assert decoder.counts["nmea_sentences"] == 293
    # The header's "# Notes: $GLGSV  for GLONASS sats, and $GPGSV ..." yields rejected lines, not sentences.
    assert nmea_rejected(decoder) == 2
    assert decoder.rejected["junk_bytes"] > 0


def test_truncated_last_line_of_ublox8_is_counted():
    data = shared_file("nmea/gpsd/ublox-8.log").read_bytes()
    _, decoder = decode_chunks([data])
    assert decoder.counts["nmea_RMC"] == 72 and decoder.counts["nmea_GSV"] == 504
    assert nmea_rejected(decoder) == 1


def _tpv_by_time(chk_path):
    tpv = {}
    for line in chk_path.read_text().splitlines():
        if '"class":"TPV"' in line:
            obj = json.loads(line)
            if "time" in obj and "lat" in obj:
                tpv[obj["time"]] = obj
    return tpv


@pytest.mark.parametrize("name", ["ublox-neo-m9n-nmea.log", "ublox-zed-f9p-nmea.log"])
def test_nmea_fixes_match_gpsd_tpv(name):
    log = shared_file(f"nmea/gpsd/{name}")
    tpv = _tpv_by_time(shared_file(f"nmea/gpsd/{name}.chk"))
    fixes = [r for r in GnssReader(str(log)) if isinstance(r, GnssFix) and r.utc]
    matched = 0
    for fix in fixes:
        key = fix.utc.strftime("%Y-%m-%dT%H:%M:%S.") + f"{fix.utc.microsecond // 1000:03d}Z"
        if key not in tpv:
            continue
        matched += 1
        ref = tpv[key]
        assert math.degrees(fix.lat_rad) == pytest.approx(ref["lat"], abs=2e-9)
        assert math.degrees(fix.lon_rad) == pytest.approx(ref["lon"], abs=2e-9)
        assert fix.hmsl_m == pytest.approx(ref["altMSL"], abs=1e-3)
    assert matched >= 0.9 * len(fixes) and matched > 20


def _drain_reader(reader: GnssReader, total_bytes: int, timeout_s: float = 20.0) -> list:
    """Iterate a serial reader in this thread; stop it once every byte was read."""
    def watch():
        deadline = threading.Event()
        for _ in range(int(timeout_s / 0.02)):
            if reader.source.bytes_read >= total_bytes:
                break
            deadline.wait(0.02)
        deadline.wait(0.1)
        reader.stop()
    threading.Thread(target=watch, daemon=True).start()
    return list(reader)


@pytest.mark.parametrize("name", ["nmea/gpsd/ublox-neo-m9n-nmea.log", "nmea/gpsd/ublox-8.log"])
def test_nmea_over_pty_matches_file_decoding(name):
    data = strip_comment_header(shared_file(name).read_bytes())
    ref, ref_decoder = decode_chunks([data])
    dev = PtyDevice(split_bytes(data, 512), delay_s=0.0005, close_after_s=0.3)
    try:
        reader = GnssReader(dev.path, 38400)
        dev.start()
        live = list(reader)     # ends when the master closes (device gone)
    finally:
        reader.close()
        dev.close()
    assert reader.end_reason.startswith("device error")
    assert [r.text for r in live if isinstance(r, NmeaSentence)] == [r.text for r in ref if isinstance(r, NmeaSentence)]
    assert reader.decoder.counts == ref_decoder.counts
    assert nmea_rejected(reader.decoder) == nmea_rejected(ref_decoder)
    # stamps come from the monotonic clock and never go backwards
    stamps = [r.t_mono_s for r in live if isinstance(r, NmeaSentence)]
    assert all(b >= a for a, b in zip(stamps, stamps[1:]))


def test_mixed_ubx_nmea_over_pyserial_loop():
    data = shared_file("ubx/pyubx2/2023-4-17_82912_serial-COM3.ubx").read_bytes()
    port = serial.serial_for_url("loop://", timeout=0.05)

    def feed():
        for chunk in split_bytes(data, 700):
            port.write(chunk)
    threading.Thread(target=feed, daemon=True).start()
    reader = GnssReader(port)
    live = _drain_reader(reader, len(data))
    ref, ref_decoder = decode_chunks([data])
    assert reader.decoder.counts == ref_decoder.counts
    assert reader.decoder.counts["nmea_sentences"] == 818 and reader.decoder.counts["ubx_frames"] == 160
    assert reader.decoder.counts["nmea_RMC"] == 90 and reader.decoder.counts["nmea_GGA"] == 81
    assert sum(reader.decoder.rejected.values()) == 0
    acks = [r for r in live if isinstance(r, UbxAck)]
    assert len(acks) == 63 and sum(not a.acked for a in acks) == 7
    assert all(a.acked_class == 0x06 and a.acked_id in (0x8A, 0x8B) for a in acks)


def test_real_valset_frames_reencode_identically():
    """Our CFG-VALSET builder reproduces every real frame byte for byte from its items."""
    data = shared_file("ubx/pyubx2/2023-4-17_82912_serial-COM3.ubx").read_bytes()
    records, _ = decode_chunks([data])
    valsets = [r for r in records if isinstance(r, UbxFrame) and r.name == "CFG-VALSET"]
    assert len(valsets) == 27
    for frame in valsets:
        items = ubx_config.decode_valset(frame.payload)
        rebuilt = ubx_config.valset(items, layers=frame.payload[1], version=frame.payload[0],
                                     transaction=frame.payload[2])
        assert rebuilt == ubx.build_frame(0x06, 0x8A, frame.payload)
    all_keys = set().union(*(ubx_config.decode_valset(f.payload) for f in valsets))
    assert ubx_config.KEYS["CFG-MSGOUT-UBX_NAV_PVT_UART1"] in all_keys


def test_paper_config_frames_are_valid_ubx():
    frames = ubx_config.paper_10hz_config()
    records, decoder = decode_chunks([b"".join(frames)])
    assert decoder.counts["ubx_CFG-VALSET"] == len(frames) == 4 and not decoder.rejected
    items = {}
    for r in records:
        items |= ubx_config.decode_valset(r.payload)
    keys = ubx_config.KEYS
    assert items[keys["CFG-RATE-MEAS"]] == 100 and items[keys["CFG-RATE-NAV"]] == 1
    assert items[keys["CFG-MSGOUT-UBX_NAV_PVT_UART1"]] == 1
    assert items[keys["CFG-MSGOUT-UBX_RXM_RAWX_UART1"]] == 1
    baud = ubx_config.uart1_baudrate(115200)
    assert ubx_config.decode_valset(decode_chunks([baud])[0][0].payload) == {0x40520001: 115200}
    # RAM+BBR layers, version 0; the rate value is 2 bytes (size code 3)
    assert frames[0][6:10] == bytes([0, 3, 0, 0])
    assert frames[0][10:16] == bytes([0x01, 0x00, 0x21, 0x30, 100, 0])


def test_ubx_checksum_known_frame():
    # UBX-MON-VER poll, widely documented bytes: B5 62 0A 04 00 00 0E 34
    assert ubx.build_frame(0x0A, 0x04) == bytes.fromhex("b5620a0400000e34")
    # ACK-ACK for CFG-VALSET parses
    recs, _ = decode_chunks([ubx.build_frame(0x05, 0x01, bytes([0x06, 0x8A]))])
    assert recs == [UbxAck(0.0, True, 0x06, 0x8A)]


def test_nav_pvt_of_m10_log_matches_gpsd_tpv():
    log = shared_file("ubx/gpsd/ublox-glo.log")
    tpv = _tpv_by_time(shared_file("ubx/gpsd/ublox-glo.log.chk"))
    records, decoder = decode_chunks([log.read_bytes()])
    pvts = [r for r in records if isinstance(r, NavPvt)]
    assert len(pvts) == decoder.counts["ubx_NAV-PVT"] == 299
    matched = 0
    for p in pvts:
        key = p.utc.replace(microsecond=0).strftime("%Y-%m-%dT%H:%M:%S.000Z")
        ref = tpv.get(key)
        if ref is None:
            continue
        matched += 1
        assert math.degrees(p.lat_rad) == pytest.approx(ref["lat"], abs=1e-9)
        assert math.degrees(p.lon_rad) == pytest.approx(ref["lon"], abs=1e-9)
        assert p.height_m == pytest.approx(ref["altHAE"], abs=1e-3)
        assert p.hmsl_m == pytest.approx(ref["altMSL"], abs=1e-3)
        assert p.h_acc_m == pytest.approx(ref["eph"], abs=1e-3)
        assert p.v_acc_m == pytest.approx(ref["epv"], abs=1e-3)
        assert p.ground_speed_mps == pytest.approx(ref["speed"], abs=1e-3)
        assert ref["mode"] == min(p.fix_type, 3)
    assert matched == sum(p.fix_type > 0 for p in pvts) == 291
    assert pvts[0].utc.date() == dt.date(2023, 6, 28)
    # NAV-PVT iTOW (GPS) and UTC differ by the 18 leap seconds of 2023
    p = pvts[0]
    gps_utc = ubx.gps_to_utc(2268, p.itow_s, 18)
    assert abs((gps_utc - p.utc).total_seconds()) < 0.01


def test_rawx_of_neo_m8t_matches_gpsd_raw():
    log = shared_file("ubx/gpsd/ublox-neo-m8t.log")
    chk = shared_file("ubx/gpsd/ublox-neo-m8t.log.chk")
    raws = {}
    for line in chk.read_text().splitlines():
        if '"class":"RAW"' in line:
            obj = json.loads(line)
            raws[(obj["time"], obj["nsec"])] = obj
    records, decoder = decode_chunks([log.read_bytes()])
    epochs = [r for r in records if isinstance(r, RxmRawx)]
    assert len(epochs) == 39 == decoder.counts["ubx_RXM-RAWX"]
    compared = 0
    for e in epochs:
        assert e.week == 2024 and e.leap_s == 18 and e.leap_valid
        # gpsd stamps RAW with GPS time as POSIX seconds (no leap seconds)
        t = ubx.gps_to_utc(e.week, e.rcv_tow_s, 0)
        key = (int(t.timestamp()), round((t.timestamp() % 1) * 1e3) * 1000000)
        ref = raws[key]
        by_sv = {(m["gnssid"], m["svid"]): m for m in ref["rawdata"]}
        assert len(e.measurements) == 13 == len(ref["rawdata"])
        for m in e.measurements:
            r = by_sv[(m.gnss_id, m.sv_id)]
            assert m.pseudorange_m == pytest.approx(r["pseudorange"], abs=1e-5)
            if "carrierphase" in r:   # gpsd leaves it out when trkStat says it is invalid
                assert m.carrier_phase_cyc == pytest.approx(r["carrierphase"], abs=1e-5)
            else:
                assert not m.cp_valid
            assert m.doppler_hz == pytest.approx(r["doppler"], abs=1e-5)
            assert m.cno_dbhz == r["snr"]
            assert round(m.locktime_s * 1000) == r["locktime"]
            compared += 1
    assert compared == 39 * 13


C = 299792458.0
CARRIERS_HZ = [1575.42e6, 1227.60e6, 1176.45e6, 1207.14e6, 1561.098e6, 1268.52e6]


def _carrier_ok(ratio_hz_per_m: float) -> bool:
    f = ratio_hz_per_m * C
    glonass = 1598.0e6 <= f <= 1606.0e6 or 1242.0e6 <= f <= 1249.0e6
    return glonass or any(abs(f - fc) < 2e6 for fc in CARRIERS_HZ)


@pytest.mark.parametrize("name", ["ubx/pyubx2/pygpsdata-RXMRAWX.log", "ubx/gpsd/ublox-zed-f9p_hpg1.11.log"])
def test_rawx_values_are_physical(name):
    records, decoder = decode_chunks([shared_file(name).read_bytes()])
    epochs = [r for r in records if isinstance(r, RxmRawx)]
    assert len(epochs) == {"ubx/pyubx2/pygpsdata-RXMRAWX.log": 14}.get(name, 654)
    n_checked = 0
    for e in epochs:
        assert 0 <= e.rcv_tow_s < 604800 and e.week in (2048, 2327)
        for m in e.measurements:
            if m.pr_valid:
                assert 1.8e7 < m.pseudorange_m < 4.2e7
            assert abs(m.doppler_hz) < 6000 and 0 <= m.cno_dbhz < 60
            if m.pr_valid and m.cp_valid:
                # carrier phase (cycles) ~ pseudorange / wavelength: pins the R8 offsets
                assert _carrier_ok(m.carrier_phase_cyc / m.pseudorange_m)
                n_checked += 1
    assert n_checked > 10 * len(epochs)
    tows = [e.rcv_tow_s for e in epochs]
    assert all(0.99 < b - a < 1.01 for a, b in zip(tows, tows[1:]))


def test_measx_doppler_pairs_give_known_carriers():
    records, decoder = decode_chunks([shared_file("ubx/gpsd/ublox-zed-f9p_hpg1.11.log").read_bytes()])
    measx = [r for r in records if isinstance(r, RxmMeasx)]
    assert len(measx) == 654 == decoder.counts["ubx_RXM-MEASX"]
    rawx_tows = {round(r.rcv_tow_s) for r in records if isinstance(r, RxmRawx)}
    assert sum(round(m.gps_tow_s) in rawx_tows for m in measx) > 640
    checked = 0
    for m in measx:
        for s in m.satellites:
            if abs(s.doppler_mps) > 100:
                assert _carrier_ok(-s.doppler_hz / -s.doppler_mps)
                checked += 1
    assert checked > 1000


def test_random_corruption_never_crashes_and_is_counted():
    data = shared_file("ubx/gpsd/ublox-zed-f9p_hpg1.11.log").read_bytes()[:200000]
    clean, clean_dec = decode_chunks([data])
    rng = random.Random(42)
    corrupted = bytearray(data)
    for _ in range(300):
        corrupted[rng.randrange(len(corrupted))] = rng.randrange(256)
    for _ in range(30):  # garbage bursts and deletions
        pos = rng.randrange(len(corrupted))
        corrupted[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 40)))
        del corrupted[rng.randrange(len(corrupted)):][:rng.randint(1, 40)]
    records, dec = decode_chunks(split_bytes(bytes(corrupted), 333))
    n_clean = clean_dec.counts["ubx_frames"] + clean_dec.counts["nmea_sentences"]
    n_bad = dec.counts["ubx_frames"] + dec.counts["nmea_sentences"]
    assert 0.5 * n_clean < n_bad < n_clean
    assert dec.rejected["ubx_bad_checksum"] + dec.rejected["nmea_bad_checksum"] > 0
    # every surviving sentence is one of the clean ones (checksums make false accepts rare)
    clean_texts = {r.text for r in clean if isinstance(r, NmeaSentence)}
    survived = [r.text for r in records if isinstance(r, NmeaSentence)]
    assert sum(t in clean_texts for t in survived) >= len(survived) - 2


def test_splitter_handles_byte_by_byte_feed_and_resync():
    frame = ubx.build_frame(0x05, 0x01, bytes([0x06, 0x8A]))
    line = b"$GNGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*"
    line += f"{__import__('functools').reduce(lambda a, b: a ^ b, line[1:-1]):02X}\r\n".encode()
    stream = b"\xb5\x62\x01" + b"\x00garbage$GP" + frame + line + b"\xb5" + line + frame
    splitter = GnssSplitter()
    items = []
    for k in range(len(stream)):
        items.extend(splitter.feed(stream[k:k + 1], float(k)))
    splitter.close()
    kinds = [kind for kind, _, _ in items]
    assert kinds == ["ubx", "nmea", "nmea", "ubx"]
    # frame stamps are the chunk of their last byte
    assert items[0][2] == stream.index(frame) + len(frame) - 1
    assert splitter.rejected["nmea_truncated"] == 1      # "$GP" cut by the UBX frame
    assert sum(splitter.rejected.values()) > 0
