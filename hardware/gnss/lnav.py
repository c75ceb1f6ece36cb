"""GPS LNAV (L1 C/A navigation message) subframes 1-3: parity, decode and encode.

Written from IS-GPS-200 (20.3.2 message structure, 20.3.3.3 subframe 1, 20.3.3.4
subframes 2 and 3, 20.3.5 parity, Tables 20-I, 20-III and 20-XIV).

Words: a subframe is 10 words of 30 bits, bit 1 (first transmitted, MSB) ... bit 30. A
word here is a Python int with bit 1 at position 29; bits 1-24 carry data, 25-30 parity.
Subframe bit numbers (1..300) are the ICD's: word n holds bits 30(n-1)+1 .. 30n.

Parity (IS-GPS-200 Table 20-XIV) runs over the source data d1..d24 and the last two
parity bits D29*, D30* of the previous word. On air, data bits are sent as
D_i = d_i xor D30*. Three conventions for a stored word:
  * "source": bits 1-24 are d1..d24 (polarity removed), parity bits 25-30 as transmitted;
  * "transmitted": all 30 bits as on air (D1..D24, D25..D30);
  * "upright": all 30 bits as on air, then the whole word inverted when the previous word's
    D30 was 1, so that bits 1-24 are d1..d24 and the parity bits are inverted with them.
    This is what u-blox receivers deliver in RXM-SFRBX: on a real M8/F9 GPS frame (pyubx2's
    test log, tests/test_gnss_lnav_ublox.py) the 4 words after a D30 = 1 fail both other
    conventions and all 10 pass this one.
"auto" accepts a subframe when all its words pass in one of the conventions. Word 1 of a
subframe follows word 10 of the previous one, whose last two bits the ICD forces to 0 (the
t bits), so D29* = D30* = 0.

Scale factors, bit positions and two's complement: Tables 20-I/20-III; semicircles are
converted to radians with the ICD's pi (3.1415926535898).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from leonav_runtime.gen.constants import GPS_PI

PREAMBLE = 0x8B
WORD_MASK = (1 << 30) - 1

# Parity equations: (which of D29*/D30* enters, data bits d1..d24 that enter)
_PARITY = (
    (29, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)),
    (30, (2, 3, 4, 6, 7, 11, 12, 13, 14, 15, 18, 19, 21, 24)),
    (29, (1, 3, 4, 5, 7, 8, 12, 13, 14, 15, 16, 19, 20, 22)),
    (30, (2, 4, 5, 6, 8, 9, 13, 14, 15, 16, 17, 20, 21, 23)),
    (30, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),
    (29, (3, 5, 6, 8, 9, 10, 11, 13, 15, 19, 22, 23, 24)),
)
_MASKS = tuple((star, sum(1 << (24 - b) for b in bits)) for star, bits in _PARITY)

# URA index -> nominal URA (m), IS-GPS-200 20.3.3.3.1.3 (N <= 6: 2^(1 + N/2), else 2^(N - 2));
# upper bounds of each class for encoding a value in metres
URA_NOMINAL_M = tuple([2.0 ** (1 + n / 2) for n in range(7)] + [2.0 ** (n - 2) for n in range(7, 15)] + [math.nan])
URA_UPPER_M = (2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0, 1536.0, 3072.0, 6144.0)


class LnavError(ValueError):
    """A subframe that cannot be used (parity, preamble, subframe id); `reason` is a count key."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


def parity(data24: int, d29_star: int, d30_star: int) -> int:
    """The six parity bits D25..D30 of source data d1..d24 (as a 6-bit int, D25 first)."""
    out = 0
    for star, mask in _MASKS:
        bit = (bin(data24 & mask).count("1") + (d29_star if star == 29 else d30_star)) & 1
        out = (out << 1) | bit
    return out


def encode_word(data24: int, prev_word: int, convention: str = "source") -> int:
    """30-bit word of source data d1..d24 after `prev_word` (its D29*, D30*)."""
    d29s, d30s = (prev_word >> 1) & 1, prev_word & 1
    data24 &= 0xFFFFFF
    par = parity(data24, d29s, d30s)
    bits = data24 ^ (0xFFFFFF if (convention == "transmitted" and d30s) else 0)
    return (bits << 6) | par


def word_ok(word: int, prev_word: int, convention: str) -> tuple[bool, int]:
    """(parity passes, source data d1..d24) of a stored word under a convention."""
    word &= WORD_MASK
    d29s, d30s = (prev_word >> 1) & 1, prev_word & 1
    data = word >> 6
    if convention == "transmitted" and d30s:
        data ^= 0xFFFFFF
    return parity(data, d29s, d30s) == (word & 0x3F), data


CONVENTIONS = ("source", "transmitted", "upright")


def from_upright(words: list[int]) -> list[int]:
    """The on-air words of "upright" words (each inverted back when the D30 before it is 1)."""
    out, d30 = [], 0
    for w in words:
        w = (w ^ WORD_MASK) & WORD_MASK if d30 else w & WORD_MASK
        out.append(w)
        d30 = w & 1
    return out


