"""Hostile bytes into the device readers: NMEA, UBX and WitMotion.

Checksum-valid sentences with impossible fields, UBX times out of range and a false UBX
sync near the end of a log used to raise out of the decoder (killing a recording thread)
or swallow the end of the log. Now each such record is counted under its reason and
decoding goes on. The seeded, bounded fuzz tests mutate the real logs of ../shared/data
(truncate, flip bytes with and without a recomputed checksum, re-chunk) and check, for
every mutant: nothing raises, every rejected candidate is counted, and the records of
the untouched prefix are the original ones.
"""
from __future__ import annotations

import dataclasses
import struct

import numpy as np
import pytest

from leonav.hardware.gnss import nmea, ubx
from leonav.hardware.gnss.reader import GnssDecoder, GnssReader
from leonav.hardware.imu.witmotion import PACKET_LEN, ImuReader, SampleGrouper, WitMotionParser
from leonav.hardware.records import GnssFix, GnssTimeTag, RxmRawx
from leonav.hardware.session_decode import decode_session
from tests.conftest import shared_file
from tests.timebox import bounded

NMEA_REASONS = ("nmea_truncated", "nmea_too_long", "nmea_non_ascii", nmea.NO_CHECKSUM, nmea.BAD_CHECKSUM,
                nmea.PARSE_ERROR, "truncated_at_end")



def sentence(body: str) -> bytes:
    """`$body*hh\\r\\n` with the right checksum."""
    return f"${body}*{nmea.nmea_checksum(body.encode()):02X}\r\n".encode()


def rtk_lines() -> list[bytes]:
    data = shared_file("nmea/gpsd/nmea-rtk.log").read_bytes()
    return [ln + b"\n" for ln in data.split(b"\n") if ln.startswith(b"$")]


def decode_all(chunks, t0: float = 0.0, close: bool = True) -> tuple[list, GnssDecoder]:
    dec = GnssDecoder()
    out = []
    for k, chunk in enumerate(chunks):
        out.extend(dec.decode(chunk, t0 + k))
    if close:
        out.extend(dec.close() or [])
    return out, dec


def keys(records) -> list[str]:
    return [repr(r) for r in records]


def contents(records) -> list[str]:
    """The records without their arrival stamps."""
    return [repr(dataclasses.replace(r, t_mono_s=0.0)) for r in records]


# ------------------------------------------------------------------ NMEA fields


GOOD_RMC = "GNRMC,132819.60,A,4134.49795459,N,09345.03431408,W,0.148,124.888,180320,11.5985,E,D"
GOOD_GGA = "GNGGA,132819.60,4134.49795459,N,09345.03431408,W,2,10,0.9,278.161,M,-31.442,M,6.6,0133"


@pytest.mark.parametrize("bad,reason", [
    (GOOD_RMC.replace("180320", "321399"), "nmea_bad_date"),          # day 32, month 13
    (GOOD_RMC.replace("132819.60", "256199.60", 1), "nmea_bad_time"),
    (GOOD_GGA.replace("132819.60", "256199.60", 1), "nmea_bad_time"),
    (GOOD_GGA.replace(",2,10,", ",2,1.0,"), "nmea_bad_field"),       # satellite count
    (GOOD_GGA.replace(",2,10,", ",x,10,"), "nmea_bad_field"),        # fix quality
    (GOOD_GGA.replace("4134.49795459", "4175.49795459"), "nmea_bad_field"),  # 75 minutes
    (GOOD_GGA.replace("4134.49795459,N", "4134.49795459,Q"), "nmea_bad_field"),
    (GOOD_GGA.replace("09345.03431408", "19345.03431408"), "nmea_bad_field"),  # 193 degrees
    (GOOD_GGA.replace("4134.49795459", "nan"), "nmea_bad_field"),
    ("GPZDA,132819.60,32,13,2020,00,00", "nmea_bad_date"),
], ids=["rmc-date", "rmc-time", "gga-time", "gga-sats", "gga-quality", "gga-minutes", "gga-hemisphere",
        "gga-lon-193", "gga-lat-nan", "zda-date"])
def test_checksum_valid_sentence_with_an_impossible_field_is_counted(bad, reason):
    # before: TypeError/ValueError/AttributeError raised out of NmeaFixBuilder (a dead recording thread)
    stream = sentence(GOOD_RMC) + sentence(bad) + sentence(GOOD_GGA) + sentence(GOOD_RMC) + sentence(GOOD_GGA)
    records, dec = decode_all([stream])
    assert dec.rejected[reason] == 1, dict(dec.rejected)
    assert dec.counts["nmea_sentences"] == 5            # the sentence itself is kept as it was sent
    assert sum(isinstance(r, GnssFix) for r in records) == 2
    assert all(r.utc is not None and r.utc.year == 2020 for r in records if isinstance(r, GnssFix))
    assert sum(isinstance(r, GnssTimeTag) for r in records) == 2


