"""Compressed RINEX as the field distributes it (issue 24): gzip, bzip2, unix compress (.Z) and
Hatanaka (Compact RINEX: .crx, .YYd, .crx.gz, .YYd.Z) read exactly as the plain file, by
`read_rinex_obs` / `read_rinex_nav` and by `leonav spp`; a corrupt or truncated compressed file
is one line naming the file.

The compressed copies of the shared GEONET files are made here in tmp_path (gzip and bz2 from
the standard library, .Z with ncompress, checked by gzip -d, which decodes LZW on its own;
Compact RINEX with the hatanaka package's rnx2crx). Files compressed by others: the sample
files the hatanaka package ships (a RINEX 3.01 mixed file with its .crx, .Z, .gz, .bz2 copies
made by the real compress/gzip/rnx2crx), decompressed in place.
"""
from __future__ import annotations

import bz2
import gzip
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.cli import main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss.observations import COLUMNS
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.rinex_obs import read_rinex_obs
from tests.conftest import shared_file

ncompress = pytest.importorskip("ncompress", reason="ncompress (a leonav dependency, .Z files) not installed")
hatanaka = pytest.importorskip("hatanaka", reason="hatanaka (a leonav dependency, Compact RINEX) not installed")
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")

OBS = ("gnss_rinex/07590920.05o", "gnss_rinex/30400920.05o")
NAV = ("gnss_rinex/07590920.05n", "gnss_rinex/30400920.05n", "tle/rtklib_gnss_20121031/brdc3050.12n")


def _compressed_copies(src: Path, tmp: Path, observation: bool) -> dict[str, Path]:
    """{kind: path} of compressed copies of `src`; names as the archives use them."""
    raw = src.read_bytes()
    stem = src.name
    out = {"gz": (tmp / f"{stem}.gz", gzip.compress(raw)), "bz2": (tmp / f"{stem}.bz2", bz2.compress(raw)),
           "Z": (tmp / f"{stem}.Z", ncompress.compress(raw))}
    if observation:
        crx = hatanaka.rnx2crx(raw)
        d_name = stem[:-1] + "d"   # 07590920.05o -> 07590920.05d, the RINEX 2 name of Compact RINEX
        out.update({"crx": (tmp / (stem + ".crx"), crx), "YYd": (tmp / d_name, crx),
                    "crx.gz": (tmp / (stem + ".crx.gz"), gzip.compress(crx)),
                    "YYd.Z": (tmp / (d_name + ".Z"), ncompress.compress(crx))})
    for path, data in out.values():
        path.write_bytes(data)
    return {k: p for k, (p, _) in out.items()}


def _assert_same_table(a, b) -> None:
    assert len(a) == len(b) > 0
    for name, _ in COLUMNS:
        x, y = getattr(a, name), getattr(b, name)
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), name
        else:
            assert np.array_equal(x, y), name
    assert a.counts == b.counts
    assert [(r.line, r.field, r.reason) for r in a.rejected] == [(r.line, r.field, r.reason) for r in b.rejected]
    assert np.array_equal(a.approx_position_ecef_m, b.approx_position_ecef_m)


@pytest.mark.parametrize("rel", OBS)
def test_compressed_observation_files_read_as_the_plain_file(rel, tmp_path):
    src = shared_file(rel)
    plain = read_rinex_obs(src)
    copies = _compressed_copies(src, tmp_path, observation=True)
    assert set(copies) == {"gz", "bz2", "Z", "crx", "YYd", "crx.gz", "YYd.Z"}
    for kind, path in copies.items():
        table = read_rinex_obs(path)
        _assert_same_table(table, plain)
        assert table.source == str(path), kind   # rejections and messages name the compressed file


@pytest.mark.parametrize("rel", NAV)
def test_compressed_navigation_files_read_as_the_plain_file(rel, tmp_path):
    src = shared_file(rel)
    plain = read_rinex_nav(src)
    for kind, path in _compressed_copies(src, tmp_path, observation=False).items():
        nav = read_rinex_nav(path)
        assert nav.version == plain.version and nav.leap_seconds == plain.leap_seconds, kind
        assert nav.ephemerides.data.tobytes() == plain.ephemerides.data.tobytes(), kind
        assert nav.ephemerides.counts == plain.ephemerides.counts, kind
        assert {k: list(v) for k, v in nav.iono.items()} == {k: list(v) for k, v in plain.iono.items()}, kind


def test_our_unix_compress_copy_is_real_lzw(tmp_path):
    """The .Z copies the tests make are what `compress` writes: gzip -d (its own LZW decoder)
    restores the original bytes."""
    if shutil.which("gzip") is None:
        pytest.skip("gzip not installed")
    src = shared_file(OBS[0])
    path = _compressed_copies(src, tmp_path, observation=False)["Z"]
    out = subprocess.run(["gzip", "-dc", str(path)], check=True, capture_output=True, timeout=60).stdout
    assert out == src.read_bytes()