def to_upright(words: list[int]) -> list[int]:
    """"upright" words of on-air words (each inverted when the D30 before it is 1)."""
    out, d30 = [], 0
    for w in words:
        out.append((w ^ WORD_MASK) & WORD_MASK if d30 else w & WORD_MASK)
        d30 = w & 1
    return out


def check_subframe(words: list[int], convention: str = "auto") -> tuple[list[int], str]:
    """Source data (10 x 24 bits) of a subframe whose 10 words all pass parity.

    Returns (data words, convention used); raises LnavError('parity' / 'preamble' / ...)."""
    if len(words) != 10:
        raise LnavError("word_count", f"{len(words)} words, expected 10")
    conventions = CONVENTIONS if convention == "auto" else (convention,)
    first_bad = None
    for conv in conventions:
        on_air = from_upright(words) if conv == "upright" else words
        rule = "transmitted" if conv == "upright" else conv
        prev = 0
        data = []
        for k, w in enumerate(on_air):
            ok, d = word_ok(w, prev, rule)
            if not ok:
                first_bad = k + 1 if first_bad is None else first_bad
                break
            data.append(d)
            prev = w & WORD_MASK
        else:
            if (data[0] >> 16) != PREAMBLE:
                raise LnavError("preamble", f"word 1 starts with 0x{data[0] >> 16:02X}, expected preamble 0x8B")
            return data, conv
    raise LnavError("parity", f"parity fails in word {first_bad}")


# ---------------------------------------------------------------- bit fields


def _get(data: list[int], start: int, nbits: int) -> int:
    """Unsigned value of subframe bits start..start+nbits-1 (ICD numbering; one word)."""
    w = (start - 1) // 30
    pos = (start - 1) % 30  # 0-based within the word; data bits are 0..23
    if pos + nbits > 24:
        raise ValueError("field crosses a parity boundary")
    return (data[w] >> (24 - pos - nbits)) & ((1 << nbits) - 1)


def _set(data: list[int], start: int, nbits: int, value: int) -> None:
    w = (start - 1) // 30
    pos = (start - 1) % 30
    if pos + nbits > 24 or value < 0 or value >= (1 << nbits):
        raise ValueError(f"value {value} does not fit {nbits} bits at bit {start}")
    shift = 24 - pos - nbits
    data[w] = (data[w] & ~(((1 << nbits) - 1) << shift)) | (value << shift)


@dataclass(frozen=True)
class Field:
    """An ICD field: parts ((start bit, n bits), MSB part first), signed, scale, semicircles."""

    name: str
    parts: tuple[tuple[int, int], ...]
    signed: bool = False
    scale: float = 1.0
    semicircles: bool = False

    @property
    def nbits(self) -> int:
        return sum(n for _, n in self.parts)

    def get_raw(self, data: list[int]) -> int:
        v = 0
        for start, n in self.parts:
            v = (v << n) | _get(data, start, n)
        if self.signed and v >= 1 << (self.nbits - 1):
            v -= 1 << self.nbits
        return v

    def set_raw(self, data: list[int], raw: int) -> None:
        nb = self.nbits
        lo, hi = (-(1 << (nb - 1)), (1 << (nb - 1)) - 1) if self.signed else (0, (1 << nb) - 1)
        if not lo <= raw <= hi:
            raise ValueError(f"{self.name}: {raw} outside the {nb}-bit {'signed' if self.signed else 'unsigned'} range")
        v = raw & ((1 << nb) - 1)
        left = nb
        for start, n in self.parts:
            left -= n
            _set(data, start, n, (v >> left) & ((1 << n) - 1))

    def value(self, raw: int) -> float:
        """Physical value (radians for semicircle fields) of a raw count."""
        v = raw * self.scale
        return v * GPS_PI if self.semicircles else v

    def quantize(self, value: float) -> int:
        """Nearest raw count of a physical value (the encoder's rounding)."""
        v = value / GPS_PI if self.semicircles else value
        return int(round(v / self.scale))


