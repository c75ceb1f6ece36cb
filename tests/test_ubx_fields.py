"""Every decoded UBX field against an outside decoder (pyubx2) on real logs, and edge cases
(leap second, negative nano, RTK flags, validity bits) on frames that pyubx2 itself encodes.

pyubx2 applies the u-blox scale factors (deg, 1e-5 deg, 0.01, 2^-21 ms ...) independently of
hardware/gnss/ubx.py; our records are SI (rad, m, m/s, s), so each comparison states the
unit conversion once. Gpsd's decoded output (.chk) is the second opinion for heading,
climb and velocity.
"""
from __future__ import annotations

import datetime as dt
import io
import json
import math

import pytest

from leonav.hardware.gnss import ubx
from leonav.hardware.gnss.reader import GnssDecoder
from leonav.hardware.records import NavPvt, NavTimeGps, RxmMeasx, RxmRawx, UbxFrame
from tests.conftest import shared_file

pyubx2 = pytest.importorskip("pyubx2", reason="pyubx2 (outside UBX decoder) is in the test extra")

DEG = math.pi / 180.0
UTC = dt.timezone.utc

LOGS = {  # log: messages we decode and how many of each the log holds
    "ubx/gpsd/ublox-glo.log": {"NAV-PVT": 299, "NAV-TIMEGPS": 300},
    "ubx/gpsd/ublox-neo-m8u.log": {"NAV-PVT": 3, "NAV-TIMEGPS": 3},
    "ubx/gpsd/ublox-neo-m8t.log": {"NAV-TIMEGPS": 39, "RXM-RAWX": 39},
    # first 200 kB only (the whole log takes pyubx2 seconds): 108 epochs
    "ubx/gpsd/ublox-zed-f9p_hpg1.11.log": {"RXM-RAWX": 108, "RXM-MEASX": 108},
    "ubx/pyubx2/pygpsdata-RXMRAWX.log": {"RXM-RAWX": 14},
}
RECORD_TYPE = {"NAV-PVT": NavPvt, "NAV-TIMEGPS": NavTimeGps, "RXM-RAWX": RxmRawx, "RXM-MEASX": RxmMeasx}

_cache: dict[str, tuple[list, dict]] = {}


def _both(log: str) -> tuple[list, dict[str, list]]:
    """(our records, {identity: pyubx2 messages in order}) of one real log."""
    if log not in _cache:
        data = shared_file(log).read_bytes()
        if "zed-f9p" in log:
            data = data[:200_000]
        dec = GnssDecoder()
        ours = dec.decode(data, 0.0)
        dec.close()
        theirs: dict[str, list] = {}
        for _, msg in pyubx2.UBXReader(io.BytesIO(data), protfilter=2, quitonerror=0):
            if msg is not None:
                theirs.setdefault(msg.identity, []).append(msg)
        _cache[log] = (ours, theirs)
    return _cache[log]


def _pairs(log: str, identity: str):
    ours, theirs = _both(log)
    mine = [r for r in ours if isinstance(r, RECORD_TYPE[identity])]
    ref = theirs.get(identity, [])
    assert len(mine) == len(ref) == LOGS[log][identity]
    return list(zip(mine, ref))


def _check_pvt(p: NavPvt, m) -> None:
    assert p.itow_s == pytest.approx(m.iTOW * 1e-3, abs=1e-9)
    assert (p.valid_date, p.valid_time, p.fully_resolved) == (bool(m.validDate), bool(m.validTime),
                                                             bool(m.fullyResolved))
    assert p.t_acc_s == pytest.approx(m.tAcc * 1e-9, rel=1e-12)
    assert p.fix_type == m.fixType and p.gnss_fix_ok == bool(m.gnssFixOk)
    assert p.carr_soln == m.carrSoln and p.num_sv == m.numSV
    assert p.lat_rad == pytest.approx(m.lat * DEG, abs=1e-13)
    assert p.lon_rad == pytest.approx(m.lon * DEG, abs=1e-13)
    assert p.height_m == pytest.approx(m.height * 1e-3, abs=1e-9)
    assert p.hmsl_m == pytest.approx(m.hMSL * 1e-3, abs=1e-9)
    assert p.h_acc_m == pytest.approx(m.hAcc * 1e-3, abs=1e-9)
    assert p.v_acc_m == pytest.approx(m.vAcc * 1e-3, abs=1e-9)
    assert p.vel_ned_mps == pytest.approx((m.velN * 1e-3, m.velE * 1e-3, m.velD * 1e-3), abs=1e-12)
    assert p.ground_speed_mps == pytest.approx(m.gSpeed * 1e-3, abs=1e-12)
    assert p.head_mot_rad == pytest.approx(m.headMot * DEG, abs=1e-10)
    assert p.s_acc_mps == pytest.approx(m.sAcc * 1e-3, abs=1e-12)
    assert p.head_acc_rad == pytest.approx(m.headAcc * DEG, abs=1e-10)
    assert p.pdop == pytest.approx(m.pDOP, abs=1e-9)
    assert p.invalid_llh == bool(m.invalidLlh)
    if m.validDate and m.validTime:
        ref = dt.datetime(m.year, m.month, m.day, m.hour, m.min, tzinfo=UTC) + dt.timedelta(
            seconds=m.second, microseconds=m.nano / 1000)
        assert abs((p.utc - ref).total_seconds()) < 1e-6
    else:
        assert p.utc is None


