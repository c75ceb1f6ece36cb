"""GPS LNAV subframe 4 page 18 (Klobuchar coefficients) from u-blox RXM-SFRBX."""
from __future__ import annotations

import pytest

from leonav_runtime.gnss import sfrbx
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.signals import klobuchar_coefficients
from leonav_runtime.gnss.ubx_log import parse_ubx_bytes
from tests.conftest import shared_file


def _ubx(payload: bytes) -> bytes:
    body = bytes([sfrbx.SFRBX_CLASS, sfrbx.SFRBX_ID]) + len(payload).to_bytes(2, "little") + payload
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes([a, b])


@pytest.mark.parametrize("convention", ["source", "transmitted"])
def test_page_18_round_trip_through_an_sfrbx_log(convention):
    """The GEONET 0759 header's ION ALPHA/BETA, encoded into page 18 and framed as SFRBX: the
    log reader gives the same coefficients (RINEX prints them rounded to the ICD's scale)."""
    nav = read_rinex_nav(shared_file("gnss_rinex/07590920.05n"))
    coeffs = klobuchar_coefficients(nav.iono)
    words = sfrbx.encode_iono_page(coeffs, tow_count=86405, convention=convention)
    log = parse_ubx_bytes(_ubx(sfrbx.sfrbx_payload(11, words)), "synthetic.ubx", reference_week=1316)
    assert log.counts["sfrbx_iono_pages"] == 1
    got = klobuchar_coefficients(log.iono)
    for g, c, f in zip(got, coeffs, (2.0**-30, 2.0**-27, 2.0**-24, 2.0**-24, 2.0**11, 2.0**14, 2.0**16, 2.0**16)):
        assert abs(g - c) <= f / 2 + abs(c) * 5e-4  # within half an ICD count (and RINEX's 4 digits)


def test_other_subframe_4_pages_and_bad_parity_are_not_taken():
    words = sfrbx.encode_iono_page([0.0] * 8, tow_count=100)
    asm = sfrbx.LnavAssembler(reference_week=1316)
    asm.add_words(3, [words[0], words[1] ^ 0x40] + words[2:])  # one flipped data bit
    assert asm.klobuchar is None and asm.counts["parity"] == 1
