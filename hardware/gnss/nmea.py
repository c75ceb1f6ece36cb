"""NMEA 0183 sentences: checksum check, pynmea2 parsing, fixes and UTC time tags.

A sentence is `$<talker><type>,<fields>*<hh>` followed by CR LF; `hh` is the XOR of
every byte between `$` and `*`, in hex. Sentences are parsed by pynmea2 after our own
checksum check, so every rejection has a counted reason.
"""
from __future__ import annotations

import datetime as _dt
import math

import pynmea2

from leonav.hardware.records import GnssFix, GnssTimeTag, NmeaSentence

# Reasons a candidate sentence is rejected (keys of the reader's `rejected` counter).
NO_CHECKSUM = "nmea_no_checksum"
BAD_CHECKSUM = "nmea_bad_checksum"
PARSE_ERROR = "nmea_parse_error"
# Reasons a checksum-valid sentence yields no fix / time tag (its fields cannot be right).
BAD_TIME = "nmea_bad_time"      # time of day pynmea2 cannot read (hour 25, second 61, ...)
BAD_DATE = "nmea_bad_date"      # RMC/ZDA date that does not exist (day 32, month 13, ...)
BAD_FIELD = "nmea_bad_field"    # GGA quality/satellite count not an integer, latitude/longitude
                                # not a number, minutes >= 60, beyond 90/180 deg, no N/S/E/W


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
    """A finite float, or None for an empty or unreadable field."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


class BadField(ValueError):
    """A field of a checksum-valid sentence that cannot be what it says (the reason is its args[0])."""


def _nmea_angle_deg(value: str, hemisphere: str, limit_deg: float, hemispheres: str) -> float | None:
    """ddmm.mmmm / dddmm.mmmm plus N/S/E/W -> signed degrees; None when empty.

    BadField for anything a receiver cannot mean: not a number, negative, minutes >= 60,
    more than `limit_deg`, or a hemisphere letter other than `hemispheres`."""
    if not value:
        return None
    try:
        raw = float(value)
    except ValueError:
        raise BadField(BAD_FIELD) from None
    degrees = int(raw // 100) if math.isfinite(raw) else -1
    minutes = raw - 100 * degrees
    if raw < 0 or not 0 <= minutes < 60 or degrees + minutes / 60.0 > limit_deg or hemisphere not in hemispheres:
        raise BadField(BAD_FIELD)
    sign = -1.0 if hemisphere in ("S", "W") else 1.0
    return sign * (degrees + minutes / 60.0)


def time_field(msg) -> _dt.time | None:
    """`msg.timestamp` as a time, None when empty; BadField when pynmea2 could not read it
    (pynmea2 then hands back the text, e.g. hour 25 or second 61)."""
    tod = msg.timestamp          # pynmea2 parses on each access: read once
    if tod is None or tod == "":
        return None
    if not isinstance(tod, _dt.time):
        raise BadField(BAD_TIME)
    return tod


class NmeaFixBuilder:
    """Turns NMEA sentences into fixes (GGA) and UTC time tags (RMC, ZDA).

    GGA carries no date: the date of the latest RMC/ZDA is used, with a day added when
    the GGA time of day is far below the RMC one (midnight rollover).

    `time_tag` and `fix` return the derived record, None when the sentence carries none
    (another type, no fix, empty fields), or a reject reason (BAD_TIME, BAD_DATE,
    BAD_FIELD) for a checksum-valid sentence whose fields cannot be right; such a
    sentence neither changes the date nor yields a record. They never raise.
    """

    def __init__(self) -> None:
        self._date: _dt.date | None = None
        self._date_tod_s: float = 0.0

    def _set_date(self, date: _dt.date, tod: _dt.time) -> None:
        self._date = date
        self._date_tod_s = tod.hour * 3600 + tod.minute * 60 + tod.second

    def time_tag(self, s: NmeaSentence) -> GnssTimeTag | str | None:
        """UTC tag from RMC (date+time) or ZDA; updates the date used for GGA."""
        kind = s.sentence_type
        if kind != "RMC" and kind != "ZDA":
            return None
        try:
            return self._time_tag(s, kind)
        except BadField as exc:
            return str(exc.args[0])
        except (ValueError, TypeError, AttributeError, OverflowError):
            return BAD_FIELD

    def _time_tag(self, s: NmeaSentence, kind: str) -> GnssTimeTag | None:
        msg = s.msg
        tod = time_field(msg)
        if kind == "RMC":
            date = msg.datestamp
            if date is not None and date != "" and not isinstance(date, _dt.date):
                raise BadField(BAD_DATE)
        elif msg.day is not None and msg.month is not None and msg.year is not None:
            try:
                date = _dt.date(int(msg.year), int(msg.month), int(msg.day))
            except (TypeError, ValueError, OverflowError):
                raise BadField(BAD_DATE) from None
        else:
            date = None
        if not (date and tod):
            return None
        self._set_date(date, tod)
        utc = _dt.datetime.combine(date, tod).replace(tzinfo=_dt.timezone.utc)
        return GnssTimeTag(s.t_mono_s, utc, kind)

    def fix(self, s: NmeaSentence) -> GnssFix | str | None:
        """GnssFix from a GGA with a position (quality > 0), None without one, else a reason."""
        if s.sentence_type != "GGA":
            return None
        try:
            return self._fix(s)
        except BadField as exc:
            return str(exc.args[0])
        except (ValueError, TypeError, AttributeError, OverflowError):
            return BAD_FIELD

    def _fix(self, s: NmeaSentence) -> GnssFix | None:
        msg = s.msg
        try:
            quality = int(msg.gps_qual or 0)
            num_sv = int(msg.num_sats or 0)
        except (TypeError, ValueError):
            raise BadField(BAD_FIELD) from None
        if quality == 0:
            return None
        lat = _nmea_angle_deg(msg.lat, msg.lat_dir, 90.0, "NS")
        lon = _nmea_angle_deg(msg.lon, msg.lon_dir, 180.0, "EW")
        if quality < 0 or num_sv < 0:
            raise BadField(BAD_FIELD)
        tod = time_field(msg)
        if lat is None or lon is None:
            return None
        hmsl = _to_float(msg.altitude)
        sep = _to_float(msg.geo_sep)
        utc = None
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
            quality=quality, num_sv=num_sv, hdop=_to_float(msg.horizontal_dil),
        )