@pytest.mark.parametrize("log", ["ubx/gpsd/ublox-glo.log", "ubx/gpsd/ublox-neo-m8u.log"])
def test_nav_pvt_every_field_matches_pyubx2(log):
    pairs = _pairs(log, "NAV-PVT")
    for p, m in pairs:
        _check_pvt(p, m)
    # the logs exercise the fields: moving/nonzero velocities, both validity states, flags
    assert any(abs(p.vel_ned_mps[0]) != abs(p.vel_ned_mps[1]) for p, _ in pairs)
    assert any(p.head_mot_rad > 1.0 for p, _ in pairs) and all(p.pdop < 100 for p, _ in pairs)


def test_nav_pvt_of_m8u_flags_heading_and_pdop_in_physical_units():
    """u-blox M8U (UDR): gnssFixOK, diffSoln and headVehValid set, carrSoln 0 (no RTK)."""
    (p, m), *_ = _pairs("ubx/gpsd/ublox-neo-m8u.log", "NAV-PVT")
    assert p.gnss_fix_ok and p.carr_soln == 0 and m.diffSoln == 1 and m.headVehValid == 1
    assert math.degrees(p.head_mot_rad) == pytest.approx(314.26162, abs=1e-5)   # 1e-5 deg units
    assert p.pdop == pytest.approx(1.67) and p.vel_ned_mps == pytest.approx((0.001, -0.013, 0.003))
    assert p.fully_resolved and p.t_acc_s == pytest.approx(8e-9)


@pytest.mark.parametrize("log", ["ubx/gpsd/ublox-glo.log", "ubx/gpsd/ublox-neo-m8u.log"])
def test_nav_pvt_heading_matches_gpsd_track(log):
    """gpsd's TPV of the same epochs: track = headMot in degrees."""
    tpv = {}
    for line in shared_file(log + ".chk").read_text().splitlines():
        if '"class":"TPV"' in line:
            obj = json.loads(line)
            tpv[obj["time"]] = obj
    matched = 0
    for p, _ in _pairs(log, "NAV-PVT"):
        ref = tpv.get(p.utc.replace(microsecond=0).strftime("%Y-%m-%dT%H:%M:%S.000Z"))
        if ref is None or "track" not in ref:
            continue
        matched += 1
        assert math.degrees(p.head_mot_rad) == pytest.approx(ref["track"], abs=1e-4)
    assert matched >= 2


@pytest.mark.parametrize("log", ["ubx/gpsd/ublox-glo.log", "ubx/gpsd/ublox-neo-m8u.log", "ubx/gpsd/ublox-neo-m8t.log"])
def test_nav_timegps_every_field_matches_pyubx2(log):
    pairs = _pairs(log, "NAV-TIMEGPS")
    for t, m in pairs:
        assert t.itow_s == pytest.approx(m.iTOW * 1e-3, abs=1e-9)
        assert t.ftow_s == pytest.approx(m.fTOW * 1e-9, abs=1e-15)   # ns
        assert (t.week, t.leap_s) == (m.week, m.leapS)
        assert (t.tow_valid, t.week_valid, t.leap_valid) == (bool(m.towValid), bool(m.weekValid), bool(m.leapSValid))
        assert t.t_acc_s == pytest.approx(m.tAcc * 1e-9, rel=1e-12)
        # the precise time of week is within 1 ms of the millisecond iTOW (|fTOW| <= 500 us)
        assert abs(t.ftow_s) <= 5e-4
    assert any(t.ftow_s != 0 for t, _ in pairs)


