"""NMEA 0183 sentences: checksum check, pynmea2 parsing, fixes and UTC time tags.

A sentence is `$<talker><type>,<fields>*<hh>` followed by CR LF; `hh` is the XOR of
every byte between `$` and `*`, in hex. Sentences are parsed by pynmea2 after our own
checksum check, so every rejection has a counted reason.
"""
from __future__ import annotations

import datetime as _dt
import math

import pynmea2

from hardware.records import GnssFix, GnssTimeTag, NmeaSentence

# Reasons a candidate sentence is rejected (keys of the reader's `rejected` counter).
NO_CHECKSUM = "nmea_no_checksum"
BAD_CHECKSUM = "nmea_bad_checksum"
PARSE_ERROR = "nmea_parse_error"


def nmea_checksum(body: bytes) -> int:
    """XOR of the bytes between '$' and '*'."""
    value = 0
    for byte in body:
        value ^= byte
    return value


def parse_sentence(line: bytes, t_mono_s: float) -> NmeaSentence | str:
    """Parse one sentence (`$...*hh`, CR/LF optional). Returns the record or a reject reason."""
    text = line.rstrip(b"\r\n")
    star = text.rfind(b"*")
    if star < 0 or len(text) - star != 3:
        return NO_CHECKSUM
    try:
        int(text[star + 1:], 16)
    except ValueError:
        return NO_CHECKSUM
    try:
        decoded = text.decode("ascii")
        msg = pynmea2.parse(decoded, check=True)   # verifies the checksum (XOR, see above)
    except pynmea2.ChecksumError:
        return BAD_CHECKSUM
    except (pynmea2.ParseError, UnicodeDecodeError, ValueError, TypeError, AttributeError):
        return PARSE_ERROR
    talker = getattr(msg, "talker", "") or ""
    sentence_type = getattr(msg, "sentence_type", "") or type(msg).__name__
    return NmeaSentence(t_mono_s, talker, sentence_type, decoded, msg)


def _to_float(value) -> float | None:
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _nmea_angle_deg(value: str, hemisphere: str) -> float | None:
    """ddmm.mmmm / dddmm.mmmm plus N/S/E/W -> signed degrees."""
    if not value:
        return None
    raw = float(value)
    degrees = int(raw // 100)
    minutes = raw - 100 * degrees
    sign = -1.0 if hemisphere in ("S", "W") else 1.0
    return sign * (degrees + minutes / 60.0)


class NmeaFixBuilder:
    """Turns NMEA sentences into fixes (GGA) and UTC time tags (RMC, ZDA).

    GGA carries no date: the date of the latest RMC/ZDA is used, with a day added when
    the GGA time of day is far below the RMC one (midnight rollover).
    """

    def __init__(self) -> None:
        self._date: _dt.date | None = None
        self._date_tod_s: float = 0.0

    def _set_date(self, date: _dt.date, tod: _dt.time) -> None:
        self._date = date
        self._date_tod_s = tod.hour * 3600 + tod.minute * 60 + tod.second

    def time_tag(self, s: NmeaSentence) -> GnssTimeTag | None:
        """UTC tag from RMC (date+time) or ZDA; updates the date used for GGA."""
        msg = s.msg
        kind = s.sentence_type
        if kind != "RMC" and kind != "ZDA":
            return None
        try:
            tod = msg.timestamp          # pynmea2 parses on each access: read once
            if kind == "RMC":
                date = msg.datestamp
            elif msg.day and msg.month and msg.year:
                date = _dt.date(int(msg.year), int(msg.month), int(msg.day))
            else:
                date = None
            if date and tod:
                self._set_date(date, tod)
                utc = _dt.datetime.combine(date, tod).replace(tzinfo=_dt.timezone.utc)
                return GnssTimeTag(s.t_mono_s, utc, kind)
        except (ValueError, TypeError, AttributeError):
            return None
        return None

    def fix(self, s: NmeaSentence) -> GnssFix | None:
        """GnssFix from a GGA with a position (quality > 0), else None."""
        if s.sentence_type != "GGA":
            return None
        msg = s.msg
        try:
            quality = int(msg.gps_qual or 0)
            if quality == 0:
                return None
            lat = _nmea_angle_deg(msg.lat, msg.lat_dir)
            lon = _nmea_angle_deg(msg.lon, msg.lon_dir)
        except (ValueError, TypeError):
            return None
        if quality == 0 or lat is None or lon is None:
            return None
        hmsl = _to_float(msg.altitude)
        sep = _to_float(msg.geo_sep)
        utc = None
        tod = msg.timestamp
        if self._date is not None and tod is not None:
            date = self._date
            if self._date_tod_s - (tod.hour * 3600 + tod.minute * 60 + tod.second) > 43200:
                date = date + _dt.timedelta(days=1)
            utc = _dt.datetime.combine(date, tod).replace(tzinfo=_dt.timezone.utc)
        deg = math.pi / 180.0
        return GnssFix(
            t_mono_s=s.t_mono_s, source="GGA", utc=utc, lat_rad=lat * deg, lon_rad=lon * deg,
            hmsl_m=hmsl if hmsl is not None else math.nan,
            height_m=(hmsl + sep) if (hmsl is not None and sep is not None) else None,
            quality=quality, num_sv=int(msg.num_sats or 0), hdop=_to_float(msg.horizontal_dil),
        )
