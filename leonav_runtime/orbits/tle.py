"""Two-line element (TLE / 3LE) text: validation, field decoding and writing.

The fixed-column layout is the NORAD/CelesTrak one (columns are 1-based below):

line 1: 1 NNNNNC IIIIIIII YYDDD.DDDDDDDD +.NNNNNNNN +NNNNN-N +NNNNN-N E SSSSK
line 2: 2 NNNNN III.IIII RRR.RRRR EEEEEEE AAA.AAAA MMM.MMMM NN.NNNNNNNNRRRRRK

Each line is checked here (length, checksum, line number, numeric fields, catalog number
agreement); the SGP4 record itself is built by `sgp4.api.Satrec.twoline2rv`, the
reference implementation of the same layout. Text beyond column 69 is ignored when it is
separated by white space (Vallado's verification file puts start/stop/step there).
"""
from __future__ import annotations

import datetime as _dt
import re
from dataclasses import dataclass

TLE_LINE_LENGTH = 69

# A line that starts "<digit 1-9> <5 catalog characters>" is an element line; anything
# else that is not blank or a '#' comment is a name line (the first line of a 3LE entry;
# Space-Track writes it as "0 NAME").
_ELEMENT_LINE = re.compile(r"^[1-9] [ 0-9A-Z]{5}")

_ALPHA5_LETTERS = "ABCDEFGHJKLMNPQRSTUVWXYZ"  # I and O are not used (look like 1 and 0)


class TLEFieldError(ValueError):
    """One element line failed a check; the message says which field and why.

    `which_line` is 1 or 2 (the element line at fault), 0 when unknown.
    """

    def __init__(self, message: str, which_line: int = 0) -> None:
        super().__init__(message)
        self.which_line = which_line


@dataclass(frozen=True)
class TLEFields:
    """Decoded fields of one entry (angles in degrees, as written in the TLE)."""

    norad_id: int
    classification: str
    intl_designator: str
    epoch_utc: _dt.datetime
    ndot_revday2: float  # first derivative of mean motion / 2, rev/day^2
    nddot_revday3: float  # second derivative / 6, rev/day^3
    bstar_per_earth_radius: float
    inclination_deg: float
    raan_deg: float
    eccentricity: float
    arg_perigee_deg: float
    mean_anomaly_deg: float
    mean_motion_revday: float  # Kozai mean motion, rev/day
    element_number: int
    rev_number: int


def is_element_line(line: str) -> bool:
    """True when `line` looks like a TLE data line (line number, blank, catalog)."""
    return bool(_ELEMENT_LINE.match(line))


# byte -> what it adds to the checksum: a digit its value, '-' one, anything else nothing (one
# C-level translate + sum per line instead of a Python loop over 68 characters: a 9,500-set
# Starlink file is parsed at every start of `leonav beacons`)
_CHECKSUM_WEIGHTS = bytearray(256)
for _digit in range(10):
    _CHECKSUM_WEIGHTS[ord("0") + _digit] = _digit
_CHECKSUM_WEIGHTS[ord("-")] = 1
_CHECKSUM_WEIGHTS = bytes(_CHECKSUM_WEIGHTS)


def checksum(line: str) -> int:
    """Mod-10 checksum of columns 1-68: digits count their value, '-' counts 1 (a character
    outside ASCII counts nothing)."""
    return sum(line[: TLE_LINE_LENGTH - 1].encode("ascii", "replace").translate(_CHECKSUM_WEIGHTS)) % 10


def decode_catalog_number(text: str) -> int:
    """NORAD catalog number from columns 3-7, including the Alpha-5 form (A0001 = 100001)."""
    text = text.strip()
    if not text:
        raise TLEFieldError("empty catalog number (columns 3-7)")
    if text[0].isalpha():
        letter = text[0].upper()
        if letter not in _ALPHA5_LETTERS or not text[1:].isdigit() or len(text) != 5:
            raise TLEFieldError(f"catalog number {text!r} (columns 3-7) is neither 5 digits nor Alpha-5")
        return (10 + _ALPHA5_LETTERS.index(letter)) * 10000 + int(text[1:])
    if not text.isdigit():
        raise TLEFieldError(f"catalog number {text!r} (columns 3-7) is not numeric")
    return int(text)