def test_nav_timegps_validity_bits_differ_in_the_m10_log():
    """The M10 log starts before the leap seconds are known: leapSValid 0 while week/TOW are valid."""
    pairs = _pairs("ubx/gpsd/ublox-glo.log", "NAV-TIMEGPS")
    assert any(t.week_valid and not t.leap_valid for t, _ in pairs)
    assert all(t.week == 2268 and t.leap_s == 18 for t, _ in pairs)


@pytest.mark.parametrize("log", ["ubx/gpsd/ublox-neo-m8t.log", "ubx/pyubx2/pygpsdata-RXMRAWX.log",
                                 "ubx/gpsd/ublox-zed-f9p_hpg1.11.log"])
def test_rxm_rawx_every_field_matches_pyubx2(log):
    pairs = _pairs(log, "RXM-RAWX")
    seen = {"half": False, "no_half": False, "cp_std": set(), "do_std": set(), "pr_std": set()}
    for e, m in pairs:
        assert e.rcv_tow_s == m.rcvTow and e.week == m.week and e.leap_s == m.leapS
        assert e.leap_valid == bool(m.leapSec) and e.clk_reset == bool(m.clkReset)
        assert e.version == m.reserved1 & 0xFF   # pyubx2 reads the version byte as part of reserved1
        assert len(e.measurements) == m.numMeas
        for n, r in enumerate(e.measurements, 1):
            f = lambda name: getattr(m, f"{name}_{n:02d}")  # noqa: E731
            assert (r.gnss_id, r.sv_id, r.sig_id, r.freq_id) == (f("gnssId"), f("svId"), f("sigId"), f("freqId"))
            assert r.pseudorange_m == f("prMes") and r.carrier_phase_cyc == f("cpMes")
            assert r.doppler_hz == pytest.approx(f("doMes"), rel=1e-7)
            assert r.cno_dbhz == f("cno") and r.locktime_s == pytest.approx(f("locktime") * 1e-3)
            # u-blox: prStdev 0.01 * 2^n m, cpStdev 0.004 * n cycles, doStdev 0.002 * 2^n Hz
            assert r.pr_std_m == pytest.approx(0.01 * 2 ** f("prStd"))
            assert r.cp_std_cyc == pytest.approx(0.004 * f("cpStd"))
            assert r.do_std_hz == pytest.approx(0.002 * 2 ** f("doStd"))
            assert (r.pr_valid, r.cp_valid, r.half_cyc, r.sub_half_cyc) == (
                bool(f("prValid")), bool(f("cpValid")), bool(f("halfCyc")), bool(f("subHalfCyc")))
            seen["half" if r.half_cyc else "no_half"] = True
            seen["cp_std"].add(r.cp_std_cyc)
            seen["do_std"].add(r.do_std_hz)
            seen["pr_std"].add(r.pr_std_m)
    assert seen["half"] and seen["no_half"]
    assert len(seen["cp_std"]) > 1 and len(seen["do_std"]) > 1 and len(seen["pr_std"]) > 1


def test_rxm_measx_every_field_matches_pyubx2():
    pairs = _pairs("ubx/gpsd/ublox-zed-f9p_hpg1.11.log", "RXM-MEASX")
    towset = set()
    for x, m in pairs:
        assert x.gps_tow_s == pytest.approx(m.gpsTOW * 1e-3) and x.glo_tow_s == pytest.approx(m.gloTOW * 1e-3)
        assert x.bds_tow_s == pytest.approx(m.bdsTOW * 1e-3) and x.qzss_tow_s == pytest.approx(m.qzssTOW * 1e-3)
        assert x.gps_tow_acc_s == pytest.approx(m.gpsTOWacc * 1e-3, abs=1e-12)   # pyubx2: ms (2^-4 applied)
        assert x.tow_set == m.towSet
        towset.add(x.tow_set)
        assert len(x.satellites) == m.numSv
        for n, s in enumerate(x.satellites, 1):
            f = lambda name: getattr(m, f"{name}_{n:02d}")  # noqa: E731
            assert (s.gnss_id, s.sv_id, s.cno_dbhz, s.mpath_indic) == (
                f("gnssId"), f("svId"), f("cNo"), f("mpathIndic"))
            assert s.doppler_mps == pytest.approx(f("dopplerMS"), abs=1e-9)
            assert s.doppler_hz == pytest.approx(f("dopplerHz"), abs=1e-9)
            assert (s.whole_chips, s.frac_chips, s.int_code_phase_ms, s.pseu_range_rms_err) == (
                f("wholeChips"), f("fracChips"), f("intCodePhase"), f("pseuRangeRMSErr"))
            assert s.code_phase_ms == pytest.approx(f("codePhase"), rel=1e-9)     # 2^-21 ms
    assert 2 in towset


