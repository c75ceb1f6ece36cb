"""Seeded, bounded fuzzing of the readers: element files (TLE/3LE, OMM CSV/JSON/XML) and
capture metadata (raw side JSON, SigMF) plus capture data.

Inputs are real files from ../shared/data (the OMM variants carry the real GPS element
sets of gps-ops_2026-03-09 in CelesTrak's OMM layouts; there is no public SigMF capture,
so the metadata is what `capture_io` writes and the "samples" are the real bytes of a
WitMotion recording). Each is mutated: truncated, bytes flipped, lines duplicated or
deleted, lines split or joined, re-chunked (CRLF, re-indented). For every mutant:
- no exception escapes except the documented UserInputError;
- nothing is dropped silently: every element line of a mutant is accounted for by a
  loaded entry or a counted rejection, and damage to JSON/XML/TLE is never silent;
- the entries of the untouched prefix load exactly as from the original file.
Each test runs a fixed number of mutants (seeded), under a wall-clock bound.
"""
from __future__ import annotations

import csv
import datetime as dt
import io
import json
import warnings

import numpy as np
import pytest

from leonav_runtime.beacons import capture_io
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import load_elements, parse_elements_text
from leonav_runtime.orbits import tle as tle_mod
from tests.conftest import shared_file
from tests.timebox import bounded

T0 = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)



def _line_starts(data: bytes) -> list[int]:
    starts = [0]
    for i, b in enumerate(data):
        if b == 0x0A:
            starts.append(i + 1)
    return starts


def mutate(data: bytes, rng: np.random.Generator) -> tuple[str, bytes, int]:
    """(kind, mutant, offset of the first changed byte; len(data) when only re-chunked)."""
    starts = _line_starts(data)
    n_lines = len(starts) - (1 if starts[-1] == len(data) else 0)
    kind = str(rng.choice(["truncate", "flip", "duplicate", "delete", "split", "join", "rechunk"]))
    if kind == "truncate":
        cut = int(rng.integers(0, len(data)))
        return kind, data[:cut], cut
    if kind == "flip":
        first = int(rng.integers(0, len(data)))
        out = bytearray(data)
        for k in range(int(rng.integers(1, 6))):
            i = min(len(data) - 1, first + int(rng.integers(0, 400)) * (k > 0))
            out[i] = int(rng.integers(0, 256))
        changed = [i for i in range(len(data)) if out[i] != data[i]]
        return kind, bytes(out), changed[0] if changed else len(data)
    m = int(rng.integers(0, n_lines))
    a, b = starts[m], starts[m + 1] if m + 1 < len(starts) else len(data)
    if kind == "duplicate":
        j = int(rng.integers(0, n_lines))
        line = data[starts[j]: starts[j + 1] if j + 1 < len(starts) else len(data)]
        if not line.endswith(b"\n"):
            line += b"\n"
        return kind, data[:a] + line + data[a:], a
    if kind == "delete":
        return kind, data[:a] + data[b:], a
    if kind == "split":
        c = a + int(rng.integers(0, max(1, b - a)))
        return kind, data[:c] + b"\n" + data[c:], c
    if kind == "join":
        if b - 1 >= a and data[b - 1: b] == b"\n":
            return kind, data[: b - 1] + data[b:], b - 1
        return kind, data, len(data)
    return kind, data.replace(b"\n", b"\r\n"), len(data)  # rechunk: same content, other line ends


