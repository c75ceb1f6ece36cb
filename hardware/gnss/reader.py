"""GNSS byte stream -> typed records: NMEA sentences and UBX frames, interleaved.

`GnssSplitter` finds frames in arbitrary chunks of bytes (a frame may be split across
chunks); `GnssDecoder` parses them (pynmea2, UBX decoders) and derives fixes and UTC
time tags; `GnssReader` ties a byte source to the decoder as an iterator.

Nothing malformed raises: every skipped byte or rejected frame is counted in
`rejected[reason]` (reasons listed in REJECT_REASONS). A frame that still makes a decoder
raise (a bug) is counted too (`*_internal_error`, the first message in `summary()`), so a
recording thread never dies from the bytes it reads. At the end of a stream, `close()`
returns the frames that were waiting behind a false UBX sync whose length ran past the end.
"""
from __future__ import annotations

import math
import re
import struct
from collections import Counter
from typing import Any, Callable, Iterator

from leonav.hardware.byte_source import SourceReader
from leonav.hardware.gnss import nmea, ubx
from leonav.hardware.gnss.leap import leap_seconds_at_gps
from leonav.hardware.records import GnssFix, GnssTimeTag, NavPvt, NavTimeGps, RxmRawx, UbxFrame

MAX_NMEA_BYTES = 200      # NMEA says 82; u-blox proprietary and NMEA 4.1 lines stay far below 200
MAX_UBX_PAYLOAD = 8192    # largest u-blox output (RAWX with ~100 signals) is ~3.2 kB
_START = re.compile(rb"[$\xb5]")
_INTERRUPT = re.compile(rb"\$|\xb5\x62")

REJECT_REASONS = {
    "junk_bytes": "bytes outside any NMEA sentence or UBX frame (noise, other protocols, log comments)",
    "nmea_truncated": "a sentence cut short by the start of another frame",
    "nmea_too_long": f"no line end within {MAX_NMEA_BYTES} bytes of a '$'",
    "nmea_non_ascii": "a byte >= 0x80 inside a sentence",
    nmea.NO_CHECKSUM: "no '*hh' checksum at the end of the sentence",
    nmea.BAD_CHECKSUM: "checksum mismatch",
    nmea.PARSE_ERROR: "valid checksum but pynmea2 cannot parse the fields",
    nmea.BAD_TIME: "valid sentence whose time of day cannot be read (no fix / time tag derived)",
    nmea.BAD_DATE: "valid RMC/ZDA whose date does not exist (no time tag; the date is not kept for GGA)",
    nmea.BAD_FIELD: "valid GGA whose quality, satellite count or position cannot be right (no fix)",
    "nmea_internal_error": "a sentence that made the decoder raise (a leonav bug; see summary()['first_error'])",
    "ubx_bad_length": f"UBX length field > {MAX_UBX_PAYLOAD}",
    "ubx_bad_checksum": "UBX Fletcher checksum mismatch (resynchronized one byte later)",
    "ubx_decode_error": "UBX frame whose payload size does not fit its message type",
    "ubx_bad_time": "UBX GPS week/time of week outside a week or not finite (no time tag derived)",
    "ubx_bad_position": "NAV-PVT fix with a latitude beyond 90 deg or a longitude beyond 180 deg (no fix)",
    "ubx_internal_error": "a frame that made the decoder raise (a leonav bug; see summary()['first_error'])",
    "truncated_at_end": "a frame still unfinished when the stream ended (its first byte is junk and the "
                        "rest is searched again, so a false sync never hides the frames behind it)",
}