# ---------------------------------------------------------------- frames pyubx2 encodes


def _decode(msg) -> object:
    raw = msg.serialize()
    frame = UbxFrame(0.0, raw[2], raw[3], bytes(raw[6:-2]))
    assert ubx.build_frame(raw[2], raw[3], raw[6:-2]) == raw   # our checksum equals pyubx2's
    return ubx.decode_frame(frame)


def _pvt(**fields):
    base = dict(iTOW=1000, year=2023, month=6, day=28, hour=14, min=52, second=12, validDate=1, validTime=1,
                fullyResolved=1, tAcc=20, nano=0, fixType=3, gnssFixOk=1, numSV=12, lat=55.6, lon=37.6,
                height=206121, hMSL=192758, hAcc=1500, vAcc=2500, velN=0, velE=0, velD=0, gSpeed=0, headMot=0.0,
                sAcc=100, headAcc=1.0, pDOP=1.5)
    base.update(fields)
    return pyubx2.UBXMessage("NAV", "NAV-PVT", pyubx2.GET, **base)


def test_leap_second_epoch_has_a_utc_time():
    """23:59:60 (leap second of 2016-12-31) is a valid epoch: UTC is the next day's 00:00:00 plus nano."""
    p = _decode(_pvt(year=2016, month=12, day=31, hour=23, min=59, second=60, nano=250_000))
    assert p.utc == dt.datetime(2017, 1, 1, 0, 0, 0, 250, tzinfo=UTC)


def test_negative_nano_rounds_down_to_the_previous_second():
    p = _decode(_pvt(second=12, nano=-300_000))
    assert p.utc == dt.datetime(2023, 6, 28, 14, 52, 11, 999700, tzinfo=UTC)


@pytest.mark.parametrize("carr", [0, 1, 2])
def test_rtk_carrier_solution_and_neighbouring_flag_bits(carr):
    """carrSoln is bits 6-7 of flags; headVehValid (bit 5) and diffSoln (bit 1) set must not leak into it."""
    p = _decode(_pvt(carrSoln=carr, headVehValid=1, diffSoln=1, gnssFixOk=0, psmState=3))
    assert p.carr_soln == carr and not p.gnss_fix_ok
    q = _decode(_pvt(carrSoln=carr, gnssFixOk=1))
    assert q.carr_soln == carr and q.gnss_fix_ok


def test_validity_bits_are_read_separately():
    p = _decode(_pvt(validDate=1, validTime=0, fullyResolved=0, validMag=1))
    assert (p.valid_date, p.valid_time, p.fully_resolved) == (True, False, False) and p.utc is None
    p = _decode(_pvt(validDate=0, validTime=1, fullyResolved=1))
    assert (p.valid_date, p.valid_time, p.fully_resolved) == (False, True, True) and p.utc is None
    p = _decode(_pvt(invalidLlh=1))
    assert p.invalid_llh
    p = _decode(_pvt(lastCorrectionAge=3))   # bits 1-4 of flags3 are not invalidLlh
    assert not p.invalid_llh


def test_velocity_heading_and_accuracies_of_a_moving_fix():
    p = _decode(_pvt(velN=12_345, velE=-6_789, velD=-250, gSpeed=14_089, headMot=331.25, headAcc=2.5,
                     sAcc=420, tAcc=12_345, pDOP=2.37, hAcc=1234, vAcc=2345))
    assert p.vel_ned_mps == pytest.approx((12.345, -6.789, -0.25))
    assert p.ground_speed_mps == pytest.approx(14.089)
    assert p.head_mot_rad == pytest.approx(math.radians(331.25), abs=1e-6)   # pyubx2 truncates to 1e-5 deg
    assert p.head_acc_rad == pytest.approx(math.radians(2.5), abs=1e-6)
    assert p.s_acc_mps == pytest.approx(0.42) and p.t_acc_s == pytest.approx(12.345e-6)
    assert p.pdop == pytest.approx(2.37) and (p.h_acc_m, p.v_acc_m) == pytest.approx((1.234, 2.345))
    assert (p.height_m, p.hmsl_m) == pytest.approx((206.121, 192.758))


