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

Rows: per record and signal as `add_sat` built them, in the same order (the record's signals
in the order their first observation appears in the record), so the table is identical.
"""
from __future__ import annotations

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

_POW10 = 10 ** np.arange(9, -1, -1, dtype=np.int64)   # place values of the 10 integer columns
_QTY = "CLDS"


class Records:
    """Satellite records of a body, in file order (parallel lists)."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.sat: list[str] = []        # 3 characters, as the reader names the satellite
        self.system: list[str] = []
        self.lines: list[tuple[int, ...]] = []   # line indices holding the record's fields
        self.group: list[int] = []      # index into `groups`
        self.emit: list[bool] = []      # rows kept (False: read for its rejections only)
        self.power_failure: list[bool] = []
        self.rej_pos: list[int] = []    # rejections listed before this record's fields
        self.groups: dict[tuple, int] = {}

    def add(self, t: float, sat: str, system: str, lines: tuple[int, ...], types: list[str], emit: bool,
            power_failure: bool, rej_pos: int) -> None:
        key = (tuple(types), system)
        self.t.append(t)
        self.sat.append(sat)
        self.system.append(system)
        self.lines.append(lines)
        self.group.append(self.groups.setdefault(key, len(self.groups)))
        self.emit.append(emit)
        self.power_failure.append(power_failure)
        self.rej_pos.append(rej_pos)


def _signal_of(code: str, system: str, version: float) -> tuple[str, str] | None:
    if version < 3:
        return rinex_obs_v2.v2_type(code, system)
    return (code[1:3], code[0]) if len(code) == 3 and code[0] in "CLDS" else None


def _fixed_width(reader, recs: Records, idx: np.ndarray, ntypes: int) -> tuple[np.ndarray, np.ndarray]:
    """(bytes (n, ntypes, 16), characters present per field (n, ntypes)) of the records `idx`."""
    lines, width = reader.lines, 16 * ntypes
    m = np.arange(ntypes)
    if reader.version < 3:   # 5 fields per 80-column line, the record's lines one after the other
        per_sat = max(1, -(-ntypes // 5))
        wide = "".join("".join(lines[j].ljust(80)[:80] for j in recs.lines[r])[:width].ljust(width) for r in idx)
        lens = np.array([[len(lines[j]) for j in recs.lines[r]] for r in idx], dtype=np.int64).reshape(-1, per_sat)
        avail = lens[:, m // 5] - 16 * (m % 5)
    else:                    # one line: 'Snn' then the fields
        wide = "".join(lines[recs.lines[r][0]][3:3 + width].ljust(width) for r in idx)
        lens = np.array([len(lines[recs.lines[r][0]]) for r in idx], dtype=np.int64)
        avail = lens[:, None] - 3 - 16 * m[None, :]
    raw = np.frombuffer(wide.encode("ascii", "replace"), dtype=np.uint8).reshape(len(idx), ntypes, 16)
    return raw, avail


def _parse(raw: np.ndarray, avail: np.ndarray):
    """(values, lli, ssi, blank, plain) of fixed-width fields; `values` only where `plain`."""
    num = raw[..., :14]
    blank = np.all(num == 32, axis=-1)
    ip = num[..., :10]
    digit = (ip >= 48) & (ip <= 57)
    space = ip == 32
    lead = np.cumprod(space, axis=-1).astype(bool)                # the leading spaces
    first = ~lead & np.concatenate([np.ones_like(lead[..., :1]), lead[..., :-1]], axis=-1)
    minus = (ip == 45) & first
    frac = num[..., 11:14]
    plain = (np.all(lead | digit | minus, axis=-1) & (num[..., 10] == 46)
             & np.all((frac >= 48) & (frac <= 57), axis=-1) & (avail >= 14) & ~blank)
    whole = (np.where(digit, ip - 48, 0).astype(np.int64) * _POW10).sum(axis=-1)
    thousandths = ((frac.astype(np.int64) - 48) * np.array([100, 10, 1])).sum(axis=-1)
    values = (whole * 1000 + thousandths).astype(np.float64) / 1000.0
    values = np.where(np.any(minus, axis=-1), -values, values)
    flags = raw[..., 14:16]
    ok = (flags >= 48) & (flags <= 57)
    code = np.where(ok, flags.astype(np.int64) - 48, 0)
    return values, code[..., 0], code[..., 1], blank, plain


def _slow_fields(reader, recs: Records, todo: list[tuple[int, int, int, str]], found: dict) -> list:
    """The per-field reader on the fields that are not plain F14.3, in file order: their values
    into `found[(record, m)]`; returns [(rejection position, Rejection)]."""
    saved, reader.rejected = reader.rejected, []
    out = []
    for r, m, gid, code in sorted(todo):
        rec_lines = recs.lines[r]
        if reader.version < 3:
            k = rec_lines[m // 5]
            text = reader.lines[k][16 * (m % 5):16 * (m % 5) + 16]
            what = f"{code} of {recs.sat[r].strip()}"
        else:
            k = rec_lines[0]
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
    todo: list[tuple[int, int, int, str]] = []
    for gid, (types, system) in groups.items():
        idx = np.flatnonzero(group_of == gid)
        if not types:
            continue
        raw, avail = _fixed_width(reader, recs, idx, len(types))
        values, lli, ssi, blank, plain = _parse(raw, avail)
        slow = ~blank & ~plain
        for a, m in zip(*np.nonzero(slow)):
            todo.append((int(idx[a]), int(m), gid, types[m]))
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
    parts = []
    for gid, (idx, values, lli, ssi, present) in parsed.items():
        types, system = groups[gid]
        keep = emit[idx]
        prn = np.array([_prn(recs.sat[r]) for r in idx], dtype=np.int64)
        bad_id = keep & (prn < 0)
        if bad_id.any():
            reader.counts["bad_satellite_id"] += int(bad_id.sum())
        keep &= ~bad_id
        parts += _group_rows(reader, recs, idx[keep], values[keep], lli[keep], ssi[keep], present[keep],
                             types, system, prn[keep])
    return _assemble(parts, n)


def _prn(sat: str) -> int:
    try:
        return int(sat[1:3])
    except ValueError:
        return -1


def _group_rows(reader, recs, idx, values, lli, ssi, present, types, system, prn) -> list[dict]:
    """Rows of one group: one dict of columns per signal."""
    by_signal: dict[str, list[tuple[int, str]]] = {}
    for m, code in enumerate(types):
        st = _signal_of(code, system, reader.version)
        if st is not None:
            by_signal.setdefault(st[0], []).append((m, st[1]))
    n = idx.size
    t = np.asarray(recs.t)[idx]
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
        pf = np.asarray([recs.power_failure[r] for r in idx[sel]], dtype=bool)
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
