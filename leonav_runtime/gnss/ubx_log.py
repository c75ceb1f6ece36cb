"""A u-blox binary log (UBX, possibly mixed with NMEA and comment lines) -> observation
table (RXM-RAWX) and GPS ephemerides (RXM-SFRBX LNAV subframes), so a u-blox log alone
is enough for pseudorange positioning.

Framing and RAWX decoding are the device code's (`hardware.gnss.reader.GnssSplitter`,
`hardware.gnss.ubx.decode_rxm_rawx`); SFRBX subframes go through
`leonav_runtime.gnss.sfrbx.LnavAssembler`. The 10-bit LNAV week is resolved against the first
RAWX week in the log, else `reference_week`, else the week of today's date.
"""
from __future__ import annotations

import datetime as _dt
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from leonav_runtime.gnss import sfrbx as _sfrbx
from leonav.hardware.gnss import ubx as _ubx
from leonav.hardware.gnss.reader import GnssSplitter
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import Ephemerides
from leonav_runtime.gnss.observations import ObservationTable, rawx_to_table


@dataclass
class UbxLog:
    observations: ObservationTable
    ephemerides: Ephemerides
    counts: Counter  # frames by message name, decode errors, framing rejections
    iono: dict | None = None  # {"GPSA": alpha0..3, "GPSB": beta0..3} from the last subframe 4 page 18


def parse_ubx_bytes(data: bytes, source: str = "<bytes>", *, reference_week: int | None = None) -> UbxLog:
    splitter = GnssSplitter()
    items = splitter.feed(data, 0.0)
    splitter.close()
    counts: Counter = Counter()
    epochs = []
    sfrbx_payloads: list[tuple[bytes, str]] = []
    for kind, item, _t in items:
        if kind != "ubx":
            counts["nmea_lines"] += 1
            continue
        counts[f"ubx_{item.name}"] += 1
        if (item.msg_class, item.msg_id) == (0x02, 0x15):
            try:
                epochs.append(_ubx.decode_rxm_rawx(item))
            except ValueError:
                counts["rawx_decode_error"] += 1
        elif (item.msg_class, item.msg_id) == (_sfrbx.SFRBX_CLASS, _sfrbx.SFRBX_ID):
            sfrbx_payloads.append((item.payload, f"{source}: SFRBX #{len(sfrbx_payloads) + 1}"))
    for reason, n in splitter.rejected.items():
        counts[f"framing_{reason}"] += n
    log = ubx_records_to_log(epochs, sfrbx_payloads, source, reference_week=reference_week)
    log.counts.update(counts)
    return log


def ubx_records_to_log(epochs, sfrbx_payloads: list[tuple[bytes, str]], source: str = "", *,
                       reference_week: int | None = None) -> UbxLog:
    """Decoded RXM-RAWX epochs and RXM-SFRBX payloads (with where they were read) -> UbxLog."""
    counts: Counter = Counter()
    table = rawx_to_table(epochs, source)
    if reference_week is None:
        if epochs:
            reference_week = int(epochs[0].week)
        else:
            today = _dt.datetime.now(_dt.timezone.utc)
            reference_week = int(gtime.week_tow(gtime.utc_to_gps_seconds(today))[0])
    assembler = _sfrbx.LnavAssembler(reference_week=reference_week)
    for payload, where in sfrbx_payloads:
        assembler.add_payload(payload, where)
    eph = assembler.ephemerides()
    counts.update({f"sfrbx_{k}": v for k, v in assembler.counts.items()})
    iono = None
    if assembler.klobuchar is not None:
        iono = {"GPSA": assembler.klobuchar[:4], "GPSB": assembler.klobuchar[4:]}
    return UbxLog(table, eph, counts, iono)


def read_ubx_log(path: str | Path, *, reference_week: int | None = None) -> UbxLog:
    """Read a u-blox log file; see the module docstring."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserInputError(f"{path}: u-blox log not found") from None
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, expected a u-blox log file") from None
    return parse_ubx_bytes(data, str(path), reference_week=reference_week)
