"""GPS LNAV subframes and u-blox SFRBX: bit-exact round trip of the broadcast ephemerides
of the shared RINEX files (encode -> SFRBX payload -> decode), parity, week rollover."""
from __future__ import annotations

import random
import struct

import numpy as np
import pytest

from leonav.hardware.gnss import lnav
from leonav_runtime.gnss import sfrbx
from leonav.hardware.gnss.ubx import build_frame
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.ubx_log import parse_ubx_bytes
from tests.conftest import shared_file

NAVS = {"gnss_rinex/07590920.05n": 1316, "gnss_rinex/30400920.05n": 1316,
        "tle/rtklib_gnss_20121031/brdc3050.12n": 1712}
FLOAT_FIELDS = [f for sid in (1, 2, 3) for f in lnav.SUBFRAME_FIELDS[sid] if f.name not in ("toc", "toe", "aodo")]


def roundtrip(eph, reference_week, convention="source"):
    asm = sfrbx.LnavAssembler(reference_week=reference_week)
    payloads = []
    for row in eph.data:
        for words in sfrbx.encode_ephemeris(row, convention=convention):
            payloads.append(sfrbx.sfrbx_payload(int(row["prn"]), words))
    for p in payloads:
        asm.add_payload(p)
    return asm, payloads


@pytest.mark.parametrize("convention", ["source", "transmitted", "upright"])
@pytest.mark.parametrize("rel,week", NAVS.items())
def test_every_field_back_to_its_last_bit(rel, week, convention):
    eph = read_rinex_nav(shared_file(rel)).ephemerides
    asm, _ = roundtrip(eph, week, convention)
    out = asm.ephemerides()
    assert asm.counts["ephemerides"] == len(eph) == len(out)
    a, b = eph.data, out.data
    for f in FLOAT_FIELDS:
        if f.name not in a.dtype.names:
            continue
        quantized = np.array([f.value(f.quantize(float(v))) for v in a[f.name]])
        assert np.array_equal(b[f.name], quantized), f.name  # bit-exact
        # and the RINEX values sit on the ICD grid (a wrong scale or semicircle factor would not)
        counts = (a[f.name] / (np.pi if f.semicircles else 1.0)) / f.scale
        assert np.max(np.abs(counts - np.round(counts))) < 0.01, f.name
    for name in ("system", "prn", "iode", "iodc", "health", "codes_l2", "l2p_flag", "toe", "toc", "toe_sow",
                 "week", "fit_s"):
        assert np.array_equal(a[name], b[name]), name
    # transmission time: start of the subframe holding it (6 s grid)
    assert np.array_equal(b["transmit"], np.floor(a["transmit"] / 6.0) * 6.0)
    assert np.array_equal([lnav.ura_index(x) for x in a["accuracy_m"]], [lnav.ura_index(x) for x in b["accuracy_m"]])


def test_week_crossover_and_rollover():
    eph = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides
    # some 0759 records were sent in week 1316 with toe at 0 s of week 1317
    cross = (gtime.week_tow(eph["transmit"])[0] != gtime.week_tow(eph["toe"])[0])
    assert cross.sum() >= 5
    for ref in (1316 - 500, 1316 + 500):  # any reference within 512 weeks resolves the 10-bit week
        out = roundtrip(eph, ref)[0].ephemerides()
        assert np.array_equal(out["toe"], eph["toe"])
    wrong = roundtrip(eph, 1316 + 600)[0].ephemerides()  # more than 512 weeks off: one rollover off
    assert np.all(wrong["toe"] - eph["toe"] == 1024 * 604800.0)


def test_corrupted_parity_is_rejected_and_counted():
    eph = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides
    _, payloads = roundtrip(eph, 1316)
    rng = random.Random(7)
    asm = sfrbx.LnavAssembler(reference_week=1316)
    hit = set()
    for k, p in enumerate(payloads):
        if rng.random() < 0.25:
            words = list(struct.unpack_from("<10I", p, 8))
            w = rng.randrange(10)
            words[w] ^= 1 << rng.randrange(30)  # one bit error: parity always catches it
            p = p[:8] + struct.pack("<10I", *words)
            hit.add(k)
        asm.add_payload(p)
    assert asm.counts["parity"] == len(hit) > 0
    intact = len({k // 3 for k in range(len(payloads))} - {k // 3 for k in hit})
    # a record that lost a subframe may still complete with the same IODE broadcast again
    # later (one data set, so that is right); nothing else is emitted
    assert intact <= asm.counts["ephemerides"] <= intact + 5
    quantized = {(int(r["prn"]), float(r["toe"]), int(r["iode"])) for r in eph.data}
    assert all((int(r["prn"]), float(r["toe"]), int(r["iode"])) in quantized for r in asm.ephemerides().data)


def test_parity_catches_every_single_and_double_bit_error():
    words = lnav.encode_subframe(2, {"iode": 77, "sqrt_a": 2701828097, "e": 123456789}, 12345)
    assert lnav.decode_subframe(words).raw["sqrt_a"] == 2701828097
    for w in range(10):
        for b in range(30):
            bad = list(words)
            bad[w] ^= 1 << b
            with pytest.raises(lnav.LnavError):
                lnav.decode_subframe(bad, "source")
    for b1 in range(30):  # two errors in one word: Hamming distance 4 within a word
        for b2 in range(b1 + 1, 30):
            bad = list(words)
            bad[4] ^= (1 << b1) | (1 << b2)
            with pytest.raises(lnav.LnavError):
                lnav.decode_subframe(bad, "source")


def test_words_2_and_10_end_in_zero_and_bits_31_30_are_ignored():
    row = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides.data[0]
    for words in sfrbx.encode_ephemeris(row):
        assert words[1] & 0b11 == 0 and words[9] & 0b11 == 0
        assert (words[0] >> 22) == lnav.PREAMBLE
    payload = bytearray(sfrbx.sfrbx_payload(1, sfrbx.encode_ephemeris(row)[0]))
    for k in range(10):
        payload[8 + 4 * k + 3] |= 0xC0
    asm = sfrbx.LnavAssembler(reference_week=1316)
    asm.add_payload(bytes(payload))
    assert asm.counts["subframe_1"] == 1


def test_a_ubx_log_alone_gives_ephemerides():
    """SFRBX frames in a byte stream (with RAWX for the week) -> the same ephemerides."""
    eph = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides
    _, payloads = roundtrip(eph, 1316)
    stream = b"# a comment line\n" + b"".join(build_frame(0x02, 0x13, p) for p in payloads)
    log = parse_ubx_bytes(stream, "log", reference_week=1316)
    assert len(log.ephemerides) == len(eph) and log.counts["ubx_RXM-SFRBX"] == len(payloads)
    assert np.array_equal(log.ephemerides["toe"], eph["toe"])


def test_glonass_strings_of_the_m10_log_are_counted_not_decoded():
    log = parse_ubx_bytes(shared_file("ubx/gpsd/ublox-glo.log").read_bytes(), "glo")
    assert log.counts["ubx_RXM-SFRBX"] == 584 and log.counts["sfrbx_not_gps_l1ca"] == 584
    assert len(log.ephemerides) == 0


def test_ura_index_classes():
    assert [lnav.ura_index(x) for x in (0.0, 1.0, 2.0, 2.4, 2.41, 2.8, 6144.0, 1e5, float("nan"))] == \
        [0, 0, 0, 0, 1, 1, 14, 15, 15]
    assert lnav.URA_NOMINAL_M[0] == 2.0 and lnav.URA_NOMINAL_M[6] == 16.0 and lnav.URA_NOMINAL_M[7] == 32.0
