"""UBX configuration for u-blox generation 9/10 receivers (NEO-M10) via CFG-VALSET.

CFG-VALSET (class 0x06, id 0x8A) payload: version U1 (0, or 1 with transactions), layers X1
(bit0 RAM, bit1 BBR, bit2 Flash), transaction X1 (version 1 only), a reserved byte, then key/value pairs: key U4 (little endian) followed by
the value, whose size is coded in bits 28-30 of the key (1: one bit stored in a byte,
2: 1 byte, 3: 2 bytes, 4: 4 bytes, 5: 8 bytes). The receiver answers ACK-ACK or ACK-NAK
carrying (0x06, 0x8A).

Key IDs are those of the u-blox M10 SPG 5.10 interface description. Note: RXM-RAWX /
RXM-MEASX output needs firmware that provides raw measurements; a receiver without it
NAKs the whole VALSET, so `paper_10hz_config` sends them in a separate message.
"""
from __future__ import annotations

import struct

from leonav.hardware.gnss.ubx import build_frame

CFG_CLASS, VALSET_ID, VALGET_ID = 0x06, 0x8A, 0x8B
LAYER_RAM, LAYER_BBR, LAYER_FLASH = 0x01, 0x02, 0x04

KEYS = {
    "CFG-RATE-MEAS": 0x30210001,                 # U2, ms between measurements
    "CFG-RATE-NAV": 0x30210002,                  # U2, measurements per navigation solution
    "CFG-RATE-TIMEREF": 0x20210003,              # E1, 0 UTC, 1 GPS
    "CFG-UART1-BAUDRATE": 0x40520001,            # U4, baud
    "CFG-MSGOUT-UBX_NAV_PVT_UART1": 0x20910007,  # U1, output every n navigation epochs
    "CFG-MSGOUT-UBX_NAV_TIMEGPS_UART1": 0x20910048,
    "CFG-MSGOUT-UBX_RXM_RAWX_UART1": 0x209102A5,
    "CFG-MSGOUT-UBX_RXM_MEASX_UART1": 0x20910205,
    "CFG-MSGOUT-NMEA_ID_GGA_UART1": 0x209100BB,
    "CFG-MSGOUT-NMEA_ID_RMC_UART1": 0x209100AC,
    "CFG-MSGOUT-NMEA_ID_GSV_UART1": 0x209100C5,
}

_VALUE_FORMATS = {1: "<B", 2: "<B", 3: "<H", 4: "<I", 5: "<Q"}


def key_size_code(key: int) -> int:
    """Storage size code in bits 28-30 of a configuration key ID."""
    return (key >> 28) & 0x7


def encode_item(key: int, value: int) -> bytes:
    """Key ID (U4) followed by the value packed to the size the key declares."""
    fmt = _VALUE_FORMATS.get(key_size_code(key))
    if fmt is None:
        raise ValueError(f"key 0x{key:08X}: size code {key_size_code(key)} is not 1..5")
    return struct.pack("<I", key) + struct.pack(fmt, value)


def valset(items: dict[str | int, int], layers: int = LAYER_RAM | LAYER_BBR,
           version: int = 0, transaction: int = 0) -> bytes:
    """A complete CFG-VALSET frame for `items` (key name from KEYS or numeric ID -> value).

    version 0: applied at once; version 1 with `transaction` 1 (begin), 2 (continue),
    3 (end/apply) spreads a large set over several frames.
    """
    payload = bytearray(struct.pack("<BBBB", version, layers, transaction if version else 0, 0))
    for key, value in items.items():
        key_id = KEYS[key] if isinstance(key, str) else int(key)
        payload += encode_item(key_id, int(value))
    return build_frame(CFG_CLASS, VALSET_ID, bytes(payload))


def decode_valset(payload: bytes) -> dict[int, int]:
    """Key ID -> value of a CFG-VALSET payload (inverse of `valset`, for checks/logs)."""
    out: dict[int, int] = {}
    i = 4
    while i < len(payload):
        key = struct.unpack_from("<I", payload, i)[0]
        fmt = _VALUE_FORMATS.get(key_size_code(key))
        if fmt is None:
            raise ValueError(f"CFG-VALSET: key 0x{key:08X} at byte {i} has an invalid size code")
        out[key] = struct.unpack_from(fmt, payload, i + 4)[0]
        i += 4 + struct.calcsize(fmt)
    return out


def rate_config(meas_period_ms: int = 100, nav_rate: int = 1) -> bytes:
    """Measurement period (100 ms = 10 Hz) and one navigation solution per measurement."""
    return valset({"CFG-RATE-MEAS": meas_period_ms, "CFG-RATE-NAV": nav_rate})


def uart1_baudrate(baud: int) -> bytes:
    """Change UART1's baud rate (the ACK comes at the *old* rate, or not at all)."""
    return valset({"CFG-UART1-BAUDRATE": baud})


def paper_10hz_config(raw_measurements: bool = True) -> list[bytes]:
    """VALSET frames of the paper's setup: 10 Hz, NAV-PVT every epoch on UART1, and
    (separately, since not every M10 firmware has them) RXM-RAWX and RXM-MEASX."""
    frames = [
        rate_config(100, 1),
        valset({"CFG-MSGOUT-UBX_NAV_PVT_UART1": 1, "CFG-MSGOUT-NMEA_ID_GGA_UART1": 1,
                "CFG-MSGOUT-NMEA_ID_RMC_UART1": 1}),
    ]
    if raw_measurements:
        frames.append(valset({"CFG-MSGOUT-UBX_RXM_RAWX_UART1": 1}))
        frames.append(valset({"CFG-MSGOUT-UBX_RXM_MEASX_UART1": 1}))
    return frames
