"""Edge cases of the tightly coupled GNSS road (review of issue 10): time tags of RXM-RAWX
without a valid leapS, gross pseudoranges, rows the filter cannot take, receiver clock
jumps inside gaps, and the start of the inter-system biases."""
from __future__ import annotations

import struct

import numpy as np

from hardware.clock import TimeMap
from hardware.gnss import ubx
from hardware.gnss.reader import GnssDecoder
from hardware.records import GnssTimeTag
from leonav_runtime.gnss import time as gtime


def _rawx(t_gps_s: float, leap_s: int, leap_valid: bool) -> bytes:
    week, tow = gtime.week_tow(t_gps_s)
    return ubx.build_frame(0x02, 0x15, struct.pack("<dHbBBB2x", float(tow), int(week), leap_s, 0,
                                                   0x01 if leap_valid else 0x00, 1))


def _tags(frames: list[tuple[bytes, float]]) -> list[GnssTimeTag]:
    dec = GnssDecoder()
    out = [r for data, t in frames for r in dec.decode(data, t)] + dec.close()
    return [r for r in out if isinstance(r, GnssTimeTag)]


def test_rawx_without_valid_leap_seconds_still_tags_time_on_the_gps_scale():
    """Before: no time tag, so with no NMEA the IMU axis fell back to the host clock while the
    pseudoranges sat on GPS time. Now the leap-second table gives GPS - UTC, and the tag's UTC
    maps back to the RAWX GPS time exactly as `coupled.gps_epoch` places the pseudoranges."""
    t_gps = gtime.gps_seconds(2300, 345600.25)     # 2024-02-07: GPS - UTC = 18 s
    valid = _tags([(_rawx(t_gps, 18, True), 10.0)])
    # leapS not valid yet: the receiver's (wrong) default leapS must not be used
    unsure = _tags([(_rawx(t_gps + k, 15, False), 10.0 + k) for k in range(5)])
    assert len(valid) == 1 and len(unsure) == 5
    assert unsure[0].utc == valid[0].utc
    for k, tag in enumerate(unsure):
        assert gtime.utc_to_gps_seconds(tag.utc) == t_gps + k
    tm = TimeMap.fit(unsure)
    assert tm.valid and tm.source == "RAWX"
    assert abs(tm.to_utc_unix(10.0) - valid[0].utc.timestamp()) < 1e-6
