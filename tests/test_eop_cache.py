"""The on-disk cache of the parsed IERS EOP table: same values bit for bit, misses on any change."""
from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from leonav_runtime.orbits import eop

FIELDS = ("mjd", "ut1_utc_s", "xp_arcsec", "yp_arcsec", "measured")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "eop-cache"
    monkeypatch.setenv(eop.CACHE_ENV, str(folder))
    return folder


@pytest.fixture
def table_file(tmp_path):
    path = tmp_path / "finals2000A.all"
    shutil.copyfile(eop.default_path(), path)
    return path


def _parsed(path):
    return eop.EopTable.parse(path.read_bytes().decode("ascii", errors="replace"), str(path))


def _same(a, b):
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name
    assert a.rejected_lines == b.rejected_lines and a.source == b.source


def test_cached_table_is_bit_for_bit_the_parsed_one_and_skips_the_parse(cache, table_file, monkeypatch):
    # one garbled row, so the rejected count goes through the cache too
    lines = table_file.read_text().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if len(line) > 70 and line[58:68].strip())
    lines[i] = lines[i][:60] + "x.xxxxxx" + lines[i][68:]
    table_file.write_text("".join(lines))
    reference = _parsed(table_file)
    assert reference.rejected_lines == 1
    _same(eop.EopTable.load(table_file), reference)
    assert len(list(cache.glob("*.npz"))) == 1

    def no_parse(*args, **kwargs):
        raise AssertionError("parsed although the cache holds this table")
    monkeypatch.setattr(eop.EopTable, "parse", classmethod(no_parse))
    hit = eop.EopTable.load(table_file)
    _same(hit, reference)
    t = np.linspace(0, 86400.0 * 365, 97)
    start = eop.mjd_to_utc(reference.mjd[100])
    for a, b in zip(hit.at(start, t, warn=False).__dict__.values(), reference.at(start, t, warn=False).__dict__.values()):
        assert np.array_equal(a, b)


def test_edited_table_is_parsed_again_whatever_its_time_stamp(cache, table_file):
    original = eop.EopTable.load(table_file)
    st = table_file.stat()
    data = bytearray(table_file.read_bytes())
    lines = data.decode().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if len(line) > 70 and line[58:68].strip() and line[61] != "9")
    offset = sum(len(line) for line in lines[:i]) + 61
    data[offset:offset + 1] = b"9"                      # one UT1-UTC digit, same size
    table_file.write_bytes(bytes(data))
    os.utime(table_file, ns=(st.st_atime_ns, st.st_mtime_ns))
    edited = eop.EopTable.load(table_file)
    _same(edited, _parsed(table_file))
    assert not np.array_equal(edited.ut1_utc_s, original.ut1_utc_s)
    assert len(list(cache.glob("*.npz"))) == 2


def test_damaged_or_wrong_entries_are_ignored_and_rewritten(cache, table_file):
    reference = _parsed(table_file)
    eop.EopTable.load(table_file)
    (entry,) = cache.glob("*.npz")
    good = entry.read_bytes()
    key = entry.stem
    bad_arrays = dict(key=np.array(key), measured=reference.measured, rejected_lines=np.array(0),
                      mjd=reference.mjd[::-1].copy(), ut1_utc_s=reference.ut1_utc_s,
                      xp_arcsec=reference.xp_arcsec, yp_arcsec=reference.yp_arcsec)
    other_key = dict(bad_arrays, key=np.array("0" * 64), mjd=reference.mjd)
    short = dict(bad_arrays, mjd=reference.mjd, ut1_utc_s=reference.ut1_utc_s[:-1])
    for damage in (b"", b"not a zip", good[: len(good) // 2], bad_arrays, other_key, short):
        if isinstance(damage, dict):
            with open(entry, "wb") as fh:
                np.savez(fh, **damage)
        else:
            entry.write_bytes(damage)
        _same(eop.EopTable.load(table_file), reference)
        assert entry.read_bytes() == good   # rewritten whole
    assert not list(cache.glob(".*.tmp"))


def test_small_files_and_cache_off_are_parsed_directly(cache, table_file, tmp_path, monkeypatch):
    small = tmp_path / "small.all"
    small.write_text("".join(table_file.read_text().splitlines(keepends=True)[:50]))
    _same(eop.EopTable.load(small), _parsed(small))
    assert not cache.exists()
    monkeypatch.setenv(eop.CACHE_ENV, "off")
    _same(eop.EopTable.load(table_file), _parsed(table_file))
    assert not cache.exists()


def test_at_most_max_entries_are_kept(cache, table_file, monkeypatch):
    monkeypatch.setattr(eop, "CACHE_MAX_ENTRIES", 2)
    text = table_file.read_text()
    for n in range(4):
        table_file.write_text(text + " " * n + "\n")   # different bytes, same rows
        eop.EopTable.load(table_file)
    assert len(list(cache.glob("*.npz"))) == 2
