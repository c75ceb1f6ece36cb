"""TLE fields: every decoded field against sgp4's own TLE reader on real element sets, and
edge cases from the format's definition (Alpha-5 catalogue numbers, blank and malformed
fields, column 69, the two-digit year pivot, epoch-day range, limits of inclination and
mean motion, the writer's implied-exponent rounding).

Alpha-5 (Space Force, 2020): catalogue numbers 100000-339999 are written as a letter and
four digits; the letter stands for 10..33 in order A-Z without I and O (they look like 1
and 0): A0000 = 100000, H9999 = 179999, J0000 = 180000, Z9999 = 339999.
"""
from __future__ import annotations

import datetime as dt
import math

import pytest
from sgp4.api import Satrec

from leonav_runtime.orbits import tle
from leonav_runtime.orbits.tle import TLEFieldError, decode_catalog_number, encode_catalog_number, parse_fields
from tests.conftest import shared_file

UTC = dt.timezone.utc
XPDOTP = 1440.0 / (2.0 * math.pi)   # rev/day per rad/min (sgp4's unit of mean motion)

ISS_1 = "1 25544U 98067A   08264.51782528 -.00002182  00000-0 -11606-4 0  2927"
ISS_2 = "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391563537"


def mod10(line: str) -> str:
    """Line (68 columns) plus its checksum digit: digits count their value, '-' counts 1."""
    line = line[:68]
    return line + str(sum(int(c) if c.isdigit() else c == "-" for c in line) % 10)


def entries(path, limit):
    lines = [ln.rstrip() for ln in path.read_text().splitlines()]
    out = []
    for i, ln in enumerate(lines[:-1]):
        if ln.startswith("1 ") and lines[i + 1].startswith("2 "):
            out.append((ln, lines[i + 1]))
    return out[:limit]


@pytest.mark.parametrize("name, limit", [("tle/gps-ops_2026-03-09.txt", 40), ("tle/starlink_2026-02-23.txt", 400),
                                         ("tle/starlink_supgp_2026-05-13.txt", 200),
                                         ("tle/rtklib_gnss_20121031/tle_nav.txt", 120)])
def test_every_field_matches_sgp4s_reader(name, limit):
    n_negative_bstar = n_nonzero_nddot = 0
    for l1, l2 in entries(shared_file(name), limit):
        f = parse_fields(l1, l2)
        s = Satrec.twoline2rv(l1, l2)
        assert f.norad_id == s.satnum and f.classification == s.classification
        assert f.intl_designator == s.intldesg.strip()
        assert (f.epoch_utc.year % 100, f.epoch_utc.timetuple().tm_yday) == (s.epochyr, int(s.epochdays))
        day = (f.epoch_utc - dt.datetime(f.epoch_utc.year, 1, 1, tzinfo=UTC)).total_seconds() / 86400 + 1
        assert day == pytest.approx(s.epochdays, abs=1e-9)
        assert f.ndot_revday2 == pytest.approx(s.ndot * XPDOTP * 1440.0, rel=1e-9, abs=1e-16)
        assert f.nddot_revday3 == pytest.approx(s.nddot * XPDOTP * 1440.0**2, rel=1e-9, abs=1e-20)
        assert f.bstar_per_earth_radius == pytest.approx(s.bstar, rel=1e-12, abs=1e-18)
        assert math.radians(f.inclination_deg) == pytest.approx(s.inclo, abs=1e-12)
        assert math.radians(f.raan_deg) == pytest.approx(s.nodeo, abs=1e-12)
        assert f.eccentricity == pytest.approx(s.ecco, abs=1e-15)
        assert math.radians(f.arg_perigee_deg) == pytest.approx(s.argpo, abs=1e-12)
        assert math.radians(f.mean_anomaly_deg) == pytest.approx(s.mo, abs=1e-12)
        assert f.mean_motion_revday == pytest.approx(s.no_kozai * XPDOTP, rel=1e-12)
        assert (f.element_number, f.rev_number) == (s.elnum, s.revnum)
        n_negative_bstar += f.bstar_per_earth_radius < 0
        n_nonzero_nddot += f.nddot_revday3 != 0
    assert n_negative_bstar > 0 or "gps" in name or "rtklib" in name