def test_files_compressed_by_others_decompress_to_their_plain_original():
    """The hatanaka package's sample files: a RINEX 3.01 file (GPS + GLONASS) and copies made by
    the compress, gzip, bzip2 and rnx2crx programs of their authors, not by these tests. (Its one
    epoch line is cut at column 34, so the reader rejects that epoch: the bytes are compared.)"""
    from importlib.resources import files

    from leonav_runtime.gnss.rinex_files import decompress_rinex

    data = Path(str(files("hatanaka.test.data")))
    if not (data / "sample.rnx").is_file():
        pytest.skip(f"the hatanaka package's sample files are not installed at {data}")
    plain = (data / "sample.rnx").read_bytes()
    assert b"RINEX VERSION / TYPE" in plain.splitlines()[0]
    for name in ("sample.rnx.Z", "sample.rnx.gz", "sample.rnx.bz2", "sample.crx", "sample.crx.Z", "sample.crx.gz",
                 "sample.crx.bz2"):
        stored = (data / name).read_bytes()
        assert stored != plain
        # some copies were made from a CRLF text: lines compared (the readers split either way)
        assert decompress_rinex(stored, data / name).splitlines() == plain.splitlines(), name


def _pos_body(path: Path) -> list[str]:
    """The solution lines of a .pos (the header names the input files, which differ)."""
    return [ln for ln in path.read_text().splitlines() if not ln.startswith("%")]


def test_spp_on_compressed_files_gives_the_same_solution(tmp_path, capsys):
    o, n = shared_file(OBS[0]), shared_file(NAV[0])
    obs_copies = _compressed_copies(o, tmp_path, observation=True)
    nav_gz = _compressed_copies(n, tmp_path, observation=False)["gz"]
    assert main(["spp", str(o), "--nav", str(n), "--out", str(tmp_path / "plain")]) == 0
    reference = _pos_body(tmp_path / "plain" / "07590920_05o.pos")
    assert len(reference) == 120
    for kind in ("YYd.Z", "crx.gz", "Z"):
        path = obs_copies[kind]
        out = tmp_path / kind.replace(".", "_")
        assert main(["spp", str(path), "--nav", str(nav_gz), "--out", str(out)]) == 0, kind
        stem = path.name.replace(".", "_")
        assert _pos_body(out / f"{stem}.pos") == reference, kind
    capsys.readouterr()


def _one_line_error(argv: list[str], capsys) -> str:
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert "\n" not in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("kind", ["gz", "bz2", "crx", "crx.gz"])
def test_truncated_compressed_file_is_one_line_naming_the_file(kind, tmp_path, capsys):
    o, n = shared_file(OBS[0]), shared_file(NAV[0])
    path = _compressed_copies(o, tmp_path, observation=True)[kind]
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    err = _one_line_error(["spp", str(path), "--nav", str(n), "--out", str(tmp_path / "out")], capsys)
    assert err.startswith(f"leonav spp: error: {path}: ")
    assert "truncated" in err
    with pytest.raises(UserInputError, match="truncated"):
        read_rinex_obs(path)