SUBFRAME_FIELDS = {
    1: (
        Field("wn", ((61, 10),)), Field("codes_l2", ((71, 2),)), Field("ura", ((73, 4),)),
        Field("health", ((77, 6),)), Field("iodc", ((83, 2), (211, 8))), Field("l2p_flag", ((91, 1),)),
        Field("tgd", ((197, 8),), True, 2.0**-31), Field("toc", ((219, 16),), False, 2.0**4),
        Field("af2", ((241, 8),), True, 2.0**-55), Field("af1", ((249, 16),), True, 2.0**-43),
        Field("af0", ((271, 22),), True, 2.0**-31),
    ),
    2: (
        Field("iode", ((61, 8),)), Field("crs", ((69, 16),), True, 2.0**-5),
        Field("delta_n", ((91, 16),), True, 2.0**-43, True), Field("m0", ((107, 8), (121, 24)), True, 2.0**-31, True),
        Field("cuc", ((151, 16),), True, 2.0**-29), Field("e", ((167, 8), (181, 24)), False, 2.0**-33),
        Field("cus", ((211, 16),), True, 2.0**-29), Field("sqrt_a", ((227, 8), (241, 24)), False, 2.0**-19),
        Field("toe", ((271, 16),), False, 2.0**4), Field("fit_flag", ((287, 1),)), Field("aodo", ((288, 5),), False, 900.0),
    ),
    3: (
        Field("cic", ((61, 16),), True, 2.0**-29), Field("omega0", ((77, 8), (91, 24)), True, 2.0**-31, True),
        Field("cis", ((121, 16),), True, 2.0**-29), Field("i0", ((137, 8), (151, 24)), True, 2.0**-31, True),
        Field("crc", ((181, 16),), True, 2.0**-5), Field("omega", ((197, 8), (211, 24)), True, 2.0**-31, True),
        Field("omega_dot", ((241, 24),), True, 2.0**-43, True), Field("iode", ((271, 8),)),
        Field("idot", ((279, 14),), True, 2.0**-43, True),
    ),
}
TLM = (Field("tlm_message", ((9, 14),)), Field("integrity", ((23, 1),)))
HOW = (Field("tow_count", ((31, 17),)), Field("alert", ((48, 1),)), Field("antispoof", ((49, 1),)),
       Field("subframe_id", ((50, 3),)))


@dataclass
class Subframe:
    """A decoded LNAV subframe: id 1..5, HOW time-of-week count (x 6 s = start of the next
    subframe), flags, and the raw counts of its fields (subframes 1-3)."""

    subframe_id: int
    tow_count: int
    alert: int
    antispoof: int
    raw: dict[str, int]
    convention: str

    def value(self, name: str) -> float:
        for f in SUBFRAME_FIELDS[self.subframe_id]:
            if f.name == name:
                return f.value(self.raw[name])
        raise KeyError(name)

    @property
    def transmit_sow(self) -> float:
        """Seconds of week at the start of this subframe (HOW count of the next one, minus 6 s)."""
        return self.tow_count * 6.0 - 6.0


def decode_subframe(words: list[int], convention: str = "auto") -> Subframe:
    """Check parity and decode one subframe (10 words of 30 bits). Raises LnavError."""
    data, conv = check_subframe(words, convention)
    how = {f.name: f.get_raw(data) for f in HOW}
    sid = how["subframe_id"]
    if not 1 <= sid <= 5:
        raise LnavError("subframe_id", f"subframe id {sid} (expected 1..5)")
    raw = {f.name: f.get_raw(data) for f in SUBFRAME_FIELDS.get(sid, ())}
    return Subframe(sid, how["tow_count"], how["alert"], how["antispoof"], raw, conv)


def _solve_t_bits(data: list[int], k: int, prev_word: int) -> None:
    """Set the two non-information bits 23-24 of data word k so that its D29 = D30 = 0."""
    for t in range(4):
        d = (data[k] & ~0x3) | t
        par = parity(d, (prev_word >> 1) & 1, prev_word & 1)
        if par & 0b11 == 0:
            data[k] = d
            return
    raise AssertionError("no t bits give D29 = D30 = 0")  # cannot happen: D29 has d24, D30 has d23


def encode_subframe(subframe_id: int, raw: dict[str, int], tow_count: int, *, tlm_message: int = 0,
                    alert: int = 0, antispoof: int = 0, convention: str = "source") -> list[int]:
    """10 words (30 bits each, parity computed) of subframe 1, 2 or 3 from raw field counts.
    Reserved bits are 0; words 2 and 10 get their t bits solved for D29 = D30 = 0."""
    data = [0] * 10
    _set(data, 1, 8, PREAMBLE)
    TLM[0].set_raw(data, tlm_message)
    HOW[0].set_raw(data, tow_count)
    HOW[1].set_raw(data, alert)
    HOW[2].set_raw(data, antispoof)
    HOW[3].set_raw(data, subframe_id)
    for f in SUBFRAME_FIELDS[subframe_id]:
        f.set_raw(data, raw.get(f.name, 0))
    words: list[int] = []
    prev = 0
    for k in range(10):
        if k in (1, 9):
            _solve_t_bits(data, k, prev)
        w = encode_word(data[k], prev, "transmitted" if convention == "upright" else convention)
        words.append(w)
        prev = w
    return to_upright(words) if convention == "upright" else words


def ura_index(accuracy_m: float) -> int:
    """URA index N whose class holds an accuracy in metres (15: unknown / > 6144 m)."""
    if not math.isfinite(accuracy_m) or accuracy_m < 0:
        return 15
    for n, upper in enumerate(URA_UPPER_M):
        if accuracy_m <= upper:
            return n
    return 15