def _quiet_load(text: str, source: str = "<fuzz>"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parse_elements_text(text, source)


def _decode(data: bytes) -> str:
    return data.decode("utf-8", errors="replace")  # what load_elements does with a file's bytes


def _record(es, i: int) -> tuple:
    s = es.satrecs[i]
    return (es.names[i], int(es.norad_ids[i]), es.epochs_utc[i], s.no_kozai, s.ecco, s.inclo, s.nodeo,
            s.argpo, s.mo, s.bstar, s.jdsatepoch, s.jdsatepochF)


def _check_prefix(original, mutant_es, ends: list[int], offset: int, same_sources: bool = True) -> None:
    """Entries whose text ends (newline included) before `offset` load exactly as from the original."""
    prefix = [i for i, end in enumerate(ends) if end <= offset]
    assert len(mutant_es) >= len(prefix)
    for i in prefix:
        assert _record(mutant_es, i) == _record(original, i)
        if same_sources:
            assert mutant_es.sources[i] == original.sources[i]


# ------------------------------------------------------------------ TLE / 3LE


def _tle_ends(es, text: str) -> list[int]:
    """Byte offset just after line 2 (and its newline) of each entry (ASCII text)."""
    starts = _line_starts(text.encode())
    ends = []
    for src in es.sources:
        line2 = int(src.rsplit(":", 1)[1]) + 1  # 1-based number of line 2
        ends.append(starts[line2] if line2 < len(starts) else len(text))
    return ends


def _tle_sources() -> list[tuple[str, bytes]]:
    out = []
    for rel, n_lines in (("tle/gps-ops_2026-03-09.txt", None), ("tle/starlink_supgp_2026-05-13.txt", 150),
                         ("tle/rtklib_gnss_20121031/tle_nav.txt", 120), ("sgp4/rtklib_tle_sgp4_str3.txt", None)):
        data = shared_file(rel).read_bytes()
        if n_lines:
            data = b"".join(data.splitlines(keepends=True)[:n_lines])
        out.append((rel, data))
    return out


def test_fuzz_tle_and_3le_files():
    rng = np.random.default_rng(20261130)
    with bounded(90):
        for rel, data in _tle_sources():
            original = _quiet_load(_decode(data), rel)
            ends = _tle_ends(original, _decode(data))
            for _ in range(120):
                kind, mutant, offset = mutate(data, rng)
                text = _decode(mutant)
                try:
                    es = _quiet_load(text, rel)
                except UserInputError as exc:
                    assert str(exc).startswith(rel)
                    assert not any(end <= offset for end in ends), (kind, offset)  # a good prefix always loads
                    continue
                lines = [ln.rstrip() for ln in text.splitlines()]
                n1 = sum(1 for ln in lines if tle_mod.is_element_line(ln) and ln[0] == "1")
                n2 = sum(1 for ln in lines if tle_mod.is_element_line(ln) and ln[0] == "2")
                other = sum(1 for ln in lines if tle_mod.is_element_line(ln) and ln[0] not in "12")
                loaded, rejected = len(es), len(es.rejected)
                # every line 1 is a loaded entry or a rejection, every stray line 2 or odd line
                # number a rejection (a line 2 right after a rejected odd line belongs to it)
                assert n1 <= loaded + rejected, (kind, n1, loaded, rejected)
                assert n2 <= loaded + 2 * rejected and other <= rejected, (kind, n2, other, loaded, rejected)
                assert all(1 <= r.line <= len(lines) and r.reason for r in es.rejected)
                if kind == "rechunk":
                    assert [_record(es, i) for i in range(len(es))] == [_record(original, i) for i in range(len(original))]
                    assert rejected == 0
                else:
                    _check_prefix(original, es, ends, offset)


def test_fuzz_tle_through_files_with_non_utf8_bytes(tmp_path):
    rng = np.random.default_rng(7)
    data = shared_file("tle/gps-ops_2026-03-09.txt").read_bytes()
    original = load_elements(shared_file("tle/gps-ops_2026-03-09.txt"))
    ends = _tle_ends(original, data.decode())
    path = tmp_path / "fuzz.tle"
    with bounded(30):
        for _ in range(60):
            out = bytearray(data)
            first = int(rng.integers(0, len(data)))
            for k in range(int(rng.integers(1, 4))):
                out[min(len(data) - 1, first + 7 * k)] = int(rng.choice([0x80, 0xC3, 0xE2, 0xFF, 0x00, 0x0B, 0x85]))
            path.write_bytes(bytes(out))
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    es = load_elements(path)
            except UserInputError:
                continue
            _check_prefix(original, es, ends, first, same_sources=False)


# ------------------------------------------------------------------ OMM (CSV, JSON, XML)

_OMM_KEYS = ("OBJECT_NAME", "OBJECT_ID", "EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE",
             "ARG_OF_PERICENTER", "MEAN_ANOMALY", "EPHEMERIS_TYPE", "CLASSIFICATION_TYPE", "NORAD_CAT_ID",
             "ELEMENT_SET_NO", "REV_AT_EPOCH", "BSTAR", "MEAN_MOTION_DOT", "MEAN_MOTION_DDOT")


def _omm_records() -> list[dict[str, str]]:
    """The real gps-ops element sets as OMM field dictionaries (text as CelesTrak writes it)."""
    lines = shared_file("tle/gps-ops_2026-03-09.txt").read_text().splitlines()
    recs = []
    for k in range(0, len(lines) - 2, 3):
        f = tle_mod.parse_fields(lines[k + 1], lines[k + 2])
        recs.append({
            "OBJECT_NAME": lines[k].strip(), "OBJECT_ID": f.intl_designator,
            "EPOCH": f.epoch_utc.strftime("%Y-%m-%dT%H:%M:%S.%f"), "MEAN_MOTION": f"{f.mean_motion_revday:.8f}",
            "ECCENTRICITY": f"{f.eccentricity:.7f}", "INCLINATION": f"{f.inclination_deg:.4f}",
            "RA_OF_ASC_NODE": f"{f.raan_deg:.4f}", "ARG_OF_PERICENTER": f"{f.arg_perigee_deg:.4f}",
            "MEAN_ANOMALY": f"{f.mean_anomaly_deg:.4f}", "EPHEMERIS_TYPE": "0", "CLASSIFICATION_TYPE": "U",
            "NORAD_CAT_ID": str(f.norad_id), "ELEMENT_SET_NO": str(f.element_number),
            "REV_AT_EPOCH": str(f.rev_number), "BSTAR": f"{f.bstar_per_earth_radius:.5E}",
            "MEAN_MOTION_DOT": f"{f.ndot_revday2:.8f}", "MEAN_MOTION_DDOT": f"{f.nddot_revday3:g}",
        })
    return recs


def _omm_texts(recs) -> dict[str, tuple[bytes, list[int]]]:
    """OMM CSV/JSON/XML bytes and, per record, the offset just after it."""
    out = {}
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(_OMM_KEYS)
    ends = []
    for r in recs:
        writer.writerow([r[k] for k in _OMM_KEYS])
        ends.append(len(buf.getvalue()))
    out["csv"] = (buf.getvalue().encode(), ends)
    ends, text = [], "[\n"
    for i, r in enumerate(recs):
        text += json.dumps(r) + (",\n" if i < len(recs) - 1 else "\n")
        ends.append(len(text))
    out["json"] = ((text + "]\n").encode(), ends)
    text, ends = '<?xml version="1.0" encoding="UTF-8"?>\n<ndm>\n', []
    for r in recs:
        items = "".join(f"<{k}>{v}</{k}>" for k, v in r.items() if k not in ("OBJECT_NAME", "OBJECT_ID"))
        text += (f'<omm id="CCSDS_OMM_VERS" version="2.0"><header/><body><segment><metadata>'
                 f'<OBJECT_NAME>{r["OBJECT_NAME"]}</OBJECT_NAME><OBJECT_ID>{r["OBJECT_ID"]}</OBJECT_ID></metadata>'
                 f"<data><meanElements>{items}</meanElements></data></segment></body></omm>\n")
        ends.append(len(text))
    out["xml"] = ((text + "</ndm>\n").encode(), ends)
    return out


@pytest.mark.parametrize("fmt", ["csv", "json", "xml"])
def test_fuzz_omm_files(fmt):
    recs = _omm_records()
    data, ends = _omm_texts(recs)[fmt]
    original = _quiet_load(data.decode(), f"gp.{fmt}")
    assert len(original) == len(recs) == 32 and not original.rejected
    rng = np.random.default_rng({"csv": 11, "json": 12, "xml": 13}[fmt])
    stats: dict[str, int] = {}
    with bounded(60):
        for _ in range(150):
            kind, mutant, offset = mutate(data, rng)
            text = _decode(mutant)
            try:
                es = _quiet_load(text, f"gp.{fmt}")
            except UserInputError as exc:
                assert str(exc).startswith(f"gp.{fmt}")
                assert not any(end <= offset for end in ends), (kind, offset, str(exc)[:200])  # the prefix loads
                continue
            stats[kind] = stats.get(kind, 0) + 1
            assert all(r.reason for r in es.rejected)
            if kind == "rechunk":
                assert [_record(es, i) for i in range(len(es))] == [_record(original, i) for i in range(32)]
                continue
            _check_prefix(original, es, ends, offset, same_sources=(fmt != "csv" or kind != "split"))
            if kind == "truncate" and fmt in ("json", "xml") and text.rstrip() != data.decode().rstrip():
                assert es.rejected, "a truncated JSON/XML file must not load silently"


def test_fuzz_deeply_nested_and_huge_omm_fragments_stay_bounded():
    rng = np.random.default_rng(5)
    recs = _omm_records()
    texts = _omm_texts(recs)
    with bounded(60):
        for fmt, (data, ends) in texts.items():
            for _ in range(10):
                pos = ends[int(rng.integers(0, len(ends)))]
                depth = int(rng.integers(1_000, 50_000))
                bomb = {"csv": b'"' + b"x" * (depth * 20) + b'"\n', "json": b"[" * depth + b"]" * depth,
                        "xml": b"<a>" * depth + b"</a>" * depth}[fmt]
                text = _decode(data[:pos] + bomb + data[pos:])
                try:
                    es = _quiet_load(text, f"gp.{fmt}")
                except UserInputError:
                    continue
                prefix = sum(1 for e in ends if e <= pos)
                assert len(es) >= prefix and (es.rejected or fmt == "csv")


# ------------------------------------------------------------------ capture metadata and data


def _data_bytes() -> bytes:
    return shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()  # real bytes read as cu8


def _check_info(info: capture_io.CaptureInfo, data_len: int, header: int = 0) -> None:
    assert capture_io.MIN_SAMPLE_RATE_HZ <= info.sample_rate_hz <= capture_io.MAX_SAMPLE_RATE_HZ
    assert 0 < info.center_freq_hz <= capture_io.MAX_FREQ_HZ and np.isfinite(info.lnb_lo_hz)
    assert info.start_utc is None or isinstance(info.start_utc, dt.datetime)
    assert info.n_samples * 2 + info.trailing_bytes == data_len - info.header_bytes


@pytest.mark.parametrize("kind", ["side", "sigmf"])
def test_fuzz_capture_metadata(tmp_path, kind):
    data = _data_bytes()
    if kind == "side":
        cap = tmp_path / "cap.cu8"
        cap.write_bytes(data)
        meta_path = capture_io.write_side_json(cap, 2.4e6, 1.575e9, 9.75e9, T0)
        target = cap
    else:
        (tmp_path / "rec.sigmf-data").write_bytes(data)
        meta_path = capture_io.write_sigmf_meta(tmp_path / "rec", "cu8", 2.4e6, 1.575e9, 9.75e9, T0)
        target = meta_path
    meta = meta_path.read_bytes()
    good = capture_io.open_capture(target)
    _check_info(good, len(data))
    rng = np.random.default_rng({"side": 21, "sigmf": 22}[kind])
    with bounded(90):
        for _ in range(120):
            kind_m, mutant, _ = mutate(meta, rng)
            meta_path.write_bytes(mutant)
            try:
                info = capture_io.open_capture(target)
            except UserInputError as exc:
                assert len(str(exc)) < 1000 and "\n" not in str(exc)
                continue
            _check_info(info, len(data))
            if kind_m == "rechunk":
                assert info.describe() == good.describe()


def test_fuzz_capture_data_truncation_keeps_the_prefix(tmp_path):
    data = _data_bytes()
    cap = tmp_path / "cap.cu8"
    cap.write_bytes(data)
    capture_io.write_side_json(cap, 2.4e6, 1.575e9, 9.75e9, T0)
    full = capture_io.read_all(capture_io.open_capture(cap))
    rng = np.random.default_rng(31)
    with bounded(30):
        for _ in range(40):
            cut = int(rng.integers(0, len(data)))
            cap.write_bytes(data[:cut])
            try:
                info = capture_io.open_capture(cap)
            except UserInputError as exc:
                assert cut == 0 and "empty" in str(exc)
                continue
            assert (info.n_samples, info.trailing_bytes) == (cut // 2, cut % 2)  # the odd byte is counted
            chunks = list(capture_io.iter_chunks(info, chunk_samples=int(rng.integers(1, 5000))))
            got = np.concatenate(chunks) if chunks else np.zeros(0, np.complex64)
            np.testing.assert_array_equal(got, full[: cut // 2])
