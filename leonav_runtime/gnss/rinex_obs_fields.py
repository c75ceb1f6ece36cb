"""The observation fields of a RINEX body, read with NumPy over all satellite records at once
(the part of rinex_obs.py that was per field in Python).

The reader's walk over epochs collects satellite records (`Records`): the lines of each, its
epoch time, satellite, whether its rows are kept. Here every record's fields (16 columns:
F14.3 value, LLI digit, SSI digit) become one fixed-width byte array per group of records with
the same observation types and system; a value is read as digits -> integer / 1000 when it is
a plain F14.3 (spaces, an optional '-', digits, '.', three digits), which equals Python's
float() of the text bit for bit (an integer below 2^53 divided by 1000 rounds once, as float()
does). Any other non-blank field (cut short, not a number, exponents, '+') goes through the
reader's per-field `field()`, so its value and its rejection (file, line, field) are what they
always were, at the same place in the list of rejections.

Rows: one per record and signal, as the per-field reader built them and in its order (a
record's signals in the order their first observation appears in the record): the C/L/D/S of
the signal's codes (a later code of the same quantity wins), zero C/L/S values missing and
counted, LLI from the phase, SSI from the code when it has one, else from the phase.
tests/test_gnss_rinex_obs_reference.py holds what the per-field reader returned.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from leonav_runtime.gnss import rinex_obs_v2
from leonav_runtime.gnss.observations import (
    COLUMNS,
    FLAG_ANTISPOOFING,
    FLAG_CP_VALID,
    FLAG_HALF_CYCLE,
    FLAG_LOSS_OF_LOCK,
    FLAG_POWER_FAILURE,
    FLAG_PR_VALID,
)

_PLACE = 10 ** np.arange(12, -1, -1, dtype=np.int64)   # thousandths of the 10 integer + 3 decimal columns
_COL = np.arange(10)
_QTY = "CLDS"


class Records:
    """Satellite records of a body, in file order (parallel lists, appended an epoch at a time)."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.sat: list[str] = []        # 3 characters, as the reader names the satellite
        self.start: list[int] = []      # index of the record's first line (RINEX 2: its fields go on
        #                                 the lines after it, 5 a line; RINEX 3: the one 'Snn' line)
        self.group: list[int] = []      # index into `groups`
        self.emit: list[bool] = []      # rows kept (False: read for its rejections only)
        self.power_failure: list[bool] = []
        self.rej_pos: list[int] = []    # rejections listed before this record's fields
        self.groups: dict[tuple, int] = {}   # (observation types, system) -> group index

    def add_epoch(self, t: float, sats: list[str], systems: list[str], starts: list[int],
                  types_by_system: dict[str, list[str]], emit: bool, power_failure: bool, rej_pos: int) -> None:
        """The satellite records of one epoch at GPS time t (s)."""
        n = len(sats)
        gid = {s: self.groups.setdefault((tuple(types_by_system[s]), s), len(self.groups)) for s in set(systems)}
        self.t += [t] * n
        self.sat += sats
        self.start += starts
        self.group += [gid[s] for s in systems]
        self.emit += [emit] * n
        self.power_failure += [power_failure] * n
        self.rej_pos += [rej_pos] * n


def _signal_of(code: str, system: str, version: float) -> tuple[str, str] | None:
    if version < 3:
        return rinex_obs_v2.v2_type(code, system)
    return (code[1:3], code[0]) if len(code) == 3 and code[0] in "CLDS" else None


