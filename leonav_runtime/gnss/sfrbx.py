"""u-blox UBX-RXM-SFRBX (0x02 0x13): broadcast navigation data subframes -> ephemerides.

Payload (u-blox M8 protocol 17+, F9 HPG 1.x, M10 SPG 5.x interface descriptions):
gnssId U1 @0, svId U1 @1, sigId U1 @2 (reserved on M8), freqId U1 @3 (GLONASS slot + 7),
numWords U1 @4, chn U1 @5, version U1 @6 (0x02), reserved U1 @7, then numWords x dwrd U4
little endian @8 + 4 k. GPS L1 C/A: 10 words per subframe in transmission order, each
holding the 30-bit LNAV word right-aligned (bit 29 = the word's first bit, bit 0 its
parity bit D30); bits 31-30 are not data (ignored on decode, written as 0). The decoder
accepts the three word conventions of `hardware.gnss.lnav`: "upright" (whole words with the
polarity removed, parity bits included: what u-blox receivers deliver, measured on a real
frame), "source" and "transmitted".

`LnavAssembler` collects subframes 1-3 per satellite and emits one ephemeris row
(`leonav_runtime.gnss.ephemeris.EPH_DTYPE`) when subframe 1's IODC (8 LSBs) and the IODE
of subframes 2 and 3 agree. The 10-bit week is resolved with a reference week (a full
GPS week within 512 weeks of the data: a RAWX week of the same log, the file date, or
the processing date). Rejections are counted by reason: "parity", "preamble",
"subframe_id", "payload", "iode_mismatch", "not_gps_l1ca".

`encode_ephemeris` packs an ephemeris row into subframes 1-3 (rounding each field to
its ICD scale) and `sfrbx_payload` wraps words as an SFRBX payload: the round-trip test
of the decoder.
"""
from __future__ import annotations

import math
import struct
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from leonav.hardware.gnss import lnav
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import EPH_DTYPE, Ephemerides, default_fit_s

SFRBX_CLASS, SFRBX_ID = 0x02, 0x13
GPS_L1CA_FIT_FLAG1_S = 6 * 3600.0  # fit flag 1: "more than 4 hours"; the shortest such interval (6 h) is used


@dataclass
class SfrbxFrame:
    gnss_id: int
    sv_id: int
    sig_id: int
    freq_id: int
    chn: int
    version: int
    words: list[int]


def parse_sfrbx_payload(payload: bytes) -> SfrbxFrame:
    """SFRBX payload -> fields and dwrds; ValueError when the size does not fit numWords."""
    if len(payload) < 8:
        raise ValueError(f"RXM-SFRBX payload is {len(payload)} bytes, expected >= 8")
    gnss_id, sv_id, sig_id, freq_id, num_words, chn, version, _ = struct.unpack_from("<8B", payload, 0)
    if len(payload) != 8 + 4 * num_words:
        raise ValueError(f"RXM-SFRBX payload is {len(payload)} bytes, expected 8 + 4*{num_words}")
    words = list(struct.unpack_from(f"<{num_words}I", payload, 8))
    return SfrbxFrame(gnss_id, sv_id, sig_id, freq_id, chn, version, words)


def sfrbx_payload(sv_id: int, words: list[int], *, gnss_id: int = 0, sig_id: int = 0, freq_id: int = 0,
                  chn: int = 0, version: int = 2) -> bytes:
    """SFRBX payload of one subframe (30-bit words right-aligned in U4, bits 31-30 zero)."""
    return struct.pack("<8B", gnss_id, sv_id, sig_id, freq_id, len(words), chn, version, 0) + \
        struct.pack(f"<{len(words)}I", *[w & lnav.WORD_MASK for w in words])


# ---------------------------------------------------------------- decode to ephemerides


# Subframe 4 page 18 (SV ID 56): ionospheric and UTC data, IS-GPS-200 20.3.3.5.1 and
# Figure 20-1 sheet 8 / Table 20-X: alpha_n (s/semicircle^n), beta_n (s/semicircle^n), signed.
IONO_PAGE_SV_ID = 56
IONO_FIELDS = (
    lnav.Field("data_id", ((61, 2),)), lnav.Field("sv_id", ((63, 6),)),
    lnav.Field("alpha0", ((69, 8),), True, 2.0**-30), lnav.Field("alpha1", ((77, 8),), True, 2.0**-27),
    lnav.Field("alpha2", ((91, 8),), True, 2.0**-24), lnav.Field("alpha3", ((99, 8),), True, 2.0**-24),
    lnav.Field("beta0", ((107, 8),), True, 2.0**11), lnav.Field("beta1", ((121, 8),), True, 2.0**14),
    lnav.Field("beta2", ((129, 8),), True, 2.0**16), lnav.Field("beta3", ((137, 8),), True, 2.0**16),
)
KLOBUCHAR_NAMES = ("alpha0", "alpha1", "alpha2", "alpha3", "beta0", "beta1", "beta2", "beta3")