def test_a_bad_date_is_not_kept_for_the_next_fixes():
    bad = sentence(GOOD_RMC.replace("180320", "321399"))
    records, dec = decode_all([bad + sentence(GOOD_GGA)])
    fix = [r for r in records if isinstance(r, GnssFix)]
    assert len(fix) == 1 and fix[0].utc is None and dec.rejected["nmea_bad_date"] == 1


# ------------------------------------------------------------------ UBX


def _rawx(tow: float, week: int = 2048, leap: int = 18) -> bytes:
    return ubx.build_frame(0x02, 0x15, struct.pack("<dHbBBB2x", tow, week, leap, 0, 1, 1))


@pytest.mark.parametrize("tow", [1e300, float("nan"), -5.0, 7e5])
def test_rawx_time_out_of_range_is_counted_and_the_frame_kept(tow):
    # before: OverflowError / ValueError out of ubx.gps_to_utc
    records, dec = decode_all([_rawx(436762.0) + _rawx(tow) + _rawx(436763.0)])
    assert dec.rejected["ubx_bad_time"] == 1
    assert sum(isinstance(r, RxmRawx) for r in records) == 3
    assert sum(isinstance(r, GnssTimeTag) for r in records) == 2


def test_false_ubx_sync_near_the_end_does_not_swallow_the_log():
    # before: a `B5 62` with a length of 8,000 in the last 8 KB hid every frame after it
    data = shared_file("ubx/gpsd/ublox-neo-m8t.log").read_bytes()
    clean, clean_dec = decode_all([data])
    cut = data.index(b"\xb5\x62", len(data) - 6000)     # just before a real frame
    hostile = data[:cut] + b"\xb5\x62\x01\x07" + struct.pack("<H", 8000) + data[cut:]
    records, dec = decode_all([hostile[i:i + 1000] for i in range(0, len(hostile), 1000)])
    assert contents(records) == contents(clean)
    assert dec.rejected["truncated_at_end"] == clean_dec.rejected["truncated_at_end"] + 1
    assert dec.rejected["junk_bytes"] == clean_dec.rejected["junk_bytes"] + 6
    # the reader's iterator recovers the same frames
    assert contents(GnssReader(hostile)) == contents(clean)


def test_false_sync_at_the_end_of_a_recorded_session(tmp_path):
    data = shared_file("ubx/gpsd/ublox-neo-m8t.log").read_bytes()
    clean, _ = decode_all([data])
    cut = data.index(b"\xb5\x62", len(data) - 4000)
    hostile = data[:cut] + b"\xb5\x62\x02\x15\x00\x20" + data[cut:]
    (tmp_path / "gnss.raw").write_bytes(hostile)
    (tmp_path / "gnss.chunks.csv").write_text(f"t_mono_s,end_offset\n1.0,{len(hostile)}\n")
    dec = decode_session(tmp_path)
    assert contents(dec.gnss_records) == contents(clean)


# ------------------------------------------------------------------ fuzzing


def _flip(data: bytes, rng, avoid: bytes = b"") -> tuple[bytes, int]:
    out = bytearray(data)
    first = int(rng.integers(0, len(data)))
    for k in range(int(rng.integers(1, 4))):
        i = min(len(data) - 1, first + k * int(rng.integers(0, 300)))
        b = int(rng.integers(0, 256))
        out[i] = b - 1 if bytes([b]) in avoid else b
    changed = [i for i in range(len(data)) if out[i] != data[i]]
    return bytes(out), (changed[0] if changed else len(data))


def _nmea_valid_flip(data: bytes, rng) -> tuple[bytes, int]:
    """A field byte of one sentence changed and the checksum recomputed (passes the checksum)."""
    starts = [i for i in range(len(data)) if data[i] == 0x24]
    s = starts[int(rng.integers(len(starts)))]
    star = data.index(b"*", s)
    body = bytearray(data[s + 1:star])
    j = int(rng.integers(6, len(body)))
    body[j] = int(rng.choice(list(b"0123456789.,-+eENSWQx ")))
    line = b"$" + bytes(body) + b"*%02X" % nmea.nmea_checksum(bytes(body))
    mutant = data[:s] + line + data[star + 3:]
    return mutant, (s if mutant != data else len(data))


def _ubx_valid_flip(data: bytes, frames: list[tuple[int, int]], rng) -> tuple[bytes, int]:
    """Payload bytes of one UBX frame changed and its Fletcher checksum recomputed."""
    a, b = frames[int(rng.integers(len(frames)))]
    frame = bytearray(data[a:b])
    if b - a <= 8:
        return data, len(data)
    for _ in range(int(rng.integers(1, 4))):
        frame[6 + int(rng.integers(0, b - a - 8))] = int(rng.integers(0, 256))
    body = bytes(frame[2:-2])
    mutant = data[:a] + bytes(frame[:-2]) + ubx.checksum(body) + data[b:]
    return mutant, (a if mutant != data else len(data))


def _ubx_frame_spans(data: bytes) -> list[tuple[int, int]]:
    spans, i = [], 0
    while True:
        i = data.find(b"\xb5\x62", i)
        if i < 0 or i + 6 > len(data):
            return spans
        end = i + 8 + (data[i + 4] | data[i + 5] << 8)
        if end <= len(data) and ubx.checksum(data[i + 2:end - 2]) == data[end - 2:end]:
            spans.append((i, end))
            i = end
        else:
            i += 1