def _fixed_width(reader, recs: Records, idx: np.ndarray, ntypes: int) -> tuple[np.ndarray, np.ndarray]:
    """(bytes (n, ntypes, 16), characters present per field (n, ntypes)) of the records `idx`."""
    lines, width = reader.lines, 16 * ntypes
    m = np.arange(ntypes)
    starts = [recs.start[r] for r in idx]
    if reader.version < 3:   # 5 fields per 80-column line, the record's lines one after the other
        per_sat = max(1, -(-ntypes // 5))
        block = [lines[j] for s in starts for j in range(s, s + per_sat)]
        wide = "".join([ln.ljust(80)[:80] for ln in block])
        if per_sat * 80 != width:
            wide = "".join(wide[k:k + width] for k in range(0, len(wide), per_sat * 80))
        lens = np.fromiter(map(len, block), dtype=np.int64, count=len(block)).reshape(-1, per_sat)
        avail = lens[:, m // 5] - 16 * (m % 5)
    else:                    # one line: 'Snn' then the fields
        block = [lines[s] for s in starts]
        wide = "".join([ln[3:3 + width].ljust(width) for ln in block])
        lens = np.fromiter(map(len, block), dtype=np.int64, count=len(block))
        avail = lens[:, None] - 3 - 16 * m[None, :]
    raw = np.frombuffer(wide.encode("ascii", "replace"), dtype=np.uint8).reshape(len(idx), ntypes, 16)
    return raw, avail


def _parse(raw: np.ndarray, avail: np.ndarray):
    """(values, lli, ssi, blank, plain) of fixed-width fields; `values` only where `plain`."""
    num = raw[..., :14]
    blank = (num == 32).all(axis=-1)
    d = num - np.uint8(48)                    # digits 0-9; any other byte wraps above 9
    digit = d < 10
    nonspace = num[..., :10] != 32
    first = np.where(nonspace.any(axis=-1), nonspace.argmax(axis=-1), 10)[..., None]
    lead = _COL < first                       # the leading spaces
    minus = (num[..., :10] == 45) & (_COL == first)
    plain = ((lead | digit[..., :10] | minus).all(axis=-1) & (num[..., 10] == 46) & digit[..., 11:14].all(axis=-1)
             & (avail >= 14) & ~blank)
    dd = np.where(digit, d, 0).astype(np.int64)
    thousandths = dd[..., :10] @ _PLACE[:10] + dd[..., 11:14] @ _PLACE[10:]
    values = thousandths.astype(np.float64) / 1000.0
    values = np.where(minus.any(axis=-1), -values, values)
    flags = raw[..., 14:16] - np.uint8(48)
    code = np.where(flags < 10, flags, 0).astype(np.int64)
    return values, code[..., 0], code[..., 1], blank, plain


def _slow_fields(reader, recs: Records, todo: list[tuple[int, int, str]], found: dict) -> list:
    """The per-field reader on the fields that are not plain F14.3, in file order: their values
    into `found[(record, m)]`; returns [(rejection position, Rejection)]."""
    saved, reader.rejected = reader.rejected, []
    out = []
    for r, m, code in sorted(todo):
        if reader.version < 3:
            k = recs.start[r] + m // 5
            text = reader.lines[k][16 * (m % 5):16 * (m % 5) + 16]
            what = f"{code} of {recs.sat[r].strip()}"
        else:
            k = recs.start[r]
            text = reader.lines[k][3 + 16 * m:3 + 16 * (m + 1)]
            what = f"{code} of {recs.sat[r]}"
        n0 = len(reader.rejected)
        found[(r, m)] = reader.field(k, text, what)
        out += [(recs.rej_pos[r], rej) for rej in reader.rejected[n0:]]
    reader.rejected = saved
    return out


def _merge(structural: list, fields: list) -> list:
    """The rejections in the order the per-field reader listed them."""
    out, k = [], 0
    for pos, rej in fields:
        out += structural[k:pos]
        k = max(k, pos)
        out.append(rej)
    return out + structural[k:]


def build_rows(reader, recs: Records) -> dict[str, np.ndarray]:
    """The observation table's columns of every emitted record (see the module docstring);
    counts into reader.counts, field rejections merged into reader.rejected."""
    n = len(recs.t)
    groups = {gid: key for key, gid in recs.groups.items()}
    group_of = np.asarray(recs.group, dtype=np.int64)
    parsed = {}
    todo: list[tuple[int, int, str]] = []   # (record, field, observation code) of the fields read one by one
    for gid, (types, _system) in groups.items():
        idx = np.flatnonzero(group_of == gid)
        if not types:
            continue
        raw, avail = _fixed_width(reader, recs, idx, len(types))
        values, lli, ssi, blank, plain = _parse(raw, avail)
        slow = ~blank & ~plain
        for a, m in zip(*np.nonzero(slow)):
            todo.append((int(idx[a]), int(m), types[m]))
        parsed[gid] = (idx, values, lli, ssi, plain)
    found: dict = {}
    reader.rejected = _merge(reader.rejected, _slow_fields(reader, recs, todo, found))
    # the slow fields' results into the group arrays (value NaN when rejected or blank)
    for (r, m), (v, l_, s_) in found.items():
        idx, values, lli, ssi, plain = parsed[recs.group[r]]
        a = int(np.searchsorted(idx, r))
        values[a, m], lli[a, m], ssi[a, m] = v, l_, s_
        plain[a, m] = not math.isnan(v)
    emit = np.asarray(recs.emit, dtype=bool)
    per_record = (np.asarray(recs.t, dtype=np.float64), np.asarray(recs.power_failure, dtype=bool))
    sats = recs.sat
    parts = []
    for gid, (idx, values, lli, ssi, present) in parsed.items():
        types, system = groups[gid]
        keep = emit[idx]
        prn = np.array([_prn(sats[r]) for r in idx.tolist()], dtype=np.int64)
        bad_id = keep & (prn < 0)
        if bad_id.any():
            reader.counts["bad_satellite_id"] += int(bad_id.sum())
        keep &= ~bad_id
        parts += _group_rows(reader, per_record, idx[keep], values[keep], lli[keep], ssi[keep], present[keep],
                             types, system, prn[keep])
    return _assemble(parts, n)


@functools.lru_cache(maxsize=4096)
def _prn(sat: str) -> int:
    try:
        return int(sat[1:3])
    except ValueError:
        return -1


def _group_rows(reader, per_record, idx, values, lli, ssi, present, types, system, prn) -> list[dict]:
    """Rows of one group: one dict of columns per signal. per_record: (time, power failure) of
    every record."""
    by_signal: dict[str, list[tuple[int, str]]] = {}
    for m, code in enumerate(types):
        st = _signal_of(code, system, reader.version)
        if st is not None:
            by_signal.setdefault(st[0], []).append((m, st[1]))
    n = idx.size
    t, power_failure = per_record[0][idx], per_record[1][idx]
    out = []
    for signal, cols in by_signal.items():
        q = {c: np.full(n, np.nan) for c in _QTY}
        lli_s = np.zeros(n, dtype=np.int64)
        ssi_s = np.zeros(n, dtype=np.int64)
        key = np.full(n, len(types), dtype=np.int64)     # the signal's first observation in the record
        for m, qty in cols:
            here = present[:, m]
            key = np.where(here & (key == len(types)), m, key)
            use = here
            if qty in "CLS":
                zero = here & (values[:, m] == 0.0)
                if zero.any():
                    reader.counts[f"zero_{qty}"] += int(zero.sum())
                use = here & ~zero
            q[qty] = np.where(use, values[:, m], q[qty])
            if qty == "L":
                lli_s = np.where(use, lli[:, m], lli_s)
                ssi_s = np.where(use & (ssi_s == 0), ssi[:, m], ssi_s)
            elif qty == "C":   # the code's SSI when it has one, else the phase's
                ssi_s = np.where(use & (ssi[:, m] != 0), ssi[:, m], ssi_s)
        measured = ~(np.isnan(q["C"]) & np.isnan(q["L"]) & np.isnan(q["D"]))
        no_meas = ~measured & ~np.isnan(q["S"]) & (key < len(types))
        if no_meas.any():
            reader.counts["rows_without_measurement"] += int(no_meas.sum())
        if not measured.any():
            continue
        sel = measured
        pf = power_failure[sel]
        flags = (np.where(np.isnan(q["C"][sel]), 0, FLAG_PR_VALID) | np.where(np.isnan(q["L"][sel]), 0, FLAG_CP_VALID)
                 | np.where(lli_s[sel] & 1, FLAG_LOSS_OF_LOCK, 0) | np.where(lli_s[sel] & 2, FLAG_HALF_CYCLE, 0)
                 | np.where(lli_s[sel] & 4, FLAG_ANTISPOOFING, 0) | np.where(pf, FLAG_POWER_FAILURE, 0))
        slots = (np.array([reader.glo_slots.get(int(p), 0) for p in prn[sel]], dtype=np.int64) if system == "R"
                 else np.zeros(int(sel.sum()), dtype=np.int64))
        out.append({"record": idx[sel], "key": key[sel], "system": system, "prn": prn[sel], "signal": signal,
                    "pseudorange_m": q["C"][sel], "carrier_phase_cyc": q["L"][sel], "doppler_hz": q["D"][sel],
                    "cn0_dbhz": q["S"][sel], "lli": lli_s[sel], "ssi": ssi_s[sel], "flags": flags,
                    "freq_slot": slots, "t": t[sel]})
    return out


def _assemble(parts: list[dict], n_records: int) -> dict[str, np.ndarray]:
    """The columns of all groups' rows, ordered by record and then by first observation."""
    if not parts:
        return {name: np.zeros(0, dtype) for name, dtype in COLUMNS}
    record = np.concatenate([p["record"] for p in parts])
    key = np.concatenate([p["key"] for p in parts])
    order = np.lexsort((key, record))
    sizes = [p["record"].size for p in parts]
    cols = {
        "t_gps_s": np.concatenate([p["t"] for p in parts]),
        "system": np.repeat([p["system"] for p in parts], sizes),
        "prn": np.concatenate([p["prn"] for p in parts]),
        "signal": np.repeat([p["signal"] for p in parts], sizes),
        "sigma_pr_m": np.full(record.size, np.nan),
    }
    for name in ("pseudorange_m", "carrier_phase_cyc", "doppler_hz", "cn0_dbhz", "lli", "ssi", "flags", "freq_slot"):
        cols[name] = np.concatenate([p[name] for p in parts])
    return {name: np.asarray(cols[name], dtype=dtype)[order] for name, dtype in COLUMNS}