def decode_iono_page(data: list[int]) -> tuple[float, ...] | None:
    """Klobuchar alpha0..3, beta0..3 of subframe 4 data words (10 x 24 bits) if the page is
    page 18 (SV ID 56), else None."""
    raw = {f.name: f.get_raw(data) for f in IONO_FIELDS}
    if raw["sv_id"] != IONO_PAGE_SV_ID:
        return None
    fields = {f.name: f for f in IONO_FIELDS}
    return tuple(fields[n].value(raw[n]) for n in KLOBUCHAR_NAMES)


def encode_iono_page(coefficients, tow_count: int, *, convention: str = "source") -> list[int]:
    """10 words of a subframe 4 page 18 carrying Klobuchar coefficients (other fields 0):
    the round-trip test of `decode_iono_page`. Coefficients are rounded to the ICD scale."""
    data = [0] * 10
    lnav.Field("preamble", ((1, 8),)).set_raw(data, lnav.PREAMBLE)
    lnav.HOW[0].set_raw(data, tow_count)
    lnav.HOW[3].set_raw(data, 4)
    fields = {f.name: f for f in IONO_FIELDS}
    fields["data_id"].set_raw(data, 1)
    fields["sv_id"].set_raw(data, IONO_PAGE_SV_ID)
    for name, value in zip(KLOBUCHAR_NAMES, coefficients):
        fields[name].set_raw(data, fields[name].quantize(value))
    words, prev = [], 0
    for k in range(10):
        if k in (1, 9):  # non-information bits 23-24 of words 2 and 10: D29 = D30 = 0
            for t in range(4):
                d = (data[k] & ~0x3) | t
                if lnav.parity(d, (prev >> 1) & 1, prev & 1) & 0b11 == 0:
                    data[k] = d
                    break
        w = lnav.encode_word(data[k], prev, "transmitted" if convention == "upright" else convention)
        words.append(w)
        prev = w
    return lnav.to_upright(words) if convention == "upright" else words


@dataclass
class LnavAssembler:
    """Subframes 1-3 of each GPS satellite -> ephemeris rows (`ephemerides()`); subframe 4
    page 18 -> the latest Klobuchar coefficients (`klobuchar`, alpha0..3 beta0..3)."""

    reference_week: int
    convention: str = "auto"
    counts: Counter = field(default_factory=Counter)
    klobuchar: tuple[float, ...] | None = None
    _pending: dict[int, dict[int, lnav.Subframe]] = field(default_factory=dict)
    _rows: list = field(default_factory=list)
    _sources: list[str] = field(default_factory=list)

    def add_payload(self, payload: bytes, where: str = "") -> None:
        try:
            frame = parse_sfrbx_payload(payload)
        except ValueError:
            self.counts["payload"] += 1
            return
        if frame.gnss_id != 0 or frame.sig_id != 0 or len(frame.words) != 10:
            self.counts["not_gps_l1ca"] += 1
            return
        self.add_words(frame.sv_id, frame.words, where)

    def add_words(self, prn: int, words: list[int], where: str = "") -> None:
        try:
            sf = lnav.decode_subframe([w & lnav.WORD_MASK for w in words], self.convention)
        except lnav.LnavError as exc:
            self.counts[exc.reason] += 1
            return
        self.counts[f"subframe_{sf.subframe_id}"] += 1
        if sf.subframe_id == 4:
            data, _ = lnav.check_subframe([w & lnav.WORD_MASK for w in words], sf.convention)
            coeffs = decode_iono_page(data)
            if coeffs is not None:
                self.klobuchar = coeffs
                self.counts["iono_pages"] += 1
            return
        if sf.subframe_id > 3:
            return
        slot = self._pending.setdefault(prn, {})
        slot[sf.subframe_id] = sf
        if len(slot) == 3:
            s1, s2, s3 = slot[1], slot[2], slot[3]
            iodc8 = s1.raw["iodc"] & 0xFF
            if not (iodc8 == s2.raw["iode"] == s3.raw["iode"]):
                if sf.subframe_id == 3:
                    self.counts["iode_mismatch"] += 1
                return
            self._rows.append(self._row(prn, s1, s2, s3))
            self._sources.append(where or f"SFRBX G{prn:02d}")
            self.counts["ephemerides"] += 1
            self._pending[prn] = {}

    def _row(self, prn: int, s1: lnav.Subframe, s2: lnav.Subframe, s3: lnav.Subframe) -> np.void:
        week = gtime.resolve_week(s1.raw["wn"], self.reference_week)
        t_tx = float(gtime.gps_seconds(week, s1.transmit_sow))
        row = np.zeros((), EPH_DTYPE)
        row["system"], row["prn"] = "G", prn
        row["transmit"] = t_tx
        toe_sow = s2.value("toe")
        row["toe_sow"] = toe_sow
        row["toe"] = float(gtime.nearest_week_time(toe_sow, t_tx))
        row["week"] = int(gtime.week_tow(row["toe"])[0])  # the week that goes with toe (as in RINEX)
        row["toc"] = float(gtime.nearest_week_time(s1.value("toc"), t_tx))
        for name in ("af0", "af1", "af2", "tgd"):
            row[name] = s1.value(name)
        for name in ("crs", "delta_n", "m0", "cuc", "e", "cus", "sqrt_a"):
            row[name] = s2.value(name)
        for name in ("cic", "omega0", "cis", "i0", "crc", "omega", "omega_dot", "idot"):
            row[name] = s3.value(name)
        row["iode"] = s2.raw["iode"]
        row["iodc"] = s1.raw["iodc"]
        row["health"] = s1.raw["health"]
        row["accuracy_m"] = lnav.URA_NOMINAL_M[s1.raw["ura"]]
        row["codes_l2"] = s1.raw["codes_l2"]
        row["l2p_flag"] = s1.raw["l2p_flag"]
        row["fit_flag"] = s2.raw["fit_flag"]
        row["fit_s"] = GPS_L1CA_FIT_FLAG1_S if s2.raw["fit_flag"] else default_fit_s("G", 0.0)
        return row

    def ephemerides(self) -> Ephemerides:
        data = np.array(self._rows, dtype=EPH_DTYPE) if self._rows else np.zeros(0, EPH_DTYPE)
        return Ephemerides(data, list(self._sources), [], Counter(self.counts)).deduplicate()


