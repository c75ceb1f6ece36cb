"""The on-disk element cache (orbits/element_cache.py): a hit gives the same ElementSet as a
fresh parse, and anything that could make it different is a miss or is ignored."""
from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest

from leonav_runtime.orbits import RejectedElementsWarning, element_cache, load_elements
from leonav_runtime.orbits.tle import format_tle
from tests.conftest import shared_file


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(element_cache.CACHE_ENV, str(folder))
    monkeypatch.setattr(element_cache, "MIN_BYTES", 0)   # the small files below go through it too
    return folder


def _same(a, b) -> None:
    assert a.names == b.names and a.sources == b.sources and a.rejected == b.rejected
    assert np.array_equal(a.norad_ids, b.norad_ids) and a.constellation == b.constellation
    assert a.epochs_utc == b.epochs_utc
    assert all(x.tzinfo is y.tzinfo for x, y in zip(a.epochs_utc, b.epochs_utc))
    for s, t in zip(a.satrecs, b.satrecs):
        assert (s.satnum, s.jdsatepoch, s.jdsatepochF, s.no_kozai, s.ecco, s.inclo, s.bstar, s.mo) == \
               (t.satnum, t.jdsatepoch, t.jdsatepochF, t.no_kozai, t.ecco, t.inclo, t.bstar, t.mo)
    t_min = np.array([0.0, 90.0])
    ra = a.satrec_array.sgp4(a.satrecs[0].jdsatepoch + np.zeros(2), a.satrecs[0].jdsatepochF + t_min / 1440)
    rb = b.satrec_array.sgp4(b.satrecs[0].jdsatepoch + np.zeros(2), b.satrecs[0].jdsatepochF + t_min / 1440)
    assert all(np.array_equal(x, y) for x, y in zip(ra, rb))


def _entry(norad: int, day: float) -> list[str]:
    import datetime as dt

    l1, l2 = format_tle(norad_id=norad, epoch_utc=dt.datetime(2026, 2, 23, tzinfo=dt.timezone.utc)
                        + dt.timedelta(days=day), inclination_deg=53.0, raan_deg=10.0 * norad % 360,
                        eccentricity=1e-4, arg_perigee_deg=90.0, mean_anomaly_deg=3.0 * norad % 360,
                        mean_motion_revday=15.06, bstar_per_earth_radius=1e-4)
    return [f"STARLINK-{norad}", l1, l2]


def test_a_hit_is_the_same_element_set_as_a_fresh_parse(cache, monkeypatch):
    path = shared_file("tle/starlink_2026-02-23.txt")
    monkeypatch.setenv(element_cache.CACHE_ENV, "off")
    fresh = load_elements(path)
    assert not cache.exists()
    monkeypatch.setenv(element_cache.CACHE_ENV, str(cache))
    first = load_elements(path)                       # a miss: parsed, then stored
    assert len(list(cache.glob("*.json"))) == 1
    calls = []
    from leonav_runtime.orbits import elements

    monkeypatch.setattr(elements, "_parse_text", lambda *a: calls.append(a) or pytest.fail("parsed again"))
    second = load_elements(path)                      # a hit: nothing parsed
    assert calls == []
    _same(fresh, first)
    _same(fresh, second)


def test_rejected_entries_and_their_warning_come_back_from_the_cache(cache, tmp_path):
    good, bad = _entry(101, 0.1), _entry(102, 0.2)
    bad[2] = bad[2][:-1] + str((int(bad[2][-1]) + 1) % 10)   # wrong checksum on line 2
    path = tmp_path / "set.tle"
    path.write_text("\n".join(good + bad) + "\n")
    runs = []
    for _ in range(2):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            es = load_elements(path)
        runs.append((es, [str(w.message) for w in caught if w.category is RejectedElementsWarning]))
    (a, wa), (b, wb) = runs
    _same(a, b)
    assert len(a) == 1 and len(a.rejected) == 1 and a.rejected[0].line == 6 and "checksum" in a.rejected[0].reason
    assert wa == wb and len(wa) == 1


def test_changed_bytes_are_a_miss_even_with_the_same_size_and_time(cache, tmp_path):
    path = tmp_path / "set.tle"
    path.write_text("\n".join(_entry(201, 0.1)) + "\n")
    stat = path.stat()
    assert load_elements(path).norad_ids.tolist() == [201]
    path.write_text("\n".join(_entry(202, 0.1)) + "\n")    # same length: only the digits differ
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert path.stat().st_size == stat.st_size
    assert load_elements(path).norad_ids.tolist() == [202]
    assert len(list(cache.glob("*.json"))) == 2


def test_a_damaged_or_disagreeing_entry_is_ignored_and_rewritten(cache, tmp_path):
    path = tmp_path / "set.tle"
    path.write_text("\n".join(_entry(301, 0.1) + _entry(302, 0.3)) + "\n")
    reference = load_elements(path)
    (entry,) = cache.glob("*.json")
    body = json.loads(entry.read_text())
    body["entries"][1][1] = 999                          # lines of 302 stored under another number
    entry.write_text(json.dumps(body))
    _same(reference, load_elements(path))
    assert json.loads(entry.read_text())["entries"][1][1] == 302   # parsed again and rewritten
    for damage in ("{not json", json.dumps({**body, "format": -1}), json.dumps({**body, "entries": [[1, 2]]})):
        entry.write_text(damage)
        _same(reference, load_elements(path))


def test_strict_checksum_off_and_an_unwritable_cache_still_load(cache, tmp_path, monkeypatch):
    path = tmp_path / "set.tle"
    path.write_text("\n".join(_entry(401, 0.1)) + "\n")
    load_elements(path, strict_checksum=False)
    assert not cache.exists()                            # that mode is never cached
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(element_cache.CACHE_ENV, str(blocker / "sub"))   # a folder under a file
    assert load_elements(path).norad_ids.tolist() == [401]


def test_small_files_are_not_cached(cache, tmp_path, monkeypatch):
    monkeypatch.setattr(element_cache, "MIN_BYTES", 64 * 1024)
    path = tmp_path / "set.tle"
    path.write_text("\n".join(_entry(601, 0.1)) + "\n")
    assert load_elements(path).norad_ids.tolist() == [601] and not cache.exists()


def test_the_cache_keeps_at_most_max_entries_files(cache, tmp_path, monkeypatch):
    monkeypatch.setattr(element_cache, "MAX_ENTRIES", 3)
    for k in range(5):
        path = tmp_path / f"s{k}.tle"
        path.write_text("\n".join(_entry(500 + k, 0.1)) + "\n")
        load_elements(path)
    assert len(list(cache.glob("*.json"))) == 3


def test_the_built_in_constellations_text_goes_through_the_cache(cache, monkeypatch):
    import datetime as dt

    from leonav_runtime.orbits import elements
    from leonav_runtime.orbits.constellations import default_elements

    epoch = dt.datetime(2026, 2, 23, 12, tzinfo=dt.timezone.utc)
    monkeypatch.setenv(element_cache.CACHE_ENV, "off")
    fresh = default_elements(epoch)
    monkeypatch.setenv(element_cache.CACHE_ENV, str(cache))
    default_elements(epoch)                           # misses: parsed, then stored (GPS and Starlink)
    assert len(list(cache.glob("*.json"))) == 2
    monkeypatch.setattr(elements, "_parse_text", lambda *a: pytest.fail("parsed again"))
    again = default_elements(epoch)
    for name in ("gps", "starlink"):
        _same(fresh[name], again[name])