def test_corrupt_compressed_files_are_one_line_naming_the_file(tmp_path, capsys):
    o, n = shared_file(OBS[0]), shared_file(NAV[0])
    copies = _compressed_copies(o, tmp_path, observation=True)
    for kind, what in (("gz", "gzip"), ("Z", "unix compress"), ("crx", "Compact RINEX")):
        path = copies[kind]
        data = bytearray(path.read_bytes())
        data[len(data) // 3:len(data) // 3 + 40] = b"\xff" * 40 if kind != "crx" else b"x" * 40
        path.write_bytes(bytes(data))
        err = _one_line_error(["spp", str(path), "--nav", str(n), "--out", str(tmp_path / kind)], capsys)
        assert err.startswith(f"leonav spp: error: {path}: {what}"), err
    nav = _compressed_copies(n, tmp_path, observation=False)["gz"]
    nav.write_bytes(nav.read_bytes()[:100])
    err = _one_line_error(["gnss", "nav", str(nav)], capsys)
    assert f"{nav}: gzip data corrupt or truncated" in err


def test_truncated_unix_compress_file_is_a_cut_rinex_file_rejected_by_line(tmp_path):
    """LZW has no end marker: a .Z cut short is a RINEX text cut short, its last record rejected
    (file and line named) and counted, the epochs before it kept."""
    o = shared_file(OBS[0])
    path = _compressed_copies(o, tmp_path, observation=False)["Z"]
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        table = read_rinex_obs(path)
    plain = read_rinex_obs(o)
    assert 0 < table.counts["epochs"] < plain.counts["epochs"]
    assert table.rejected and all(r.source == str(path) for r in table.rejected)
    kept = np.isin(plain.t_gps_s, table.epochs()[:-1])   # every complete epoch before the cut is identical
    assert np.array_equal(plain.pseudorange_m[kept], table.pseudorange_m[np.isin(table.t_gps_s, table.epochs()[:-1])],
                          equal_nan=True)


def test_zip_archive_is_refused_naming_the_tool(tmp_path, capsys):
    import zipfile

    o = shared_file(OBS[0])
    path = tmp_path / "07590920.05o.zip"
    with zipfile.ZipFile(path, "w") as z:
        z.write(o, o.name)
    err = _one_line_error(["gnss", "obs", str(path)], capsys)
    assert f"{path}: a zip archive" in err and "unzip" in err


@pytest.mark.parametrize("kind", ["gz", "bz2", "Z", "crx.gz"])
def test_expansion_beyond_the_limit_is_refused_in_one_line(kind, tmp_path, capsys, monkeypatch):
    """A small archive that expands past LEONAV_MAX_RINEX_MB (a decompression bomb) is refused
    naming the file and the variable; the same file reads under a higher limit."""
    o, n = shared_file(OBS[0]), shared_file(NAV[0])
    path = _compressed_copies(o, tmp_path, observation=True)[kind]
    size_mb = o.stat().st_size / 2**20   # 0.065 MB
    monkeypatch.setenv("LEONAV_MAX_RINEX_MB", f"{size_mb / 2:.4f}")
    err = _one_line_error(["spp", str(path), "--nav", str(n), "--out", str(tmp_path / "out")], capsys)
    assert err.startswith(f"leonav spp: error: {path}: ") and "LEONAV_MAX_RINEX_MB" in err
    monkeypatch.setenv("LEONAV_MAX_RINEX_MB", f"{size_mb * 1.01:.4f}")
    _assert_same_table(read_rinex_obs(path), read_rinex_obs(o))


def test_gzip_bomb_stops_at_the_limit(tmp_path, monkeypatch):
    """64 MB of zeros in a 64 kB gzip file: refused after 1 MB, without expanding it all."""
    import tracemalloc

    path = tmp_path / "bomb.05o.gz"
    path.write_bytes(gzip.compress(b"0" * (64 * 2**20), compresslevel=9))
    assert path.stat().st_size < 2**17
    monkeypatch.setenv("LEONAV_MAX_RINEX_MB", "1")
    tracemalloc.start()
    with pytest.raises(UserInputError, match="expands to more than 1 MB"):
        read_rinex_obs(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 16 * 2**20


def test_concatenated_gzip_members_read_as_one_file(tmp_path):
    """gzip allows several members one after the other (cat a.gz b.gz): all are read."""
    o = shared_file(OBS[0])
    raw = o.read_bytes()
    cut = raw.index(b"\n", len(raw) // 2) + 1
    path = tmp_path / "two_members.05o.gz"
    path.write_bytes(gzip.compress(raw[:cut]) + gzip.compress(raw[cut:]))
    _assert_same_table(read_rinex_obs(path), read_rinex_obs(o))


def test_bad_limit_value_is_one_line(tmp_path, monkeypatch):
    o = shared_file(OBS[0])
    path = _compressed_copies(o, tmp_path, observation=False)["gz"]
    monkeypatch.setenv("LEONAV_MAX_RINEX_MB", "lots")
    with pytest.raises(UserInputError, match="LEONAV_MAX_RINEX_MB='lots': expected a number of megabytes"):
        read_rinex_obs(path)


def test_compact_rinex_that_crx2rnx_would_skip_is_refused_not_read_short(tmp_path, capsys):
    """A repeated line in a Compact RINEX file: crx2rnx warns and skips every epoch up to the
    next re-initialised one (hundreds of lines); taking its output would drop them uncounted,
    so the file is refused in one line naming it and quoting crx2rnx."""
    o, n = shared_file(OBS[0]), shared_file(NAV[0])
    path = _compressed_copies(o, tmp_path, observation=True)["crx"]
    lines = path.read_bytes().split(b"\n")
    lines.insert(len(lines) // 2, lines[len(lines) // 2])
    path.write_bytes(b"\n".join(lines))
    err = _one_line_error(["spp", str(path), "--nav", str(n), "--out", str(tmp_path / "out")], capsys)
    assert err.startswith(f"leonav spp: error: {path}: Compact RINEX (Hatanaka) data not decoded cleanly: crx2rnx")
    assert "skip" in err


def test_gnss_obs_and_nav_commands_read_compressed_files(tmp_path, capsys):
    """`leonav gnss obs|nav` print the same summary for a compressed file as for the plain one."""
    import json

    o, n = shared_file(OBS[0]), shared_file(NAV[0])
    obs_crx = _compressed_copies(o, tmp_path, observation=True)["YYd.Z"]
    nav_z = _compressed_copies(n, tmp_path, observation=False)["Z"]
    summaries = []
    for path in (o, obs_crx):
        assert main(["gnss", "obs", str(path)]) == 0
        out = capsys.readouterr().out
        summaries.append(json.loads(out[:out.rindex("}") + 1]))
    assert summaries[0] == summaries[1] and summaries[0]["rows"] == 1872
    lines = []
    for path in (n, nav_z):
        assert main(["gnss", "nav", str(path)]) == 0
        lines.append(capsys.readouterr().out.replace(str(path), "FILE"))
    assert lines[0] == lines[1] and "ephemerides" in lines[0]