class GnssSplitter:
    """Splits a byte stream into complete NMEA lines and checksum-valid UBX frames.

    feed() returns `(kind, payload, t_mono_s)` items: ("nmea", line_bytes, t) or
    ("ubx", UbxFrame, t). A frame's stamp is the stamp of the chunk holding its last byte.
    A bad UBX checksum advances the search by one byte only, so a false sync inside
    binary data never swallows the real frames after it.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._t_last = float("nan")
        self.rejected: Counter = Counter()

    def feed(self, data: bytes, t_mono_s: float, final: bool = False) -> list[tuple[str, Any, float]]:
        """Items completed by `data`; `final`: no more bytes will come (see `close`)."""
        buf = self._buf
        buf += data
        self._t_last = t_mono_s
        out: list[tuple[str, Any, float]] = []
        n = len(buf)
        i = 0
        while i < n:
            byte = buf[i]
            if byte == 0x24:  # '$'
                end = buf.find(b"\n", i, i + MAX_NMEA_BYTES)
                interrupt = self._interruption(buf, i, end if end >= 0 else min(n, i + MAX_NMEA_BYTES))
                if interrupt >= 0:
                    self.rejected["nmea_truncated"] += 1
                    i = interrupt
                    continue
                if end < 0:
                    if n - i >= MAX_NMEA_BYTES:
                        self.rejected["nmea_too_long"] += 1
                        i += 1
                        continue
                    if final:
                        i = self._unfinished(i)
                        continue
                    break  # wait for the rest of the line
                line = bytes(buf[i:end + 1])
                i = end + 1
                if not line.isascii():
                    self.rejected["nmea_non_ascii"] += 1
                    continue
                out.append(("nmea", line, t_mono_s))
            elif byte == 0xB5:
                if n - i < 2 or (buf[i + 1] == 0x62 and n - i < 6):
                    if final:
                        i = self._unfinished(i)
                        continue
                    break
                if buf[i + 1] != 0x62:
                    self.rejected["junk_bytes"] += 1
                    i += 1
                    continue
                length = buf[i + 4] | (buf[i + 5] << 8)
                if length > MAX_UBX_PAYLOAD:
                    self.rejected["ubx_bad_length"] += 1
                    self.rejected["junk_bytes"] += 1
                    i += 1
                    continue
                total = 8 + length
                if n - i < total:
                    if final:  # a false sync whose length runs past the end: search on one byte later
                        i = self._unfinished(i)
                        continue
                    break
                body = bytes(buf[i + 2:i + 6 + length])
                if ubx.checksum(body) != bytes(buf[i + 6 + length:i + total]):
                    self.rejected["ubx_bad_checksum"] += 1
                    self.rejected["junk_bytes"] += 1
                    i += 1
                    continue
                frame = UbxFrame(t_mono_s, body[0], body[1], body[4:], ubx.message_name(body[0], body[1]))
                out.append(("ubx", frame, t_mono_s))
                i += total
            else:
                match = _START.search(buf, i)
                nxt = match.start() if match else n
                self.rejected["junk_bytes"] += nxt - i
                i = nxt
        del buf[:i]
        return out

    def _unfinished(self, i: int) -> int:
        """End of stream inside a candidate at i: count it, skip its first byte."""
        self.rejected["truncated_at_end"] += 1
        self.rejected["junk_bytes"] += 1
        return i + 1

    @staticmethod
    def _interruption(buf: bytearray, start: int, stop: int) -> int:
        """Index of a new '$' or UBX sync inside the sentence [start+1, stop), else -1."""
        match = _INTERRUPT.search(buf, start + 1, stop)
        return match.start() if match else -1

    def close(self) -> list[tuple[str, Any, float]]:
        """End of stream: every unfinished candidate is counted (`truncated_at_end`) and
        skipped by one byte, and the rest is split again; returns the items found there
        (frames a false sync had held back), stamped with the last chunk's stamp."""
        out = self.feed(b"", self._t_last, final=True) if self._buf else []
        self._buf.clear()
        return out


