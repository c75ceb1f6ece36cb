"""RINEX navigation reader: real GPS files (RINEX 2.10 GEONET, RINEX 2 IGS brdc), RINEX 3
text (Galileo, BeiDou, GLONASS skipped), georinex as a second reader, bad input and
seeded mutations."""
from __future__ import annotations

import random
import warnings

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.rinex_nav import RejectedRecordsWarning, parse_rinex_nav, read_rinex_nav
from tests import gnss_rinex3_synth as synth
from tests.conftest import shared_file

NAV_FILES = {"gnss_rinex/07590920.05n": 162, "gnss_rinex/30400920.05n": 164,
             "tle/rtklib_gnss_20121031/brdc3050.12n": 423}


@pytest.mark.parametrize("rel,count", NAV_FILES.items())
def test_real_files_read_without_rejections(rel, count):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        nav = read_rinex_nav(shared_file(rel))
    eph = nav.ephemerides
    assert len(eph) == count and not eph.rejected
    assert set(eph["system"]) == {"G"}
    assert nav.iono["GPSA"] and nav.iono["GPSB"]
    assert np.all(np.abs(eph["toe"] - eph["toc"]) < 4 * 3600)
    assert np.all((eph["sqrt_a"] > 5100) & (eph["sqrt_a"] < 5200))  # G24 of 2012 was still drifting: 5176.66


def test_first_record_of_0759_field_by_field():
    eph = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides
    r = eph.data[0]
    assert (r["system"], r["prn"], r["iode"], r["iodc"], r["week"]) == ("G", 1, 140, 396, 1316)
    assert r["toc"] == gtime.calendar_to_seconds(2005, 4, 2, 2, 0, 0.0)
    assert r["toe_sow"] == 525600.0 and r["toe"] == gtime.gps_seconds(1316, 525600.0)
    assert r["af0"] == 3.966595977540e-04 and r["af1"] == 1.705302565820e-12
    assert r["crs"] == -52.1875 and r["m0"] == 2.871534990340 and r["sqrt_a"] == 5.153636478420e+03
    assert r["tgd"] == -3.259629011150e-09 and r["accuracy_m"] == 1.0 and r["health"] == 0
    assert r["transmit"] == gtime.gps_seconds(1316, 519576.0)
    assert r["fit_s"] == 4 * 3600.0  # blank fit interval: 4 h
    assert eph.sources[0].endswith("07590920.05n:13")


def test_agrees_with_georinex_on_the_igs_file():
    gr = pytest.importorskip("georinex")
    path = shared_file("tle/rtklib_gnss_20121031/brdc3050.12n")
    ours = read_rinex_nav(path).ephemerides
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = gr.load(path)
    pairs = {"SVclockBias": "af0", "SVclockDrift": "af1", "Crs": "crs", "DeltaN": "delta_n", "M0": "m0",
             "Cuc": "cuc", "Eccentricity": "e", "Cus": "cus", "sqrtA": "sqrt_a", "Toe": "toe_sow",
             "Cic": "cic", "Omega0": "omega0", "Cis": "cis", "Io": "i0", "Crc": "crc", "omega": "omega",
             "OmegaDot": "omega_dot", "IDOT": "idot", "TGD": "tgd", "IODC": "iodc", "health": "health"}
    times = (ds.time.values - np.datetime64("1980-01-06")).astype("timedelta64[ns]").astype(np.int64) * 1e-9
    sv = [str(s) for s in ds.sv.values]
    n = 0
    for k, r in enumerate(ours.data):
        i = int(np.argmin(np.abs(times - r["toc"])))
        j = sv.index(f"G{r['prn']:02d}")
        for theirs, mine in pairs.items():
            assert float(ds[theirs].values[i, j]) == float(r[mine]), (theirs, k)
        n += 1
    assert n == 423