def test_str3_and_verification_sets_negative_exponents():
    """Spacetrack Report #3 test set and Vallado's verification TLEs (negative ndot/bstar, deep space)."""
    for name in ("sgp4/rtklib_tle_sgp4_str3.txt", "sgp4/SGP4-VER.TLE"):
        lines = [ln.rstrip() for ln in shared_file(name).read_text().splitlines() if ln[:2] in ("1 ", "2 ")]
        pairs = [(a, b) for a, b in zip(lines, lines[1:]) if a.startswith("1 ") and b.startswith("2 ")]
        checked = 0
        for l1, l2 in pairs:
            try:
                f = parse_fields(l1[:69], l2[:69], verify_checksum=False)
            except TLEFieldError:
                continue
            s = Satrec.twoline2rv(l1[:69], l2[:69])
            assert f.bstar_per_earth_radius == pytest.approx(s.bstar, rel=1e-12, abs=1e-18)
            assert f.ndot_revday2 == pytest.approx(s.ndot * XPDOTP * 1440.0, rel=1e-9, abs=1e-16)
            assert f.eccentricity == pytest.approx(s.ecco, abs=1e-15)
            checked += 1
        assert checked >= 1


@pytest.mark.parametrize("text, number", [("A0000", 100000), ("A0001", 100001), ("H9999", 179999),
                                          ("J0000", 180000), ("N5678", 225678), ("P0000", 230000),
                                          ("Z9999", 339999), ("99999", 99999), ("00005", 5), ("  123", 123)])
def test_alpha5_decoding_follows_the_definition(text, number):
    assert decode_catalog_number(text) == number
    if number >= 100000:
        assert encode_catalog_number(number) == text
        l1 = mod10(ISS_1.replace("25544", text))
        l2 = mod10(ISS_2.replace("25544", text))
        assert parse_fields(l1, l2).norad_id == number == Satrec.twoline2rv(l1, l2).satnum


def test_alpha5_encoding_round_trips_and_limits():
    for n in (0, 99999, 100000, 109999, 110000, 179999, 180000, 229999, 230000, 339999, 254321):
        text = encode_catalog_number(n)
        assert len(text) == 5 and decode_catalog_number(text) == n
    with pytest.raises(ValueError):
        encode_catalog_number(340000)


@pytest.mark.parametrize("text", ["I0001", "O1234", "A001", "A00011", "AB123", "A-123", "1A234", ""])
def test_invalid_catalogue_numbers_are_rejected(text):
    with pytest.raises(TLEFieldError, match="catalog number"):
        decode_catalog_number(text)


def _edit(line: str, first: int, text: str) -> str:
    """Replace columns first.. (1-based) with text and recompute the checksum."""
    return mod10(line[:first - 1] + text + line[first - 1 + len(text):68])


def test_reference_lines_parse():
    f = parse_fields(mod10(ISS_1), mod10(ISS_2))
    assert f.norad_id == 25544 and f.intl_designator == "98067A" and f.rev_number == 56353
    assert f.epoch_utc == dt.datetime(2008, 1, 1, tzinfo=UTC) + dt.timedelta(days=263.51782528)
    assert f.ndot_revday2 == pytest.approx(-2.182e-5) and f.bstar_per_earth_radius == pytest.approx(-1.1606e-5)
    assert f.element_number == 292


@pytest.mark.parametrize("line, first, text, which, needle", [
    (1, 34, "          ", 1, None),                        # blank ndot: written as 0 by some tools
    (2, 9, "        ", 2, "inclination"),                  # blank inclination is an error, not 0
    (2, 18, "        ", 2, "right ascension"),
    (2, 35, "        ", 2, "argument of perigee"),
    (2, 44, "        ", 2, "mean anomaly"),
    (2, 53, "           ", 2, "mean motion"),
    (2, 27, "       ", 2, "eccentricity"),
    (2, 27, "00-6703", 2, "eccentricity"),
    (1, 65, "2a2", 1, "element-set number"),
    (1, 65, " -29", 1, "element-set number"),
    (2, 64, "5-635", 2, "revolution number"),
    (2, 64, "+5635", 2, "revolution number"),
    (1, 19, "0x", 1, "epoch year"),
    (1, 54, "-11606-x", 1, "B*"),
])
def test_blank_and_malformed_fields(line, first, text, which, needle):
    l1, l2 = mod10(ISS_1), mod10(ISS_2)
    if line == 1:
        l1 = _edit(l1, first, text)
    else:
        l2 = _edit(l2, first, text)
    if needle is None:
        assert parse_fields(l1, l2).ndot_revday2 == 0.0
        return
    with pytest.raises(TLEFieldError, match=needle) as err:
        parse_fields(l1, l2)
    assert err.value.which_line == which


def test_two_digit_year_pivot_at_57():
    """Years 57-99 are 1957-1999, 00-56 are 2000-2056 (Sputnik 1 was launched in 1957)."""
    for yy, year in (("57", 1957), ("99", 1999), ("00", 2000), ("56", 2056)):
        f = parse_fields(_edit(mod10(ISS_1), 19, yy), mod10(ISS_2))
        assert f.epoch_utc.year == year


@pytest.mark.parametrize("day, ok", [("000.50000000", False), ("001.00000000", True), ("366.99999999", True),
                                     ("367.00000000", False)])