def _rechunk(data: bytes, rng) -> list[bytes]:
    cuts = np.sort(rng.integers(0, len(data), int(rng.integers(1, 60))))
    return [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)])]


def _check_gnss_mutant(data: bytes, mutant: bytes, offset: int, rng, nmea_only: bool) -> None:
    chunks = _rechunk(mutant, rng)
    records, dec = decode_all(chunks, close=True)
    # the same bytes in one chunk give the same records (chunking never changes decoding)
    whole, _ = decode_all([mutant])
    assert [repr(getattr(r, "msg", None)) + type(r).__name__ for r in records] == \
        [repr(getattr(r, "msg", None)) + type(r).__name__ for r in whole]
    # untouched prefix: every record complete before the first changed byte is the original's
    prefix, _ = decode_all([data[:offset]], close=False)
    assert keys(whole[:len(prefix)]) == keys(prefix)
    if nmea_only:  # every '$' became a sentence or a counted rejection
        assert mutant.count(b"$") == dec.counts["nmea_sentences"] + sum(dec.rejected[k] for k in NMEA_REASONS)


def _strip_comments(data: bytes) -> bytes:
    return b"".join(ln + b"\n" for ln in data.split(b"\n") if ln and not ln.startswith(b"#"))


def _mutants(data: bytes, n: int, rng, flip, valid_flip):
    """n (mutant, offset of the first change) in turn: truncated, a flipped byte, a flip that
    keeps the checksum valid, the original (rechunked by the check)."""
    for k in range(n):
        kind = k % 4
        if kind == 0:
            cut = int(rng.integers(0, len(data)))
            yield data[:cut], cut
        elif kind == 1:
            yield flip()
        elif kind == 2:
            yield valid_flip()
        else:
            yield data, len(data)


@pytest.mark.parametrize("name,n", [("nmea/gpsd/nmea-rtk.log", 80), ("nmea/gpsd/ublox-neo-m9n-nmea.log", 40)])
def test_fuzz_nmea_reader(name, n):
    data = _strip_comments(shared_file(name).read_bytes())[:30000]
    rng = np.random.default_rng(15)
    with bounded(20):
        for mutant, offset in _mutants(data, n, rng, lambda: _flip(data, rng, avoid=b"\xb5"),
                                       lambda: _nmea_valid_flip(data, rng)):
            _check_gnss_mutant(data, mutant, offset, rng, nmea_only=True)


@pytest.mark.parametrize("name,limit,n", [("ubx/gpsd/ublox-neo-m8t.log", 30000, 60),
                                          ("ubx/gpsd/ublox-glo.log", 20000, 40),
                                          ("ubx/gpsd/ublox-zed-f9p_hpg1.11.log", 20000, 40)])
def test_fuzz_ubx_reader(name, limit, n):
    data = shared_file(name).read_bytes()[:limit]
    spans = _ubx_frame_spans(data)
    rng = np.random.default_rng(15)
    with bounded(30):
        for mutant, offset in _mutants(data, n, rng, lambda: _flip(data, rng),
                                       lambda: _ubx_valid_flip(data, spans, rng)):
            _check_gnss_mutant(data, mutant, offset, rng, nmea_only=False)


def _imu_decode(chunks, close: bool = True):
    parser, grouper = WitMotionParser(), SampleGrouper()
    samples, packets = [], 0
    for k, chunk in enumerate(chunks):
        for p in parser.feed(chunk, float(k)):
            packets += 1
            samples.extend(grouper.push(p))
    left = len(parser._buf)
    if close:
        parser.close()
        samples.extend(grouper.flush())
    return samples, packets, parser, left


def test_fuzz_witmotion_reader():
    data = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()[:12000]
    rng = np.random.default_rng(15)
    with bounded(20):
        for k in range(90):
            kind = ("truncate", "flip", "rechunk")[k % 3]
            if kind == "truncate":
                cut = int(rng.integers(0, len(data)))
                mutant, offset = data[:cut], cut
            elif kind == "flip":
                mutant, offset = _flip(data, rng)
            else:
                mutant, offset = data, len(data)
            samples, packets, parser, left = _imu_decode(_rechunk(mutant, rng))
            # every byte is in a packet, counted as junk, or in the counted unfinished tail
            assert PACKET_LEN * packets + parser.rejected["junk_bytes"] + left == len(mutant)
            assert parser.rejected["truncated_at_end"] == (1 if left else 0) and left < PACKET_LEN
            whole, _, _, _ = _imu_decode([mutant])
            assert [(s.f_b_mps2, s.w_b_radps, s.rpy_rad) for s in whole] == \
                [(s.f_b_mps2, s.w_b_radps, s.rpy_rad) for s in samples]
            prefix, _, _, _ = _imu_decode([data[:offset]], close=False)
            assert keys(whole[:len(prefix)]) == keys(prefix)
    # the reader (iterator) yields the same samples
    assert len(list(ImuReader(data))) == len(_imu_decode([data])[0])