def test_rinex3_galileo_beidou_and_skipped_glonass():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        nav = parse_rinex_nav(synth.nav_text(), "t.nav")
    eph = nav.ephemerides
    assert nav.version == 3.03 and nav.counts["skipped_R"] == 1
    by = {(s, int(p)): eph.data[k] for k, (s, p) in enumerate(zip(eph["system"], eph["prn"]))}
    assert set(by) == {("E", 11), ("E", 12), ("C", 11), ("C", 1), ("G", 5)}
    e11, c01, c11, g05 = by[("E", 11)], by[("C", 1)], by[("C", 11)], by[("G", 5)]
    # Galileo: GST = GPST; BGDs; data sources; IODnav serves as IODC
    assert e11["toe"] == synth.T_TOE_SYS and e11["tgd"] == 1.2e-9 and e11["tgd2"] == 1.4e-9
    assert e11["data_sources"] == 517 and e11["iodc"] == e11["iode"] == 88
    # BeiDou: BDT + 14 s = GPST; TGD1/TGD2; AODC; GEO flag for C01 only
    assert c11["toe"] == synth.T_TOE_SYS + 14.0 and c11["toc"] == synth.T_TOE_SYS + 14.0
    assert (c11["tgd"], c11["tgd2"], c11["iodc"]) == (4.3e-9, -1.6e-9, 1)
    assert c01["geo"] and not c11["geo"]
    assert g05["iodc"] == 261 and g05["fit_s"] == 4 * 3600


# ------------------------------------------------------------------------- bad input

HEADER2 = "     2.10           N: GPS NAV DATA                         RINEX VERSION / TYPE\n" \
          "                                                            END OF HEADER\n"


def test_unknown_version_names_file_line_and_field():
    text = synth.nav_text().replace("     3.03", "     4.01", 1)
    with pytest.raises(UserInputError, match=r"t\.nav:1: field RINEX VERSION: version 4\.01"):
        parse_rinex_nav(text, "t.nav")
    with pytest.raises(UserInputError, match=r"x:1: field RINEX VERSION: '2\.x'"):
        parse_rinex_nav(HEADER2.replace("     2.10", "      2.x"), "x")
    with pytest.raises(UserInputError, match="GLONASS"):
        parse_rinex_nav(HEADER2.replace("N: GPS NAV", "G: GLO NAV"), "x")
    with pytest.raises(UserInputError, match="not a RINEX file"):
        parse_rinex_nav("hello\n", "x")
    with pytest.raises(UserInputError, match="END OF HEADER"):
        parse_rinex_nav(HEADER2.splitlines()[0] + "\n", "x")
    with pytest.raises(UserInputError, match="not found"):
        read_rinex_nav("/nonexistent/brdc0010.20n")


def _real_text():
    return shared_file("gnss_rinex/07590920.05n").read_text()


def test_garbled_field_rejects_that_record_and_names_line_and_field():
    lines = _real_text().splitlines()
    # record 2 starts at line 21 (1-based); its sqrt(A) is the 4th field of line 3 of the record
    k = 20 + 2
    lines[k] = lines[k][:61] + "5.15373O749130D+03"[:19].ljust(19)[:18] + lines[k][79:]
    with pytest.warns(RejectedRecordsWarning):
        nav = parse_rinex_nav("\n".join(lines), "f.n")
    assert len(nav.ephemerides) == 161
    (rej,) = nav.rejected
    assert (rej.source, rej.line, rej.field) == ("f.n", 23, "sqrt(A)")
    assert "not a number" in rej.reason
    assert str(rej).startswith("f.n:23: sqrt(A): ")


def test_out_of_range_value_truncated_record_and_all_bad():
    lines = _real_text().splitlines()
    lines[22] = lines[22][:61] + " 9.153730749130D+03"  # sqrt(A) 9153: outside 2500..7500
    del lines[30]  # record 3 loses a line
    with pytest.warns(RejectedRecordsWarning):
        nav = parse_rinex_nav("\n".join(lines), "f.n")
    reasons = {(r.line, r.field) for r in nav.rejected}
    assert (23, "sqrt(A)") in reasons
    assert any(f == "record" for _, f in reasons)
    assert len(nav.ephemerides) == 160
    only_bad = HEADER2 + " 1 05  4  2  2  0  0.0 zzz\n"
    with pytest.raises(UserInputError, match="no usable navigation record"):
        parse_rinex_nav(only_bad, "bad.n")


