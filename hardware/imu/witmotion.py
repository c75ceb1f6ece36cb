"""WitMotion serial protocol (WT901C-TTL, BWT901CL, WT901SD): packets, samples, config.

Output packet, 11 bytes: 0x55, type, 8 payload bytes (four little-endian int16 words
for the types below), checksum = low byte of the sum of bytes 0..9.
Types and scale factors (BWT901CL datasheet v20-0707, sec. 6.1):

| type | content | decoded `values` |
|------|---------|------------------|
| 0x50 | time: YY MM DD hh mm ss, ms (u16) | (datetime,) of the sensor's clock |
| 0x51 | acc x,y,z; temperature | (ax, ay, az) m/s^2 = raw/32768*16 g; temp_c = raw/100 |
| 0x52 | angular rate x,y,z; voltage | (wx, wy, wz) rad/s from raw/32768*2000 deg/s; volt raw/100 |
| 0x53 | roll, pitch, yaw; version | (roll, pitch, yaw) rad from raw/32768*180 deg; version |
| 0x54 | magnetic x,y,z; temperature | (hx, hy, hz) raw counts; temp_c = raw/100 |
| 0x59 | quaternion q0..q3 | (q0, q1, q2, q3) = raw/32768 |

`g` is standard gravity (9.80665 m/s^2, G_MPS2) unless given: the datasheet writes
"g (9.8 m/s^2)", a 0.07 % difference that the filter's accelerometer scale absorbs.
Axes: X forward, Y left, Z up (datasheet sec. 3.3) = leonav's FLU body frame.

Config command, 5 bytes, no checksum: 0xFF 0xAA register DataL DataH.
"""
from __future__ import annotations

import datetime as _dt
import math
import struct
from collections import Counter
from typing import Any, Callable, Iterator

from leonav.hardware.byte_source import SourceReader
from leonav.hardware.records import ImuSample, WitPacket

HEADER = 0x55
PACKET_LEN = 11
G_MPS2 = 9.80665
DEG = math.pi / 180.0

TIME, ACC, GYRO, ANGLE, MAG, QUAT = 0x50, 0x51, 0x52, 0x53, 0x54, 0x59
KNOWN_TYPES = frozenset(range(0x50, 0x5B))   # 0x50..0x5A per the datasheet's RSW table
PACKET_NAMES = {TIME: "time", ACC: "acc", GYRO: "gyro", ANGLE: "angle", MAG: "mag", QUAT: "quat"}

REJECT_REASONS = {
    "junk_bytes": "bytes skipped while looking for a 0x55 header with a valid packet behind it",
    "bad_checksum": "a 0x55 + known type whose checksum byte does not match (resync 1 byte later)",
    "unknown_type": "a 0x55 followed by a type byte outside 0x50..0x5A (resync 1 byte later)",
    "incomplete_samples": "output cycles lacking one of acc/gyro/angle (dropped from imu.csv)",
    "truncated_at_end": "bytes of an unfinished packet when the stream ended",
}


def packet_checksum(first10: bytes) -> int:
    """Low byte of the sum of bytes 0..9."""
    return sum(first10) & 0xFF


def build_packet(kind: int, words: tuple[int, int, int, int]) -> bytes:
    """An 11-byte output packet from four int16 words (for tests and simulators)."""
    head = bytes((HEADER, kind)) + struct.pack("<hhhh", *words)
    return head + bytes((packet_checksum(head),))


def build_time_packet(t: _dt.datetime) -> bytes:
    """An 11-byte 0x50 time packet for `t` (year 20YY)."""
    ms = t.microsecond // 1000
    head = bytes((HEADER, TIME, t.year - 2000, t.month, t.day, t.hour, t.minute, t.second)) + struct.pack("<H", ms)
    return head + bytes((packet_checksum(head),))


def decode_packet(packet: bytes, t_mono_s: float, g_mps2: float = G_MPS2) -> WitPacket:
    """Decode one checksum-verified 11-byte packet into physical units (see module doc)."""
    kind = packet[1]
    raw = struct.unpack_from("<hhhh", packet, 2)
    if kind == ACC:
        k = 16.0 * g_mps2 / 32768.0
        values: tuple = (raw[0] * k, raw[1] * k, raw[2] * k, raw[3] / 100.0)
    elif kind == GYRO:
        k = 2000.0 / 32768.0 * DEG
        values = (raw[0] * k, raw[1] * k, raw[2] * k, raw[3] / 100.0)
    elif kind == ANGLE:
        k = 180.0 / 32768.0 * DEG
        values = (raw[0] * k, raw[1] * k, raw[2] * k, raw[3] & 0xFFFF)
    elif kind == MAG:
        values = (raw[0], raw[1], raw[2], raw[3] / 100.0)
    elif kind == QUAT:
        values = tuple(r / 32768.0 for r in raw)
    elif kind == TIME:
        yy, mo, dd, hh, mi, ss = packet[2:8]
        ms = packet[8] | (packet[9] << 8)
        try:
            values = (_dt.datetime(2000 + yy, mo, dd, hh, mi, ss, min(ms, 999) * 1000, tzinfo=_dt.timezone.utc),)
        except ValueError:
            values = (None,)   # sensor clock not set: keep the packet, no time
    else:
        values = raw
    return WitPacket(t_mono_s, kind, values, raw)


