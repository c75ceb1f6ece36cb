"""The observation reader against its previous (per-field) version and against georinex.

tests/data/rinex_obs_reference.json holds, for every input below, what the per-field reader
of commit f5b507e returned, with one fix (a code's blank SSI no longer cleared the SSI its
phase had given: a row's SSI is the code's when it has one, else the phase's): the row count, a SHA-256 of every value and flag of the table
(all columns, row order included), the counts and the rejections (file:line: field: reason),
so the vectorised reader must give exactly the same table, counts and messages. Inputs: the
shared GEONET files (RINEX 2.10), the same data written as RINEX 3.04 here, the synthetic
RINEX 3.03 text, and seeded edits of each (characters changed, lines cut, blank or removed
or repeated lines, LLI/SSI digits changed, values 0.000, epoch flags 1 and 6): 6 + 180 files.

Regenerate (only with a reader known to be right, and say why in the commit):
    python -m tests.test_gnss_rinex_obs_reference --write
"""
from __future__ import annotations

import hashlib
import json
import random
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.gnss.observations import COLUMNS
from leonav_runtime.gnss.rinex_obs import parse_rinex_obs, read_rinex_obs
from tests import gnss_rinex3_synth as synth
from tests.conftest import SHARED_DATA, shared_file

REFERENCE = Path(__file__).parent / "data" / "rinex_obs_reference.json"
SHARED_OBS = ("gnss_rinex/07590920.05o", "gnss_rinex/30400920.05o")
V3_TYPES = {"C1": "C1C", "L1": "L1C", "L2": "L2W", "P2": "C2W"}
EDITS_PER_BASE = 30


