"""UBX binary protocol: framing, checksum and decoders for the messages leonav uses.

Frame: 0xB5 0x62, class (1), id (1), payload length (2, little endian), payload,
CK_A, CK_B (8-bit Fletcher over class..payload). All multi-byte fields little endian.
Offsets and scale factors follow the u-blox interface descriptions (M8 protocol 15+,
F9 HPG 1.1x, M10 SPG 5.10); each decoder states its payload layout.
"""
from __future__ import annotations

import datetime as _dt
import math
import struct

from leonav.hardware.records import (
    MeasxSatellite,
    NavPvt,
    NavTimeGps,
    RawxMeasurement,
    RxmMeasx,
    RxmRawx,
    UbxAck,
    UbxFrame,
)

SYNC = b"\xb5\x62"
GPS_EPOCH = _dt.datetime(1980, 1, 6, tzinfo=_dt.timezone.utc)
SECONDS_PER_WEEK = 604800.0

MESSAGE_NAMES = {
    (0x01, 0x01): "NAV-POSECEF",
    (0x01, 0x03): "NAV-STATUS",
    (0x01, 0x04): "NAV-DOP",
    (0x01, 0x06): "NAV-SOL",
    (0x01, 0x07): "NAV-PVT",
    (0x01, 0x11): "NAV-VELECEF",
    (0x01, 0x20): "NAV-TIMEGPS",
    (0x01, 0x22): "NAV-CLOCK",
    (0x01, 0x35): "NAV-SAT",
    (0x01, 0x43): "NAV-SIG",
    (0x01, 0x61): "NAV-EOE",
    (0x02, 0x13): "RXM-SFRBX",
    (0x02, 0x14): "RXM-MEASX",
    (0x02, 0x15): "RXM-RAWX",
    (0x05, 0x00): "ACK-NAK",
    (0x05, 0x01): "ACK-ACK",
    (0x06, 0x8A): "CFG-VALSET",
    (0x06, 0x8B): "CFG-VALGET",
    (0x0A, 0x04): "MON-VER",
    (0x10, 0x02): "ESF-MEAS",
    (0x10, 0x03): "ESF-RAW",
}


def message_name(msg_class: int, msg_id: int) -> str:
    """Human name like "NAV-PVT", or "UBX-0xCC-0xII" for messages not listed."""
    return MESSAGE_NAMES.get((msg_class, msg_id), f"UBX-0x{msg_class:02X}-0x{msg_id:02X}")


def checksum(body: bytes) -> bytes:
    """8-bit Fletcher checksum (CK_A, CK_B) over class, id, length and payload."""
    ck_a = ck_b = 0
    for byte in body:
        ck_a = (ck_a + byte) & 0xFF
        ck_b = (ck_b + ck_a) & 0xFF
    return bytes((ck_a, ck_b))


def build_frame(msg_class: int, msg_id: int, payload: bytes = b"") -> bytes:
    """A complete UBX frame (sync, header, payload, checksum) as bytes."""
    body = struct.pack("<BBH", msg_class, msg_id, len(payload)) + bytes(payload)
    return SYNC + body + checksum(body)


def gps_to_utc(week: int, tow_s: float, leap_s: int) -> _dt.datetime:
    """UTC datetime of GPS week/time-of-week, given GPS-UTC leap seconds.

    ValueError when the time of week is not finite or outside [-1 s, one week + 1 s] (the
    second of margin holds a receiver's rounded fractional part) or the week is negative."""
    if not (math.isfinite(tow_s) and -1.0 <= tow_s <= SECONDS_PER_WEEK + 1.0 and week >= 0):
        raise ValueError(f"GPS week {week}, time of week {tow_s!r} s: expected a week >= 0 and 0..{SECONDS_PER_WEEK:g} s")
    return GPS_EPOCH + _dt.timedelta(seconds=week * SECONDS_PER_WEEK + tow_s - leap_s)


# ------------------------------------------------------------------ decoders