def test_week_written_mod_1024_gives_the_same_epochs():
    text = _real_text()
    lines = text.splitlines()
    for k in range(12, len(lines), 8):  # the week is the 3rd field of orbit line 5
        ln = lines[k + 5]
        lines[k + 5] = ln[:41] + " 2.920000000000D+02" + ln[60:]
    a = parse_rinex_nav(text, "a").ephemerides
    b = parse_rinex_nav("\n".join(lines), "b").ephemerides
    assert np.array_equal(a["toe"], b["toe"]) and np.array_equal(a["toc"], b["toc"])
    assert set(b["week"]) == {292}


def _mutate(text: str, rng: random.Random, header_lines: int) -> tuple[str, int]:
    lines = text.splitlines()
    k = rng.randrange(header_lines, len(lines))
    kind = rng.choice(["char", "delete", "truncate", "duplicate", "garbage"])
    line = lines[k]
    if kind == "char" and line:
        j = rng.randrange(len(line))
        lines[k] = line[:j] + rng.choice("xX?*#-.D 9") + line[j + 1:]
    elif kind == "delete":
        del lines[k]
    elif kind == "truncate":
        lines[k] = line[: rng.randrange(len(line) + 1)]
    elif kind == "duplicate":
        lines.insert(k, line)
    else:
        lines[k] = "".join(rng.choice("ab01 D+-.") for _ in range(rng.randrange(1, 90)))
    return "\n".join(lines) + "\n", k


@pytest.mark.parametrize("seed", range(40))
def test_seeded_mutations_keep_every_untouched_record(seed):
    """One random mutation: the reader returns or raises UserInputError; records whose lines
    were not touched come back exactly as from the clean file."""
    text = _real_text()
    clean = parse_rinex_nav(text, "f").ephemerides
    rng = random.Random(seed)
    mutated, k = _mutate(text, rng, header_lines=12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            nav = parse_rinex_nav(mutated, "f").ephemerides
        except UserInputError:
            return
    touched_record = (k - 12) // 8  # the record holding (or next to) the mutated line
    keys = {(int(r["prn"]), float(r["toe"]), int(r["iode"])): r for r in nav.data}
    lost = 0
    for i, r in enumerate(clean.data):
        key = (int(r["prn"]), float(r["toe"]), int(r["iode"]))
        if key in keys and keys[key].tobytes() == r.tobytes():
            continue
        lost += 1
        assert abs(i - touched_record) <= 1, f"record {i} lost, mutation at line {k + 1}"
    assert lost <= 2
    assert len(nav) + len(nav.rejected) >= len(clean) - 2
    for rej in nav.rejected:
        assert rej.source == "f" and rej.line >= 13 and rej.reason


def test_utc_gps_conversions():
    import datetime as dt
    assert gtime.utc_to_gps_seconds(gtime.gps_seconds_to_utc(1.0e9)) == 1.0e9
    assert gtime.leap_seconds_at_utc(dt.date(2012, 10, 31)) == 16
    assert gtime.leap_seconds_at_utc(dt.date(2005, 4, 2)) == 13
    # the step: 2017-01-01 00:00:00 UTC is GPS 1167264018
    assert gtime.utc_to_gps_seconds(dt.datetime(2017, 1, 1)) == 1167264018.0
    assert gtime.utc_to_gps_seconds(dt.datetime(2016, 12, 31, 23, 59, 59)) == 1167264016.0
    assert gtime.gps_seconds_to_utc(1167264018.0) == dt.datetime(2017, 1, 1, tzinfo=dt.timezone.utc)
    assert gtime.resolve_week(292, 1316) == 1316 and gtime.resolve_week(1316 % 1024, 2100) == 2340
    assert gtime.resolve_week(0, 2047) == 2048 and gtime.resolve_week(1023, 2048) == 2047