class WitMotionParser:
    """Finds checksum-valid 11-byte packets in arbitrary chunks of bytes.

    Resynchronizes after garbage: a candidate at a 0x55 is accepted only when its type
    is known and its checksum matches; otherwise the search moves on by one byte, so
    a false 0x55 inside garbage never swallows a real packet.
    """

    def __init__(self, g_mps2: float = G_MPS2) -> None:
        self._buf = bytearray()
        self.g_mps2 = g_mps2
        self.rejected: Counter = Counter()
        self.counts: Counter = Counter()

    def feed(self, data: bytes, t_mono_s: float) -> list[WitPacket]:
        buf = self._buf
        buf += data
        out: list[WitPacket] = []
        n = len(buf)
        i = 0
        while i < n:
            if buf[i] != HEADER:
                nxt = buf.find(b"\x55", i)
                nxt = n if nxt < 0 else nxt
                self.rejected["junk_bytes"] += nxt - i
                i = nxt
                continue
            if n - i < 2:
                break
            if buf[i + 1] not in KNOWN_TYPES:
                self.rejected["unknown_type"] += 1
                self.rejected["junk_bytes"] += 1
                i += 1
                continue
            if n - i < PACKET_LEN:
                break
            if (sum(buf[i:i + 10]) & 0xFF) != buf[i + 10]:
                self.rejected["bad_checksum"] += 1
                self.rejected["junk_bytes"] += 1
                i += 1
                continue
            packet = decode_packet(bytes(buf[i:i + PACKET_LEN]), t_mono_s, self.g_mps2)
            self.counts[PACKET_NAMES.get(packet.kind, f"0x{packet.kind:02X}")] += 1
            out.append(packet)
            i += PACKET_LEN
        del buf[:i]
        return out

    def close(self) -> None:
        if self._buf:
            self.rejected["truncated_at_end"] += 1
            self._buf.clear()


class SampleGrouper:
    """Groups packets of one output cycle into an ImuSample (acc + gyro + angle required).

    The sensor sends each cycle's packets back to back in ascending type order (0x50 0x51
    0x52 0x53 0x54 ...). A new cycle starts when a packet's type is not above the previous
    one's, so a lost packet never merges two cycles. Once a cycle has been closed that
    way, the set of types per cycle is known and later cycles are emitted as soon as that
    set is complete (no waiting for the next cycle); an incomplete one is emitted when the
    next cycle starts. Cycles missing acc, gyro or angle are counted in `incomplete` and
    dropped; a missing mag/quaternion/time packet only leaves that field None.
    """

    REQUIRED = (ACC, GYRO, ANGLE)

    def __init__(self) -> None:
        self._group: dict[int, WitPacket] = {}
        self._last_kind = -1
        self._cycle_types: frozenset[int] | None = None
        self.incomplete = 0

    def push(self, packet: WitPacket) -> list[ImuSample]:
        out: list[ImuSample] = []
        if self._group and packet.kind <= self._last_kind:
            self._cycle_types = frozenset(self._group) | (self._cycle_types or frozenset())
            out.extend(self._close())
        self._group[packet.kind] = packet
        self._last_kind = packet.kind
        if self._cycle_types is not None and self._cycle_types <= self._group.keys():
            out.extend(self._close())
        return out

    def flush(self) -> list[ImuSample]:
        return self._close()

    def _close(self) -> list[ImuSample]:
        group, self._group = self._group, {}
        if not group:
            return []
        if not all(k in group for k in self.REQUIRED):
            self.incomplete += 1
            return []
        acc, gyro, angle = group[ACC], group[GYRO], group[ANGLE]
        mag, quat, clock = group.get(MAG), group.get(QUAT), group.get(TIME)
        return [ImuSample(
            t_mono_s=acc.t_mono_s,
            f_b_mps2=acc.values[:3],
            w_b_radps=gyro.values[:3],
            rpy_rad=angle.values[:3],
            temperature_c=acc.values[3],
            mag_raw=tuple(mag.values[:3]) if mag else None,
            q_wxyz=tuple(quat.values) if quat else None,
            device_time=clock.values[0] if clock else None,
        )]