def encode_catalog_number(norad_id: int) -> str:
    """Five characters for columns 3-7; Alpha-5 above 99999 (up to 339999)."""
    if 0 <= norad_id <= 99999:
        return f"{norad_id:05d}"
    if norad_id <= 339999:
        return _ALPHA5_LETTERS[norad_id // 10000 - 10] + f"{norad_id % 10000:04d}"
    raise ValueError(f"NORAD id {norad_id} does not fit the 5-character (Alpha-5) field")


def _field(line: str, first: int, last: int) -> str:
    return line[first - 1:last]


def _float(line: str, first: int, last: int, name: str, *, blank_is_zero: bool = False) -> float:
    text = _field(line, first, last).strip()
    if not text and blank_is_zero:
        return 0.0
    try:
        return float(text.replace(" ", ""))
    except ValueError:
        raise TLEFieldError(f"non-numeric field {name} (columns {first}-{last}): {text!r}") from None


def _int(line: str, first: int, last: int, name: str) -> int:
    text = _field(line, first, last).strip()
    if not text:
        return 0
    if not text.isdigit():
        raise TLEFieldError(f"non-numeric field {name} (columns {first}-{last}): {text!r}")
    return int(text)


def _implied_exponent(line: str, first: int, last: int, name: str) -> float:
    """Fields like ' 61711-4' meaning 0.61711e-4 (implied leading decimal point)."""
    raw = _field(line, first, last)
    text = raw.replace(" ", "")
    if not text:
        return 0.0
    match = re.fullmatch(r"([+-]?)(\d{1,5})([+-]\d)?", text)
    if not match:
        # Some writers put an explicit point or plain decimal: accept what float() takes.
        try:
            return float(text)
        except ValueError:
            raise TLEFieldError(f"non-numeric field {name} (columns {first}-{last}): {raw.strip()!r}") from None
    sign, digits, exponent = match.groups()
    value = float(f"0.{digits}") * (10.0 ** int(exponent or "+0"))
    return -value if sign == "-" else value


def check_line(line: str, expected_number: int, *, verify_checksum: bool = True) -> str:
    """Return the 69 significant columns of an element line or raise TLEFieldError."""
    try:
        return _check_line(line, expected_number, verify_checksum)
    except TLEFieldError as exc:
        exc.which_line = expected_number
        raise


def _check_line(line: str, expected_number: int, verify_checksum: bool) -> str:
    if len(line) < TLE_LINE_LENGTH:
        raise TLEFieldError(
            f"truncated line {expected_number}: {len(line)} characters, expected {TLE_LINE_LENGTH}"
        )
    if len(line) > TLE_LINE_LENGTH and not line[TLE_LINE_LENGTH].isspace():
        raise TLEFieldError(
            f"line {expected_number} is {len(line)} characters long, expected {TLE_LINE_LENGTH}"
        )
    line = line[:TLE_LINE_LENGTH]
    if line[0] != str(expected_number):
        raise TLEFieldError(f"wrong line number {line[0]!r}, expected {expected_number}")
    if not line[TLE_LINE_LENGTH - 1].isdigit():
        raise TLEFieldError(f"line {expected_number} column 69 (checksum) is {line[-1]!r}, not a digit")
    computed = checksum(line)
    if verify_checksum and computed != int(line[-1]):
        raise TLEFieldError(
            f"bad checksum on line {expected_number}: column 69 says {line[-1]}, the mod-10 sum of "
            f"columns 1-68 is {computed}"
        )
    return line


def parse_epoch(line1: str) -> _dt.datetime:
    """Epoch (columns 19-32: two-digit year, day of year with fraction) as UTC datetime."""
    year = _int(line1, 19, 20, "epoch year")
    day = _float(line1, 21, 32, "epoch day")
    if not 1.0 <= day < 367.0:
        raise TLEFieldError(f"epoch day {day} (columns 21-32) outside 1..366")
    year += 1900 if year >= 57 else 2000
    start = _dt.datetime(year, 1, 1, tzinfo=_dt.timezone.utc)
    return start + _dt.timedelta(days=day - 1.0)


def parse_fields(line1: str, line2: str, *, verify_checksum: bool = True) -> TLEFields:
    """Check both lines and decode every field. Raises TLEFieldError naming the problem."""
    line1 = check_line(line1, 1, verify_checksum=verify_checksum)
    line2 = check_line(line2, 2, verify_checksum=verify_checksum)
    try:
        norad1 = decode_catalog_number(_field(line1, 3, 7))
        line1_values = dict(
            norad_id=norad1,
            classification=line1[7],
            intl_designator=_field(line1, 10, 17).strip(),
            epoch_utc=parse_epoch(line1),
            ndot_revday2=_float(line1, 34, 43, "mean-motion derivative", blank_is_zero=True),
            nddot_revday3=_implied_exponent(line1, 45, 52, "mean-motion second derivative"),
            bstar_per_earth_radius=_implied_exponent(line1, 54, 61, "B*"),
            element_number=_int(line1, 65, 68, "element-set number"),
        )
    except TLEFieldError as exc:
        exc.which_line = 1
        raise
    try:
        norad2 = decode_catalog_number(_field(line2, 3, 7))
        if norad1 != norad2:
            raise TLEFieldError(f"catalog number mismatch: line 1 has {norad1}, line 2 has {norad2}")
        fields = TLEFields(
            **line1_values,
            inclination_deg=_float(line2, 9, 16, "inclination"),
            raan_deg=_float(line2, 18, 25, "right ascension of the ascending node"),
            eccentricity=_eccentricity(line2),
            arg_perigee_deg=_float(line2, 35, 42, "argument of perigee"),
            mean_anomaly_deg=_float(line2, 44, 51, "mean anomaly"),
            mean_motion_revday=_float(line2, 53, 63, "mean motion"),
            rev_number=_int(line2, 64, 68, "revolution number"),
        )
    except TLEFieldError as exc:
        exc.which_line = 2
        raise
    if not 0.0 <= fields.inclination_deg <= 180.0:
        raise TLEFieldError(f"inclination {fields.inclination_deg} deg (columns 9-16) outside 0..180", 2)
    if fields.mean_motion_revday <= 0.0:
        raise TLEFieldError(f"mean motion {fields.mean_motion_revday} rev/day (columns 53-63) must be > 0", 2)
    return fields


def _eccentricity(line2: str) -> float:
    """Columns 27-33: seven digits with an implied leading '0.'."""
    text = _field(line2, 27, 33).strip()
    if not text.isdigit():
        raise TLEFieldError(
            f"non-numeric field eccentricity (columns 27-33, digits with implied '0.'): {text!r}"
        )
    return int(text) * 1e-7


# --------------------------------------------------------------------------- writing


def _format_implied_exponent(value: float) -> str:
    """8 characters: sign, 5 mantissa digits, exponent sign and digit (0.61711e-4 -> ' 61711-4')."""
    if value == 0.0:
        return " 00000+0"
    sign = "-" if value < 0 else " "
    mantissa, exponent = abs(value), 0
    while mantissa >= 1.0:
        mantissa /= 10.0
        exponent += 1
    while mantissa < 0.1:
        mantissa *= 10.0
        exponent -= 1
    digits = round(mantissa * 1e5)
    if digits >= 100000:  # rounding carried into a new digit
        digits //= 10
        exponent += 1
    if not -9 <= exponent <= 9:
        raise ValueError(f"{value} does not fit the TLE exponent field")
    return f"{sign}{digits:05d}{'-' if exponent < 0 else '+'}{abs(exponent)}"


def _format_ndot(value: float) -> str:
    if abs(value) >= 1.0:
        raise ValueError(f"mean-motion derivative {value} does not fit columns 34-43")
    text = f"{abs(value):.8f}"[1:]  # '.00001514'
    return ("-" if value < 0 else " ") + text


def format_tle(
    *,
    norad_id: int,
    epoch_utc: _dt.datetime,
    inclination_deg: float,
    raan_deg: float,
    eccentricity: float,
    arg_perigee_deg: float,
    mean_anomaly_deg: float,
    mean_motion_revday: float,
    bstar_per_earth_radius: float = 0.0,
    ndot_revday2: float = 0.0,
    nddot_revday3: float = 0.0,
    intl_designator: str = "",
    classification: str = "U",
    element_number: int = 999,
    rev_number: int = 0,
) -> tuple[str, str]:
    """Write the two element lines with correct mod-10 checksums.

    The epoch is written to 1e-8 day (0.864 ms), the TLE's resolution.
    """
    epoch = epoch_utc.astimezone(_dt.timezone.utc)
    start = _dt.datetime(epoch.year, 1, 1, tzinfo=_dt.timezone.utc)
    day = 1.0 + (epoch - start).total_seconds() / 86400.0
    catalog = encode_catalog_number(norad_id)
    line1 = (
        f"1 {catalog}{classification[:1] or 'U'} {intl_designator:<8.8s} {epoch.year % 100:02d}"
        f"{day:012.8f} {_format_ndot(ndot_revday2)} {_format_implied_exponent(nddot_revday3)} "
        f"{_format_implied_exponent(bstar_per_earth_radius)} 0 {element_number % 10000:4d}"
    )
    ecc_digits = round(eccentricity * 1e7)
    if not 0 <= ecc_digits <= 9999999:
        raise ValueError(f"eccentricity {eccentricity} outside 0..1")
    line2 = (
        f"2 {catalog} {inclination_deg % 360.0 if inclination_deg > 180 else inclination_deg:8.4f} "
        f"{raan_deg % 360.0:8.4f} {ecc_digits:07d} {arg_perigee_deg % 360.0:8.4f} "
        f"{mean_anomaly_deg % 360.0:8.4f} {mean_motion_revday:11.8f}{rev_number % 100000:5d}"
    )
    for line in (line1, line2):
        if len(line) != TLE_LINE_LENGTH - 1:
            raise ValueError(f"internal: formatted TLE line has {len(line)} columns: {line!r}")
    return line1 + str(checksum(line1)), line2 + str(checksum(line2))