# ---------------------------------------------------------------- encode (round-trip tests)


def transmit_time(row) -> float:
    """Transmission time of an ephemeris row (continuous GPS s); toe - 2 h when unknown."""
    return float(row["transmit"]) if math.isfinite(row["transmit"]) else float(row["toe"]) - 7200.0


def ephemeris_raw_counts(row) -> dict[int, dict[str, int]]:
    """Raw ICD counts of subframes 1-3 for an ephemeris row (GPS), rounded to the ICD scale.

    Raises ValueError when a value does not fit its field."""
    counts: dict[int, dict[str, int]] = {1: {}, 2: {}, 3: {}}
    t_tx = transmit_time(row)
    fit_hours = float(row["fit_s"]) / 3600.0
    specials = {
        "wn": int(gtime.week_tow(t_tx)[0]) % 1024,  # week of transmission, not of toe
        "ura": lnav.ura_index(float(row["accuracy_m"])),
        "health": int(row["health"]), "iodc": int(row["iodc"]), "codes_l2": int(row["codes_l2"]),
        "l2p_flag": int(row["l2p_flag"]), "iode": int(row["iode"]), "fit_flag": 1 if fit_hours > 4.0 else 0,
        "aodo": 0,
    }
    values = {"toc": float(gtime.week_tow(row["toc"])[1]), "toe": float(row["toe_sow"])}
    for sid, fields in lnav.SUBFRAME_FIELDS.items():
        for f in fields:
            if f.name in specials:
                raw = specials[f.name]
            else:
                value = values[f.name] if f.name in values else float(row[f.name])
                raw = f.quantize(value)
            f.set_raw([0] * 10, raw)  # range check
            counts[sid][f.name] = raw
    return counts


def encode_ephemeris(row, *, convention: str = "source", tow_count: int | None = None) -> list[list[int]]:
    """Subframes 1, 2, 3 (10 words each) broadcasting an ephemeris row.

    HOW TOW count of subframe 1 from the row's transmission time (or toe - 2 h when
    unknown), +1 and +2 for subframes 2 and 3."""
    counts = ephemeris_raw_counts(row)
    if tow_count is None:
        t_tx = transmit_time(row)
        sow = float(gtime.week_tow(t_tx)[1])
        tow_count = int(sow // 6) + 1
    return [lnav.encode_subframe(sid, counts[sid], (tow_count + sid - 1) % 100800, convention=convention)
            for sid in (1, 2, 3)]


def decode_rxm_sfrbx(frame) -> SfrbxFrame:
    """`hardware.gnss.ubx.DECODERS` entry for (0x02, 0x13): a `UbxFrame` -> `SfrbxFrame`."""
    return parse_sfrbx_payload(frame.payload)