class ImuReader(SourceReader):
    """Iterator of ImuSample (or, with `packets=True`, WitPacket) from a WitMotion source.

    Source: serial port name/URL (opened at `baudrate`), a pyserial object, a file,
    a stream or bytes. `on_bytes(chunk, t_mono_s)` sees every raw chunk first.
    """

    def __init__(self, port_or_stream: Any, baudrate: int = 9600, packets: bool = False,
                 on_bytes: Callable[[bytes, float], None] | None = None, g_mps2: float = G_MPS2) -> None:
        super().__init__(port_or_stream, baudrate, on_bytes)
        self.parser = WitMotionParser(g_mps2)
        self.grouper = SampleGrouper()
        self.packets = packets
        self.samples = 0

    def __iter__(self) -> Iterator:
        try:
            for chunk, t_mono in self.chunks():
                for packet in self.parser.feed(chunk, t_mono):
                    if self.packets:
                        yield packet
                    else:
                        for sample in self.grouper.push(packet):
                            self.samples += 1
                            yield sample
        finally:
            self.parser.close()
        if not self.packets:
            for sample in self.grouper.flush():
                self.samples += 1
                yield sample

    def summary(self) -> dict:
        rejected = dict(self.parser.rejected)
        if self.grouper.incomplete:
            rejected["incomplete_samples"] = self.grouper.incomplete
        return {"accepted": dict(self.parser.counts) | {"samples": self.samples},
                "rejected": dict(sorted(rejected.items())),
                "bytes_read": self.source.bytes_read, "end_reason": self.end_reason}


# ------------------------------------------------------------------ configuration

REG_SAVE, REG_RSW, REG_RATE, REG_BAUD, REG_KEY = 0x00, 0x02, 0x03, 0x04, 0x69
UNLOCK_KEY = 0xB588          # written to register 0x69 before any other register (newer firmware)
RATE_CODES_HZ = {0.2: 0x01, 0.5: 0x02, 1: 0x03, 2: 0x04, 5: 0x05, 10: 0x06, 20: 0x07,
                 50: 0x08, 100: 0x09, 125: 0x0A, 200: 0x0B}
# Baud register codes of the WT901C / WT61-series protocol (the BWT901CL is fixed at 115200).
BAUD_CODES = {4800: 0x01, 9600: 0x02, 19200: 0x03, 38400: 0x04, 57600: 0x05, 115200: 0x06,
              230400: 0x07, 460800: 0x08, 921600: 0x09}


def config_command(register: int, value: int) -> bytes:
    """5-byte command 0xFF 0xAA reg L H writing the 16-bit `value` to `register`."""
    if not 0 <= value <= 0xFFFF or not 0 <= register <= 0xFF:
        raise ValueError(f"register 0x{register:X} value {value}: expected reg 0..255, value 0..65535")
    return bytes((0xFF, 0xAA, register, value & 0xFF, value >> 8))


def unlock_command() -> bytes:
    return config_command(REG_KEY, UNLOCK_KEY)


def save_command() -> bytes:
    return config_command(REG_SAVE, 0x0000)


def rate_command(rate_hz: float) -> bytes:
    """Output rate command; rate must be one of RATE_CODES_HZ."""
    if rate_hz not in RATE_CODES_HZ:
        raise ValueError(f"WitMotion rate {rate_hz} Hz: expected one of {sorted(RATE_CODES_HZ)}")
    return config_command(REG_RATE, RATE_CODES_HZ[rate_hz])


def baud_command(baud: int) -> bytes:
    if baud not in BAUD_CODES:
        raise ValueError(f"WitMotion baud {baud}: expected one of {sorted(BAUD_CODES)}")
    return config_command(REG_BAUD, BAUD_CODES[baud])


def content_command(kinds: tuple[int, ...] = (ACC, GYRO, ANGLE, MAG)) -> bytes:
    """Select the output packets (RSW register: bit k of the 16-bit value = type 0x50+k)."""
    bits = 0
    for kind in kinds:
        bits |= 1 << (kind - TIME)
    return config_command(REG_RSW, bits)


def configure_sequence(rate_hz: float = 10, baud: int | None = None) -> list[bytes]:
    """Unlock, set rate (and baud), save: the commands sent by `leonav record --configure`."""
    cmds = [unlock_command(), rate_command(rate_hz)]
    if baud is not None:
        cmds += [unlock_command(), baud_command(baud)]
    cmds.append(save_command())
    return cmds