class GnssDecoder:
    """Parses split frames into records and keeps the counts.

    `decode(chunk, t)` returns the records of this chunk, in stream order:
    NmeaSentence, UbxFrame or its decoded type (NavPvt, RxmRawx, RxmMeasx, UbxAck,
    NavTimeGps), plus derived GnssFix (after GGA / NAV-PVT) and GnssTimeTag records.
    """

    def __init__(self) -> None:
        self.splitter = GnssSplitter()
        self.fixes = nmea.NmeaFixBuilder()
        self.counts: Counter = Counter()
        self.first_error = ""

    @property
    def rejected(self) -> Counter:
        return self.splitter.rejected

    def decode(self, data: bytes, t_mono_s: float) -> list:
        return self._records(self.splitter.feed(data, t_mono_s))

    def _records(self, items) -> list:
        out: list = []
        for kind, item, t in items:
            try:
                out.extend(self._nmea(item, t) if kind == "nmea" else self._ubx(item))
            except Exception as exc:  # noqa: BLE001 (a bug must not end a recording: count it, go on)
                self.splitter.rejected[f"{kind}_internal_error"] += 1
                self.first_error = self.first_error or f"{type(exc).__name__}: {exc}"
        return out

    def _reject(self, reason: str) -> None:
        self.splitter.rejected[reason] += 1

    def _nmea(self, line: bytes, t: float) -> list:
        rec = nmea.parse_sentence(line, t)
        if isinstance(rec, str):
            self._reject(rec)
            return []
        self.counts["nmea_sentences"] += 1
        self.counts[f"nmea_{rec.sentence_type}"] += 1
        out = [rec]
        for derived in (self.fixes.time_tag(rec), self.fixes.fix(rec)):
            if isinstance(derived, str):
                self._reject(derived)
            elif derived is not None:
                if isinstance(derived, GnssFix):
                    self.counts["fixes"] += 1
                out.append(derived)
        return out

    def _ubx(self, item: UbxFrame) -> list:
        self.counts["ubx_frames"] += 1
        self.counts[f"ubx_{item.name}"] += 1
        try:
            rec = ubx.decode_frame(item)
        except (ValueError, OverflowError, struct.error):
            self._reject("ubx_decode_error")
            return []
        return [rec] + self._derived(rec)

    def _derived(self, rec) -> list:
        derived: list = []
        if isinstance(rec, NavPvt):
            if rec.utc is not None:
                derived.append(GnssTimeTag(rec.t_mono_s, rec.utc, "NAV-PVT"))
            fix_ok = rec.gnss_fix_ok and rec.fix_type in (2, 3, 4) and not rec.invalid_llh
            if fix_ok and not (abs(rec.lat_rad) <= math.pi / 2 and abs(rec.lon_rad) <= math.pi):
                self._reject("ubx_bad_position")
            elif fix_ok:
                self.counts["fixes"] += 1
                derived.append(GnssFix(
                    t_mono_s=rec.t_mono_s, source="NAV-PVT", utc=rec.utc, lat_rad=rec.lat_rad,
                    lon_rad=rec.lon_rad, hmsl_m=rec.hmsl_m, height_m=rec.height_m,
                    quality=rec.fix_type, num_sv=rec.num_sv, hdop=None, h_acc_m=rec.h_acc_m,
                    v_acc_m=rec.v_acc_m, vel_ned_mps=rec.vel_ned_mps))
        elif isinstance(rec, RxmRawx):
            # Without a valid leapS the receiver's GPS week/TOW still tag the epoch: GPS - UTC then
            # comes from the leap-second table, the same one that places the RAWX pseudoranges
            # on the run's axis (leonav_runtime.gnss.coupled), so IMU and pseudoranges share a clock.
            leap = rec.leap_s if rec.leap_valid else self._table_leap_s(rec.week, rec.rcv_tow_s)
            derived += self._gps_tag(rec.t_mono_s, rec.week, rec.rcv_tow_s, leap, "RAWX")
        elif isinstance(rec, NavTimeGps) and rec.tow_valid and rec.week_valid and rec.leap_valid:
            derived += self._gps_tag(rec.t_mono_s, rec.week, rec.itow_s + rec.ftow_s, rec.leap_s, "TIMEGPS")
        return derived

    def _table_leap_s(self, week: int, tow_s: float) -> int:
        """GPS - UTC (s) from the leap-second table at GPS week/TOW."""
        self.counts["rawx_leap_from_table"] += 1   # an out-of-range week/TOW is counted by _gps_tag
        return leap_seconds_at_gps(week * ubx.SECONDS_PER_WEEK + tow_s)

    def _gps_tag(self, t_mono_s: float, week: int, tow_s: float, leap_s: int, source: str) -> list:
        try:
            return [GnssTimeTag(t_mono_s, ubx.gps_to_utc(week, tow_s, leap_s), source)]
        except (ValueError, OverflowError):
            self._reject("ubx_bad_time")
            return []

    def close(self) -> list:
        """End of stream: the records of frames a false sync held back (see GnssSplitter.close)."""
        return self._records(self.splitter.close())

    def summary(self) -> dict:
        """Counts of accepted records and rejected bytes/frames per reason (and the first
        internal error's text, if a frame made a decoder raise)."""
        out = {"accepted": dict(sorted(self.counts.items())), "rejected": dict(sorted(self.rejected.items()))}
        if self.first_error:
            out["first_error"] = self.first_error
        return out


class GnssReader(SourceReader):
    """Iterator of GNSS records from a serial port, pyserial URL, file, stream or bytes.

    `GnssReader("/dev/ttyAMA0", baudrate=38400)` or `GnssReader(serial_obj)` or
    `GnssReader(open("log", "rb"))`. Records are stamped with `time.monotonic()` on
    arrival. `on_bytes(chunk, t_mono_s)` sees every raw chunk first (for raw logging).
    Iteration ends at EOF, at `stop()`, or when the device disappears (`end_reason`).
    """

    def __init__(self, port_or_stream: Any, baudrate: int = 38400,
                 on_bytes: Callable[[bytes, float], None] | None = None) -> None:
        super().__init__(port_or_stream, baudrate, on_bytes)
        self.decoder = GnssDecoder()

    def __iter__(self) -> Iterator:
        try:
            for chunk, t_mono in self.chunks():
                yield from self.decoder.decode(chunk, t_mono)
            yield from self.decoder.close()
        finally:
            self.decoder.close()

    def summary(self) -> dict:
        return self.decoder.summary() | {"bytes_read": self.source.bytes_read, "end_reason": self.end_reason}