def test_epoch_day_range(day, ok):
    l1 = _edit(mod10(ISS_1), 21, day)
    if ok:
        f = parse_fields(l1, mod10(ISS_2))
        assert f.epoch_utc.year == 2008
    else:
        with pytest.raises(TLEFieldError, match="epoch day"):
            parse_fields(l1, mod10(ISS_2))


def test_inclination_and_mean_motion_limits():
    assert parse_fields(mod10(ISS_1), _edit(mod10(ISS_2), 9, "180.0000")).inclination_deg == 180.0
    assert parse_fields(mod10(ISS_1), _edit(mod10(ISS_2), 9, "  0.0000")).inclination_deg == 0.0
    with pytest.raises(TLEFieldError, match="inclination"):
        parse_fields(mod10(ISS_1), _edit(mod10(ISS_2), 9, "180.0001"))
    with pytest.raises(TLEFieldError, match="mean motion"):
        parse_fields(mod10(ISS_1), _edit(mod10(ISS_2), 53, " 0.00000000"))


def test_line_structure_checks():
    l1, l2 = mod10(ISS_1), mod10(ISS_2)
    with pytest.raises(TLEFieldError, match="wrong line number") as err:
        parse_fields(mod10("3" + l1[1:]), l2)
    assert err.value.which_line == 1
    with pytest.raises(TLEFieldError, match="catalog number mismatch"):
        parse_fields(l1, _edit(l2, 3, "25545"))
    with pytest.raises(TLEFieldError, match="70 characters long"):
        parse_fields(l1 + "X", l2)
    assert parse_fields(l1 + "   0.0  1440.0  360.0", l2).norad_id == 25544   # Vallado's start/stop/step
    with pytest.raises(TLEFieldError, match="truncated"):
        parse_fields(l1[:68], l2)
    bad = l1[:68] + str((int(l1[68]) + 1) % 10)
    with pytest.raises(TLEFieldError, match="bad checksum"):
        parse_fields(bad, l2)
    assert parse_fields(bad, l2, verify_checksum=False).norad_id == 25544


@pytest.mark.parametrize("value", [9.999996e-5, -9.999996e-5, 1.23456e-4, 0.0, 5e-9, -3.21e-1])
def test_writer_implied_exponent_round_trips(value):
    l1, l2 = tle.format_tle(norad_id=225678, epoch_utc=dt.datetime(2026, 2, 23, 6, tzinfo=UTC), inclination_deg=53.05,
                            raan_deg=10.0, eccentricity=1.5e-4, arg_perigee_deg=90.0, mean_anomaly_deg=270.0,
                            mean_motion_revday=15.06, bstar_per_earth_radius=value, nddot_revday3=value,
                            ndot_revday2=-1.234e-5)
    assert len(l1) == len(l2) == 69 and l1[2:7] == "N5678"
    f = parse_fields(l1, l2)
    s = Satrec.twoline2rv(l1, l2)
    assert f.bstar_per_earth_radius == pytest.approx(value, rel=5e-5, abs=1e-20) == s.bstar
    assert f.ndot_revday2 == pytest.approx(-1.234e-5) and f.norad_id == 225678 == s.satnum


def test_eight_character_designator_and_four_digit_element_number():
    l1 = _edit(_edit(mod10(ISS_1), 10, "98067ABC"), 65, "1234")
    f = parse_fields(l1, mod10(ISS_2))
    s = Satrec.twoline2rv(l1, mod10(ISS_2))
    assert f.intl_designator == "98067ABC" == s.intldesg and f.element_number == 1234 == s.elnum
    w1, w2 = tle.format_tle(norad_id=25544, epoch_utc=dt.datetime(2026, 1, 1, tzinfo=UTC), inclination_deg=51.6,
                            raan_deg=0.0, eccentricity=0.0, arg_perigee_deg=0.0, mean_anomaly_deg=0.0,
                            mean_motion_revday=15.5, element_number=9876, rev_number=54321, intl_designator="98067ABC")
    g = parse_fields(w1, w2)
    assert (g.element_number, g.rev_number, g.intl_designator) == (9876, 54321, "98067ABC")


@pytest.mark.parametrize("ecc", [1.0000001, -1e-7, 1.5])
def test_writer_rejects_eccentricity_outside_0_1(ecc):
    with pytest.raises(ValueError, match="eccentricity"):
        tle.format_tle(norad_id=1, epoch_utc=dt.datetime(2026, 1, 1, tzinfo=UTC), inclination_deg=10.0,
                       raan_deg=0.0, eccentricity=ecc, arg_perigee_deg=0.0, mean_anomaly_deg=0.0,
                       mean_motion_revday=15.5)