def decode_nav_pvt(frame: UbxFrame) -> NavPvt:
    """UBX-NAV-PVT (0x01 0x07), 92-byte payload (84 on protocol < 15: no headVeh/mag).

    iTOW U4 ms @0; year U2 @4, month/day/hour/min/sec U1 @6..10; valid X1 @11
    (bit0 validDate, bit1 validTime, bit2 fullyResolved); tAcc U4 ns @12; nano I4 ns @16;
    fixType U1 @20; flags X1 @21 (bit0 gnssFixOK, bits6-7 carrSoln); numSV U1 @23;
    lon, lat I4 1e-7 deg @24, @28; height, hMSL I4 mm @32, @36; hAcc, vAcc U4 mm @40, @44;
    velN/E/D I4 mm/s @48..56; gSpeed I4 mm/s @60; headMot I4 1e-5 deg @64;
    sAcc U4 mm/s @68; headAcc U4 1e-5 deg @72; pDOP U2 0.01 @76; flags3 X2 @78 (bit0
    invalidLlh, protocol >= 15 only).
    """
    p = frame.payload
    if len(p) < 84:
        raise ValueError(f"NAV-PVT payload is {len(p)} bytes, expected 92 (or 84)")
    itow, year, month, day, hour, minute, sec, valid, t_acc, nano = struct.unpack_from("<IHBBBBBBIi", p, 0)
    fix_type, flags, _flags2, num_sv = struct.unpack_from("<BBBB", p, 20)
    lon, lat, height, hmsl, h_acc, v_acc = struct.unpack_from("<iiiiII", p, 24)
    vel_n, vel_e, vel_d, g_speed, head_mot, s_acc, head_acc, pdop = struct.unpack_from("<iiiiiIIH", p, 48)
    flags3 = struct.unpack_from("<H", p, 78)[0] if len(p) >= 80 else 0
    valid_date, valid_time = bool(valid & 1), bool(valid & 2)
    utc = None
    if valid_date and valid_time:
        try:
            # nano may be negative (the epoch is rounded to the second): add it as an offset.
            utc = _dt.datetime(year, month, day, hour, minute, min(sec, 59), tzinfo=_dt.timezone.utc)
            utc += _dt.timedelta(seconds=(sec - min(sec, 59)) + nano * 1e-9)
        except ValueError:
            utc = None
    deg = math.pi / 180.0
    return NavPvt(
        t_mono_s=frame.t_mono_s,
        itow_s=itow * 1e-3,
        utc=utc,
        valid_date=valid_date,
        valid_time=valid_time,
        fully_resolved=bool(valid & 4),
        t_acc_s=t_acc * 1e-9,
        fix_type=fix_type,
        gnss_fix_ok=bool(flags & 1),
        carr_soln=(flags >> 6) & 3,
        num_sv=num_sv,
        lat_rad=lat * 1e-7 * deg,
        lon_rad=lon * 1e-7 * deg,
        height_m=height * 1e-3,
        hmsl_m=hmsl * 1e-3,
        h_acc_m=h_acc * 1e-3,
        v_acc_m=v_acc * 1e-3,
        vel_ned_mps=(vel_n * 1e-3, vel_e * 1e-3, vel_d * 1e-3),
        ground_speed_mps=g_speed * 1e-3,
        head_mot_rad=head_mot * 1e-5 * deg,
        s_acc_mps=s_acc * 1e-3,
        head_acc_rad=head_acc * 1e-5 * deg,
        pdop=pdop * 0.01,
        invalid_llh=bool(flags3 & 1),
    )


def decode_nav_timegps(frame: UbxFrame) -> NavTimeGps:
    """UBX-NAV-TIMEGPS (0x01 0x20), 16 bytes: iTOW U4 ms @0, fTOW I4 ns @4, week I2 @8,
    leapS I1 @10, valid X1 @11 (bit0 towValid, bit1 weekValid, bit2 leapSValid), tAcc U4 ns @12."""
    p = frame.payload
    if len(p) != 16:
        raise ValueError(f"NAV-TIMEGPS payload is {len(p)} bytes, expected 16")
    itow, ftow, week, leap, valid, t_acc = struct.unpack("<IihbBI", p)
    return NavTimeGps(frame.t_mono_s, itow * 1e-3, ftow * 1e-9, week, leap,
                      bool(valid & 1), bool(valid & 2), bool(valid & 4), t_acc * 1e-9)