def v2_to_v3(text: str, order: tuple[int, ...] | None = None) -> str:
    """A RINEX 2.10 GPS observation text written as RINEX 3.04 (same values, LLI and SSI;
    types C1 L1 L2 P2 -> C1C L1C L2W C2W, in the file's order or the type indices `order`)."""
    lines = text.splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln)
    types: list[str] = []
    head = []
    for ln in lines[:end + 1]:
        label = ln[60:].strip()
        if label == "# / TYPES OF OBSERV":
            types += ln[6:60].split()
            continue
        if label == "RINEX VERSION / TYPE":
            ln = f"{'     3.04           OBSERVATION DATA    G: GPS':<60}RINEX VERSION / TYPE"
        if label == "END OF HEADER":
            order = order or tuple(range(len(types)))
            codes = " ".join(V3_TYPES[types[k]] for k in order)
            head.append(f"{'G' + f'{len(types):5d} ' + codes:<60}SYS / # / OBS TYPES")
        head.append(ln)
    per_sat = -(-len(types) // 5)
    body, i = [], end + 1
    while i < len(lines):
        ep = lines[i]
        flag, nsat = ep[28], int(ep[29:32])
        if flag in "2345":   # an event: its header/comment lines as they are
            body += [f">{'':30s}{flag}{nsat:3d}"] + lines[i + 1:i + 1 + nsat]
            i += 1 + nsat
            continue
        yy = int(ep[1:3])
        sats = ep[32:68]
        n_id_lines = -(-nsat // 12)
        for k in range(1, n_id_lines):
            sats += lines[i + k][32:68]
        body.append(f"> {2000 + yy:04d} {ep[4:6].replace(' ', '0')} {ep[7:9].replace(' ', '0')} "
                    f"{ep[10:12].replace(' ', '0')} {ep[13:15].replace(' ', '0')}{ep[15:26]}  {flag}{nsat:3d}")
        i += n_id_lines
        for s in range(nsat):
            sid = sats[3 * s:3 * s + 3]
            fields = "".join(lines[i + k].ljust(80)[:80] for k in range(per_sat))
            body.append(("G" + sid[1:3].replace(" ", "0") + "".join(fields[16 * k:16 * k + 16] for k in order)).rstrip())
            i += per_sat
    return "\n".join(head + body) + "\n"


def _bases() -> dict[str, str]:
    out = {}
    for rel in SHARED_OBS:
        path = SHARED_DATA / rel
        if path.is_file():
            text = path.read_text()
            out[path.name] = text
            out[path.name + ".v3"] = v2_to_v3(text)
    if "07590920.05o" in out:   # codes before phases: the SSI of a signal comes from its code
        out["07590920.05o.v3-codes-first"] = v2_to_v3(out["07590920.05o"], order=(1, 3, 0, 2))
    out["synth_v3"] = synth.obs_text()
    return out


def _edit(text: str, rng: random.Random) -> str:
    """1-4 seeded edits in the body of a RINEX text."""
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    for _ in range(rng.randint(1, 4)):
        i = rng.randrange(first, len(lines))
        ln = lines[i]
        kind = rng.choice(("char", "char", "digit", "cut", "blank", "drop", "repeat", "flag", "lli", "lli", "zero"))
        if kind in ("char", "digit") and ln:
            k = rng.randrange(len(ln))
            c = rng.choice("x-. 9+eE\t") if kind == "char" else rng.choice("0123456789")
            lines[i] = ln[:k] + c + ln[k + 1:]
        elif kind == "cut" and ln:
            lines[i] = ln[:rng.randrange(len(ln))]
        elif kind == "blank":
            lines.insert(i, "")
        elif kind == "drop":
            del lines[i]
        elif kind == "repeat":
            lines.insert(i, ln)
        elif kind == "flag":   # an epoch line's flag made 1 (power failure) or 6 (cycle slips)
            j = next((m for m in range(i, len(lines)) if lines[m].startswith((">", " 05"))), None)
            if j is not None:
                col = 31 if lines[j].startswith(">") else 28
                lines[j] = lines[j][:col] + rng.choice("16") + lines[j][col + 1:]
        elif kind == "lli" and len(ln) > 20:   # an LLI or SSI digit
            k = rng.randrange(0, len(ln) // 16) * 16 + (14 if ln[:1] == " " else 17) + rng.randrange(2)
            if k < len(ln):
                lines[i] = ln[:k] + rng.choice("1234567 ") + ln[k + 1:]
        elif kind == "zero" and len(ln) > 20:   # a value written as 0.000 (no observation), flags kept
            k = rng.randrange(0, len(ln) // 16) * 16 + (0 if ln[:1] == " " else 3)
            lines[i] = ln[:k] + f"{0.0:14.3f}" + ln[k + 14:]
    return "\n".join(lines) + "\n"


def inputs() -> dict[str, str]:
    """{name: text} of every input the reference holds."""
    out = {}
    for name, text in _bases().items():
        out[name] = text
        rng = random.Random(f"rinex-obs-reference-{name}")
        for k in range(EDITS_PER_BASE):
            out[f"{name}~{k}"] = _edit(text, rng)
    return out


def summary(text: str, name: str) -> dict:
    """Everything the reader returns for `text`, as the reference stores it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = parse_rinex_obs(text, name)
    digest = hashlib.sha256()
    for col, _ in COLUMNS:
        values = getattr(table, col)
        if values.dtype.kind == "f":
            values = np.where(np.isnan(values), np.float64("nan"), values)   # one NaN bit pattern
        digest.update(col.encode() + np.ascontiguousarray(values).tobytes())
    return {"rows": len(table), "sha256": digest.hexdigest(), "counts": dict(sorted(table.counts.items())),
            "rejected": [str(r) for r in table.rejected]}


def _reference() -> dict:
    if not REFERENCE.is_file():
        pytest.skip(f"{REFERENCE} missing")
    return json.loads(REFERENCE.read_text())


def test_reference_covers_the_inputs_and_their_rejections():
    ref = _reference()
    names = inputs()
    if not all(n in names for n in ("07590920.05o", "30400920.05o")):
        pytest.skip("needs the shared GEONET files (../shared/data/gnss_rinex)")
    assert set(ref) == set(names)
    # the edits reach the slow paths: most edited files have rejections, of several kinds
    edited = [v for k, v in ref.items() if "~" in k]
    assert sum(bool(v["rejected"]) for v in edited) > len(edited) // 2
    reasons = {r.split(": ", 2)[-1].split(" (")[0][:25] for v in edited for r in v["rejected"]}
    assert len(reasons) >= 6, reasons
    assert any(v["counts"].get("epochs_out_of_order") or v["counts"].get("duplicate_epochs") for v in edited)
    assert any("cycle_slip_records" in v["counts"] for v in edited)


@pytest.mark.parametrize("base", ["07590920.05o", "30400920.05o", "synth_v3"])
def test_reader_gives_exactly_the_previous_output(base):
    ref = _reference()
    todo = {k: v for k, v in inputs().items() if k.split("~")[0].split(".v3")[0] == base}
    if not todo:
        pytest.skip(f"needs ../shared/data/gnss_rinex/{base}")
    for name, text in todo.items():
        assert summary(text, name) == ref[name], name


def test_numpy_path_reads_every_plain_field(monkeypatch):
    """Every field of the shared files, their RINEX 3 writing and the synthetic text is a plain
    F14.3 read by the NumPy path: none goes through the per-field reader (which gives the same
    table, twice as slowly: a reader that sent everything there would pass the tests above), and
    a garbled field is the one field sent there."""
    from leonav_runtime.gnss import rinex_obs_fields

    seen: list[list] = []
    per_field = rinex_obs_fields._slow_fields

    def spy(reader, recs, todo, found):
        seen.append(sorted(todo))
        return per_field(reader, recs, todo, found)

    monkeypatch.setattr(rinex_obs_fields, "_slow_fields", spy)
    bases = _bases()
    if "07590920.05o" not in bases:
        pytest.skip("needs ../shared/data/gnss_rinex/07590920.05o")
    for name, text in bases.items():
        seen.clear()
        assert summary(text, name)["rows"] > 0
        assert seen == [[]], (name, seen[0][:5])
    lines = bases["07590920.05o"].splitlines()
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 2   # the first satellite's line
    lines[k] = lines[k][:5] + "x" + lines[k][6:]
    seen.clear()
    assert summary("\n".join(lines) + "\n", "garbled")["rejected"][0].startswith(f"garbled:{k + 1}: L1 of G")
    assert len(seen[0]) == 1 and seen[0][0][1:] == (0, "L1")


def test_v3_copy_reads_as_the_v2_file():
    """The RINEX 3 writing of a file reads to the same values as its RINEX 2 original (the
    signal codes of RINEX 2 C1/L1/L2/P2 are 1C, 1C, 2W, 2W either way)."""
    path = shared_file(SHARED_OBS[0])
    a = read_rinex_obs(path)
    b = parse_rinex_obs(v2_to_v3(path.read_text()), "v3")
    for col, _ in COLUMNS:
        x, y = getattr(a, col), getattr(b, col)
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), col


@pytest.mark.parametrize("rel", SHARED_OBS)
def test_every_value_and_flag_as_georinex_reads_them(rel):
    """An outside reader: georinex's value, LLI and SSI of every observation."""
    georinex = pytest.importorskip("georinex", reason="georinex (test extra) not installed")
    path = shared_file(rel)
    table = read_rinex_obs(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = georinex.load(path, useindicators=True)
    times = (ds.time.values - np.datetime64("1980-01-06T00:00:00")) / np.timedelta64(1, "ns") * 1e-9
    sv_index = {str(s): k for k, s in enumerate(ds.sv.values)}
    pairs = {"C1": ("1C", "pseudorange_m", None), "L1": ("1C", "carrier_phase_cyc", "lli"),
             "P2": ("2W", "pseudorange_m", None), "L2": ("2W", "carrier_phase_cyc", "lli")}
    checked = 0
    for code, (signal, column, lli_col) in pairs.items():
        values = ds[code].values
        ssi = ds[code + "ssi"].values
        lli = ds[code + "lli"].values if code + "lli" in ds else None
        rows = np.flatnonzero(table.signal == signal)
        for r in rows:
            k = int(np.argmin(np.abs(times - table.t_gps_s[r])))   # georinex keeps whole-ms times
            assert abs(times[k] - table.t_gps_s[r]) < 0.01
            s = sv_index[f"G{table.prn[r]:02d}"]
            ours = getattr(table, column)[r]
            assert (np.isnan(ours) and np.isnan(values[k, s])) or ours == values[k, s], (code, r)
            if lli_col and np.isfinite(ours):
                want = 0 if np.isnan(lli[k, s]) else int(lli[k, s])
                assert table.lli[r] == want, (code, r)
            if column == "pseudorange_m" and np.isfinite(ours):
                checked += 1
                # our SSI of a signal is that of its code (C1/P2) when given, else of its phase
                if np.isfinite(ssi[k, s]):
                    assert table.ssi[r] == int(ssi[k, s]), (code, r)
    assert checked == int(np.isfinite(table.pseudorange_m).sum()) > 1500   # every pseudorange checked


def _write() -> None:
    data = {name: summary(text, name) for name, text in inputs().items()}
    REFERENCE.write_text(json.dumps(data, indent=0, sort_keys=True) + "\n")
    print(f"{REFERENCE}: {len(data)} inputs")


if __name__ == "__main__":
    if "--write" in sys.argv:
        import logging

        logging.getLogger("leonav.gnss").setLevel(logging.ERROR)   # the edited files' rejections
        _write()
