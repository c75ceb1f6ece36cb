"""GNSS byte stream -> typed records: NMEA sentences and UBX frames, interleaved.

`GnssSplitter` finds frames in arbitrary chunks of bytes (a frame may be split across
chunks); `GnssDecoder` parses them (pynmea2, UBX decoders) and derives fixes and UTC
time tags; `GnssReader` ties a byte source to the decoder as an iterator.

Nothing malformed raises: every skipped byte or rejected frame is counted in
`rejected[reason]` (reasons listed in REJECT_REASONS).
"""
from __future__ import annotations

import re
from collections import Counter
from typing import Any, Callable, Iterator

from hardware.byte_source import SourceReader
from hardware.gnss import nmea, ubx
from hardware.records import GnssFix, GnssTimeTag, NavPvt, NavTimeGps, RxmRawx, UbxFrame

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
    "ubx_bad_length": f"UBX length field > {MAX_UBX_PAYLOAD}",
    "ubx_bad_checksum": "UBX Fletcher checksum mismatch (resynchronized one byte later)",
    "ubx_decode_error": "UBX frame whose payload size does not fit its message type",
    "truncated_at_end": "bytes of an unfinished frame when the stream ended",
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
        self.rejected: Counter = Counter()

    def feed(self, data: bytes, t_mono_s: float) -> list[tuple[str, Any, float]]:
        buf = self._buf
        buf += data
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
                    break  # wait for the rest of the line
                line = bytes(buf[i:end + 1])
                i = end + 1
                if not line.isascii():
                    self.rejected["nmea_non_ascii"] += 1
                    continue
                out.append(("nmea", line, t_mono_s))
            elif byte == 0xB5:
                if n - i < 2:
                    break
                if buf[i + 1] != 0x62:
                    self.rejected["junk_bytes"] += 1
                    i += 1
                    continue
                if n - i < 6:
                    break
                length = buf[i + 4] | (buf[i + 5] << 8)
                if length > MAX_UBX_PAYLOAD:
                    self.rejected["ubx_bad_length"] += 1
                    self.rejected["junk_bytes"] += 1
                    i += 1
                    continue
                total = 8 + length
                if n - i < total:
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

    @staticmethod
    def _interruption(buf: bytearray, start: int, stop: int) -> int:
        """Index of a new '$' or UBX sync inside the sentence [start+1, stop), else -1."""
        match = _INTERRUPT.search(buf, start + 1, stop)
        return match.start() if match else -1

    def close(self) -> None:
        """End of stream: count what is left as an unfinished frame."""
        if self._buf:
            self.rejected["truncated_at_end"] += 1
            self._buf.clear()


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

    @property
    def rejected(self) -> Counter:
        return self.splitter.rejected

    def decode(self, data: bytes, t_mono_s: float) -> list:
        out: list = []
        for kind, item, t in self.splitter.feed(data, t_mono_s):
            if kind == "nmea":
                rec = nmea.parse_sentence(item, t)
                if isinstance(rec, str):
                    self.splitter.rejected[rec] += 1
                    continue
                self.counts["nmea_sentences"] += 1
                self.counts[f"nmea_{rec.sentence_type}"] += 1
                out.append(rec)
                tag = self.fixes.time_tag(rec)
                if tag:
                    out.append(tag)
                fix = self.fixes.fix(rec)
                if fix:
                    self.counts["fixes"] += 1
                    out.append(fix)
            else:
                self.counts["ubx_frames"] += 1
                self.counts[f"ubx_{item.name}"] += 1
                try:
                    rec = ubx.decode_frame(item)
                except (ValueError, OverflowError):
                    self.splitter.rejected["ubx_decode_error"] += 1
                    continue
                out.append(rec)
                out.extend(self._derived(rec))
        return out

    def _derived(self, rec) -> list:
        derived: list = []
        if isinstance(rec, NavPvt):
            if rec.utc is not None:
                derived.append(GnssTimeTag(rec.t_mono_s, rec.utc, "NAV-PVT"))
            if rec.gnss_fix_ok and rec.fix_type in (2, 3, 4) and not rec.invalid_llh:
                self.counts["fixes"] += 1
                derived.append(GnssFix(
                    t_mono_s=rec.t_mono_s, source="NAV-PVT", utc=rec.utc, lat_rad=rec.lat_rad,
                    lon_rad=rec.lon_rad, hmsl_m=rec.hmsl_m, height_m=rec.height_m,
                    quality=rec.fix_type, num_sv=rec.num_sv, hdop=None, h_acc_m=rec.h_acc_m,
                    v_acc_m=rec.v_acc_m, vel_ned_mps=rec.vel_ned_mps))
        elif isinstance(rec, RxmRawx) and rec.leap_valid:
            derived.append(GnssTimeTag(rec.t_mono_s, ubx.gps_to_utc(rec.week, rec.rcv_tow_s, rec.leap_s), "RAWX"))
        elif isinstance(rec, NavTimeGps) and rec.tow_valid and rec.week_valid and rec.leap_valid:
            derived.append(GnssTimeTag(rec.t_mono_s, ubx.gps_to_utc(rec.week, rec.itow_s + rec.ftow_s, rec.leap_s), "TIMEGPS"))
        return derived

    def close(self) -> None:
        self.splitter.close()

    def summary(self) -> dict:
        """Counts of accepted records and rejected bytes/frames per reason."""
        return {"accepted": dict(sorted(self.counts.items())), "rejected": dict(sorted(self.rejected.items()))}


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
        finally:
            self.decoder.close()

    def summary(self) -> dict:
        return self.decoder.summary() | {"bytes_read": self.source.bytes_read, "end_reason": self.end_reason}
