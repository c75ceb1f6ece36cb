"""Typed records produced by the hardware readers.

Every record carries `t_mono_s`: the host monotonic clock (`time.monotonic()`, s) at the
moment the *last byte* of the frame/sentence/packet was read from the device. Receiver or
sensor time, where the message has one, is kept beside it in its own field.

Units: SI (m, m/s, rad, rad/s, s, Hz) unless a field name says otherwise
(`_deg`, `_c` for Celsius, `_raw` for unscaled counts, `_dbhz` for C/N0).
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from typing import Any

# ---------------------------------------------------------------- GNSS: NMEA


@dataclass
class NmeaSentence:
    """One checksum-verified NMEA 0183 sentence, parsed by pynmea2.

    `msg` is the pynmea2 object (e.g. `pynmea2.GGA`); `text` the sentence without CR/LF.
    """

    t_mono_s: float
    talker: str
    sentence_type: str
    text: str
    msg: Any = field(repr=False, compare=False, default=None)


# ---------------------------------------------------------------- GNSS: UBX


@dataclass
class UbxFrame:
    """One checksum-verified UBX frame (class, id, payload), before message decoding.

    `name` ("NAV-PVT", or "UBX-0xCC-0xII" when not listed) is given by the splitter from
    `hardware.gnss.ubx.message_name`, so this module does not import the protocol module.
    """

    t_mono_s: float
    msg_class: int
    msg_id: int
    payload: bytes = field(repr=False)
    name: str = ""


@dataclass
class UbxAck:
    """UBX-ACK-ACK (acked=True) or UBX-ACK-NAK for the message (cls, id)."""

    t_mono_s: float
    acked: bool
    acked_class: int
    acked_id: int


@dataclass
class NavPvt:
    """UBX-NAV-PVT navigation solution. Geodetic WGS84; velocity in local NED axes."""

    t_mono_s: float
    itow_s: float                 # GPS time of week of the navigation epoch
    utc: _dt.datetime | None      # UTC of the epoch (None unless date and time are valid)
    valid_date: bool
    valid_time: bool
    fully_resolved: bool
    t_acc_s: float
    fix_type: int                 # 0 none, 1 DR, 2 2D, 3 3D, 4 GNSS+DR, 5 time only
    gnss_fix_ok: bool
    carr_soln: int                # 0 none, 1 float, 2 fixed
    num_sv: int
    lat_rad: float
    lon_rad: float
    height_m: float               # above the ellipsoid
    hmsl_m: float                 # above mean sea level
    h_acc_m: float
    v_acc_m: float
    vel_ned_mps: tuple[float, float, float]
    ground_speed_mps: float
    head_mot_rad: float           # heading of motion, clockwise from North
    s_acc_mps: float
    head_acc_rad: float
    pdop: float
    invalid_llh: bool


@dataclass
class NavTimeGps:
    """UBX-NAV-TIMEGPS: GPS time of the navigation epoch."""

    t_mono_s: float
    itow_s: float
    ftow_s: float                 # fractional part, itow_s + ftow_s is the precise TOW
    week: int
    leap_s: int
    tow_valid: bool
    week_valid: bool
    leap_valid: bool
    t_acc_s: float


@dataclass
class RawxMeasurement:
    """One signal of UBX-RXM-RAWX (raw GNSS measurements)."""

    gnss_id: int                  # 0 GPS, 1 SBAS, 2 Galileo, 3 BeiDou, 5 QZSS, 6 GLONASS
    sv_id: int
    sig_id: int
    freq_id: int                  # GLONASS frequency slot + 7
    pseudorange_m: float
    carrier_phase_cyc: float
    doppler_hz: float             # positive when approaching (u-blox convention)
    cno_dbhz: int
    locktime_s: float
    pr_std_m: float
    cp_std_cyc: float
    do_std_hz: float
    pr_valid: bool
    cp_valid: bool
    half_cyc: bool
    sub_half_cyc: bool


@dataclass
class RxmRawx:
    """UBX-RXM-RAWX epoch: receiver time tag plus the measurements."""

    t_mono_s: float
    rcv_tow_s: float              # receiver local time of week (GPS time scale)
    week: int
    leap_s: int                   # GPS-UTC, valid only if leap_valid
    leap_valid: bool
    clk_reset: bool
    version: int
    measurements: list[RawxMeasurement]


@dataclass
class MeasxSatellite:
    """One satellite of UBX-RXM-MEASX."""

    gnss_id: int
    sv_id: int
    cno_dbhz: int
    mpath_indic: int
    doppler_mps: float            # pseudorange rate
    doppler_hz: float
    whole_chips: int
    frac_chips: int               # 1/1024 chip
    code_phase_ms: float
    int_code_phase_ms: int
    pseu_range_rms_err: int       # index, see the interface description


@dataclass
class RxmMeasx:
    """UBX-RXM-MEASX epoch (satellite measurements for RRLP)."""

    t_mono_s: float
    gps_tow_s: float
    glo_tow_s: float
    bds_tow_s: float
    qzss_tow_s: float
    gps_tow_acc_s: float
    tow_set: int
    satellites: list[MeasxSatellite]


@dataclass
class GnssFix:
    """A position fix from NMEA (GGA + latest RMC date) or UBX-NAV-PVT, for gnss_fix.csv."""

    t_mono_s: float
    source: str                   # "GGA" or "NAV-PVT"
    utc: _dt.datetime | None      # receiver's UTC of the fix epoch
    lat_rad: float
    lon_rad: float
    hmsl_m: float                 # height above mean sea level
    height_m: float | None        # ellipsoidal height (GGA: hMSL + geoid separation)
    quality: int                  # GGA quality, or NAV-PVT fixType
    num_sv: int
    hdop: float | None
    h_acc_m: float | None = None
    v_acc_m: float | None = None
    vel_ned_mps: tuple[float, float, float] | None = None


@dataclass
class GnssTimeTag:
    """A pairing of host arrival time and the receiver's UTC for the same message."""

    t_mono_s: float
    utc: _dt.datetime
    source: str                   # "NAV-PVT", "RMC", "ZDA", "RAWX", "TIMEGPS"


# ---------------------------------------------------------------- IMU


@dataclass
class WitPacket:
    """One checksum-verified WitMotion 11-byte packet, decoded to physical units.

    `kind` is the type byte (0x50 time, 0x51 acc, 0x52 gyro, 0x53 angle, 0x54 mag,
    0x59 quaternion, others kept raw). `values` holds the decoded numbers (see
    `hardware.imu.witmotion.decode_packet`), `raw` the four int16 of the payload.
    """

    t_mono_s: float
    kind: int
    values: tuple
    raw: tuple[int, int, int, int]


@dataclass
class ImuSample:
    """One WitMotion output cycle grouped into a filter input, body frame FLU.

    WitMotion axes are X forward, Y left, Z up (datasheet sec. 3.3), which is leonav's
    forward-left-up body frame, so no axis change is applied.
    `t_mono_s` is the arrival of the acceleration packet (the first of the cycle).
    """

    t_mono_s: float
    f_b_mps2: tuple[float, float, float]      # specific force (reads +g up when level)
    w_b_radps: tuple[float, float, float]     # angular rate
    rpy_rad: tuple[float, float, float]       # roll, pitch, yaw (Z-Y-X) from the sensor's AHRS
    temperature_c: float
    mag_raw: tuple[int, int, int] | None = None
    q_wxyz: tuple[float, float, float, float] | None = None
    device_time: _dt.datetime | None = None