def test_nav_timegps_negative_ftow_and_flags():
    msg = pyubx2.UBXMessage("NAV", "NAV-TIMEGPS", pyubx2.GET, iTOW=436762000, fTOW=-123456, week=2048, leapS=18,
                            towValid=1, weekValid=0, leapSValid=1, tAcc=25)
    t = _decode(msg)
    assert t.itow_s + t.ftow_s == pytest.approx(436761.999876544, abs=1e-9)
    assert (t.tow_valid, t.week_valid, t.leap_valid) == (True, False, True)
    assert t.t_acc_s == pytest.approx(25e-9) and (t.week, t.leap_s) == (2048, 18)


def test_rawx_receiver_status_bits():
    msg = pyubx2.UBXMessage("RXM", "RXM-RAWX", pyubx2.GET, rcvTow=1.5, week=2300, leapS=18, numMeas=0, leapSec=0,
                            clkReset=1, version=1)
    e = _decode(msg)
    assert (e.leap_valid, e.clk_reset, e.measurements) == (False, True, [])


def test_gps_time_to_utc_subtracts_leap_seconds():
    # GPS week 2268, TOW 226350 s (Wednesday 14:52:30 GPS) is 14:52:12 UTC with 18 leap seconds
    assert ubx.gps_to_utc(2268, 3 * 86400 + 14 * 3600 + 52 * 60 + 30, 18) == dt.datetime(2023, 6, 28, 14, 52, 12,
                                                                                          tzinfo=UTC)


def test_measx_time_of_week_accuracy_scale():
    """gpsTOWacc is in 2^-4 ms: 1.5 ms is 24 counts (the real log only has zeros)."""
    msg = pyubx2.UBXMessage("RXM", "RXM-MEASX", pyubx2.GET, version=1, gpsTOW=436762000, gloTOW=447544000,
                            bdsTOW=436748000, qzssTOW=436762000, gpsTOWacc=1.5, numSv=0, towSet=1)
    x = _decode(msg)
    assert x.gps_tow_acc_s == pytest.approx(1.5e-3) and x.tow_set == 1 and x.satellites == []
    assert (x.gps_tow_s, x.glo_tow_s, x.bds_tow_s, x.qzss_tow_s) == pytest.approx((436762.0, 447544.0, 436748.0,
                                                                                   436762.0))


@pytest.mark.parametrize("cls, mid, size, needle", [
    (0x01, 0x07, 80, "NAV-PVT payload is 80 bytes"),
    (0x01, 0x20, 20, "NAV-TIMEGPS payload is 20 bytes"),
    (0x01, 0x20, 12, "NAV-TIMEGPS payload is 12 bytes"),
    (0x05, 0x01, 3, "ACK payload is 3 bytes"),
])
def test_wrong_payload_sizes_are_errors(cls, mid, size, needle):
    with pytest.raises(ValueError, match=needle):
        ubx.decode_frame(UbxFrame(0.0, cls, mid, bytes(size)))


def test_rawx_and_measx_sizes_must_match_their_counts():
    head = bytearray(16)
    head[11] = 2                                   # numMeas = 2: 16 + 64 bytes
    with pytest.raises(ValueError, match=r"RXM-RAWX payload is 48 bytes, expected 16 \+ 32\*2"):
        ubx.decode_frame(UbxFrame(0.0, 0x02, 0x15, bytes(head) + bytes(32)))
    with pytest.raises(ValueError, match=r"RXM-RAWX payload is 112 bytes"):
        ubx.decode_frame(UbxFrame(0.0, 0x02, 0x15, bytes(head) + bytes(96)))
    head = bytearray(44)
    head[34] = 1                                   # numSV = 1: 44 + 24 bytes
    with pytest.raises(ValueError, match=r"RXM-MEASX payload is 44 bytes, expected 44 \+ 24\*1"):
        ubx.decode_frame(UbxFrame(0.0, 0x02, 0x14, bytes(head)))