def decode_rxm_rawx(frame: UbxFrame) -> RxmRawx:
    """UBX-RXM-RAWX (0x02 0x15): 16-byte header + 32 bytes per measurement.

    Header: rcvTow R8 s @0, week U2 @8, leapS I1 @10, numMeas U1 @11, recStat X1 @12
    (bit0 leapSec valid, bit1 clkReset), version U1 @13.
    Measurement n at 16 + 32 n: prMes R8 m @0, cpMes R8 cycles @8, doMes R4 Hz @16,
    gnssId @20, svId @21, sigId @22, freqId @23 (U1), locktime U2 ms @24, cno U1 dBHz @26,
    prStdev X1 @27 (0.01*2^n m, bits 0-3), cpStdev X1 @28 (0.004*n cycles, bits 0-3),
    doStdev X1 @29 (0.002*2^n Hz, bits 0-3), trkStat X1 @30 (bit0 prValid, bit1 cpValid,
    bit2 halfCyc, bit3 subHalfCyc).
    """
    p = frame.payload
    if len(p) < 16:
        raise ValueError(f"RXM-RAWX payload is {len(p)} bytes, expected >= 16")
    rcv_tow, week, leap, num_meas, rec_stat, version = struct.unpack_from("<dHbBBB", p, 0)
    if len(p) != 16 + 32 * num_meas:
        raise ValueError(f"RXM-RAWX payload is {len(p)} bytes, expected 16 + 32*{num_meas}")
    meas = []
    for n in range(num_meas):
        (pr, cp, do, gnss_id, sv_id, sig_id, freq_id, lock_ms, cno,
         pr_sd, cp_sd, do_sd, trk) = struct.unpack_from("<ddfBBBBHBBBBB", p, 16 + 32 * n)
        meas.append(RawxMeasurement(
            gnss_id=gnss_id, sv_id=sv_id, sig_id=sig_id, freq_id=freq_id,
            pseudorange_m=pr, carrier_phase_cyc=cp, doppler_hz=do, cno_dbhz=cno,
            locktime_s=lock_ms * 1e-3,
            pr_std_m=0.01 * 2 ** (pr_sd & 0x0F),
            cp_std_cyc=0.004 * (cp_sd & 0x0F),
            do_std_hz=0.002 * 2 ** (do_sd & 0x0F),
            pr_valid=bool(trk & 1), cp_valid=bool(trk & 2),
            half_cyc=bool(trk & 4), sub_half_cyc=bool(trk & 8),
        ))
    return RxmRawx(frame.t_mono_s, rcv_tow, week, leap, bool(rec_stat & 1), bool(rec_stat & 2),
                   version, meas)


def decode_rxm_measx(frame: UbxFrame) -> RxmMeasx:
    """UBX-RXM-MEASX (0x02 0x14): 44-byte header + 24 bytes per satellite.

    Header: version U1 @0, gpsTOW/gloTOW/bdsTOW U4 ms @4/@8/@12, qzssTOW U4 ms @20,
    gpsTOWacc U2 (2^-4 ms) @24, numSV U1 @34, flags X1 @35 (bits 0-1 towSet).
    Satellite n at 44 + 24 n: gnssId @0, svId @1, cNo @2, mpathIndic @3 (U1),
    dopplerMS I4 0.04 m/s @4, dopplerHz I4 0.2 Hz @8, wholeChips U2 @12, fracChips U2 @14,
    codePhase U4 2^-21 ms @16, intCodePhase U1 ms @20, pseuRangeRMSErr U1 @21.
    """
    p = frame.payload
    if len(p) < 44:
        raise ValueError(f"RXM-MEASX payload is {len(p)} bytes, expected >= 44")
    gps_tow, glo_tow, bds_tow = struct.unpack_from("<III", p, 4)
    qzss_tow, gps_acc = struct.unpack_from("<IH", p, 20)
    num_sv, flags = struct.unpack_from("<BB", p, 34)
    if len(p) != 44 + 24 * num_sv:
        raise ValueError(f"RXM-MEASX payload is {len(p)} bytes, expected 44 + 24*{num_sv}")
    sats = []
    for n in range(num_sv):
        (gnss_id, sv_id, cno, mpath, dop_ms, dop_hz, whole, frac, code_phase, int_cp,
         rms) = struct.unpack_from("<BBBBiiHHIBB", p, 44 + 24 * n)
        sats.append(MeasxSatellite(gnss_id, sv_id, cno, mpath, dop_ms * 0.04, dop_hz * 0.2,
                                   whole, frac, code_phase * 2.0 ** -21, int_cp, rms))
    return RxmMeasx(frame.t_mono_s, gps_tow * 1e-3, glo_tow * 1e-3, bds_tow * 1e-3,
                    qzss_tow * 1e-3, gps_acc * 2.0 ** -4 * 1e-3, flags & 3, sats)


def decode_ack(frame: UbxFrame) -> UbxAck:
    """UBX-ACK-ACK (0x05 0x01) / ACK-NAK (0x05 0x00): clsID U1 @0, msgID U1 @1."""
    if len(frame.payload) != 2:
        raise ValueError(f"ACK payload is {len(frame.payload)} bytes, expected 2")
    return UbxAck(frame.t_mono_s, frame.msg_id == 0x01, frame.payload[0], frame.payload[1])


DECODERS = {
    (0x01, 0x07): decode_nav_pvt,
    (0x01, 0x20): decode_nav_timegps,
    (0x02, 0x14): decode_rxm_measx,
    (0x02, 0x15): decode_rxm_rawx,
    (0x05, 0x00): decode_ack,
    (0x05, 0x01): decode_ack,
}


def decode_frame(frame: UbxFrame):
    """Typed record for a frame with a decoder, else the frame itself.

    Raises ValueError when a known message has a payload of the wrong size.
    """
    decoder = DECODERS.get((frame.msg_class, frame.msg_id))
    return decoder(frame) if decoder else frame
