"""Element loading: real CelesTrak files, SupGP, odd spacing, OMM, and corrupted input."""
from __future__ import annotations

import datetime as dt
import json
import warnings

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import (
    ElementSet,
    RejectedElementsWarning,
    load_elements,
    parse_elements_text,
    propagate_teme,
)
from leonav_runtime.orbits.tle import checksum, format_tle, parse_fields
from tests.conftest import shared_file

UTC = dt.timezone.utc


def _lines(path) -> list[str]:
    return path.read_text().splitlines()


def test_real_celestrak_files_load_completely():
    for name, count, group in (("tle/starlink_2026-02-23.txt", 9543, "starlink"),
                               ("tle/gps-ops_2026-03-09.txt", 32, "gps")):
        es = load_elements(shared_file(name))
        assert len(es) == count and es.rejected == [] and es.constellation == group
        assert len(set(es.norad_ids.tolist())) == count
    es = load_elements(shared_file("tle/gps-ops_2026-03-09.txt"))
    assert es.names[0] == "GPS BIIR-2  (PRN 13)" and es.norad_ids[0] == 24876
    # 26068.48567624 = 2026-03-09 + 0.48567624 d
    expected = dt.datetime(2026, 3, 9, tzinfo=UTC) + dt.timedelta(days=0.48567624)
    assert abs((es.epochs_utc[0] - expected).total_seconds()) < 1e-5
    assert es.sources[0].endswith("gps-ops_2026-03-09.txt:2")
    assert es.satrecs[0].satnum == 24876


def test_supgp_classification_c_and_small_element_numbers():
    es = load_elements(shared_file("tle/starlink_supgp_2026-05-13.txt"))
    assert len(es) == 10361 and es.rejected == []
    assert es.satrecs[0].classification == "C"
    assert es.epochs_utc[0].date() == dt.date(2026, 5, 12)


def test_str3_test_set_with_nonstandard_spacing():
    es = load_elements(shared_file("sgp4/rtklib_tle_sgp4_str3.txt"))
    assert len(es) == 1 and es.names == ["TEST_SAT"] and es.norad_ids[0] == 88888
    f = parse_fields(*_lines(shared_file("sgp4/rtklib_tle_sgp4_str3.txt"))[1:3])
    assert f.intl_designator == "" and f.element_number == 8 and f.rev_number == 105
    assert f.nddot_revday3 == pytest.approx(0.13844e-3) and f.bstar_per_earth_radius == pytest.approx(0.66816e-4)
    assert f.eccentricity == pytest.approx(0.0086731)


def test_two_line_files_without_names_and_ages():
    lines = _lines(shared_file("tle/gps-ops_2026-03-09.txt"))
    two_line = "\n".join(l for i, l in enumerate(lines) if i % 3) + "\n"
    es = parse_elements_text(two_line, "gps2.txt")
    assert len(es) == 32 and es.names[0] == "24876" and es.constellation == "unknown"
    ages = es.ages_s(es.epochs_utc[0] + dt.timedelta(days=1))
    assert ages[0] == pytest.approx(86400.0, abs=1e-4)


def test_space_track_3le_name_lines_with_zero_prefix():
    lines = _lines(shared_file("tle/gps-ops_2026-03-09.txt"))[:6]
    text = "\n".join("0 " + l.strip() if i % 3 == 0 else l for i, l in enumerate(lines))
    es = parse_elements_text(text, "spacetrack.3le")
    assert es.names == ["GPS BIIR-2  (PRN 13)", "GPS BIIR-5  (PRN 22)"] and es.rejected == []


def test_select_and_concat():
    es = load_elements(shared_file("tle/gps-ops_2026-03-09.txt"))
    sub = es.select(np.arange(len(es)) % 2 == 0)
    assert len(sub) == 16 and sub.names[1] == es.names[2]
    both = sub.concat(es.select([1, 3]))
    assert isinstance(both, ElementSet) and len(both) == 18
    assert both.norad_ids[-1] == es.norad_ids[3] and both.constellation == "gps"


# ---------------------------------------------------------------- corrupted input


def _write(tmp_path, lines: list[str], name: str = "bad.txt"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _fix_checksum(line: str) -> str:
    return line[:68] + str(checksum(line))


@pytest.fixture
def gps_lines():
    return _lines(shared_file("tle/gps-ops_2026-03-09.txt"))[:15]  # 5 satellites, 3LE


@pytest.mark.parametrize(
    "corrupt, line_no, words",
    [
        # flip a digit of the mean anomaly of entry 2 (file line 6): checksum breaks
        (lambda L: L.__setitem__(5, L[5][:45] + ("1" if L[5][45] != "1" else "2") + L[5][46:]), 6,
         "bad checksum on line 2"),
        # cut line 1 of entry 3 (file line 8)
        (lambda L: L.__setitem__(7, L[7][:50]), 8, "truncated line 1: 50 characters"),
        # line number of entry 4's line 2 (file line 12) becomes '3'
        (lambda L: L.__setitem__(11, "3" + L[11][1:]), 12, "wrong line number '3'"),
        # inclination of entry 5 (file line 15) gets letters; checksum made valid again
        (lambda L: L.__setitem__(14, _fix_checksum(L[14][:8] + " 5x.abcd" + L[14][16:])), 15,
         "non-numeric field inclination (columns 9-16)"),
        # catalog number of entry 1's line 2 changed (checksum fixed)
        (lambda L: L.__setitem__(2, _fix_checksum(L[2][:2] + "24877" + L[2][7:])), 3,
         "catalog number mismatch: line 1 has 24876, line 2 has 24877"),
    ],
)
def test_one_bad_entry_is_reported_and_the_rest_load(tmp_path, gps_lines, corrupt, line_no, words):
    lines = list(gps_lines)
    corrupt(lines)
    path = _write(tmp_path, lines)
    with pytest.warns(RejectedElementsWarning, match=rf"rejected 1 of 5 entries \(lines {line_no}\)"):
        es = load_elements(path)
    assert len(es) == 4
    assert len(es.rejected) == 1
    rej = es.rejected[0]
    assert rej.line == line_no and words in rej.reason and rej.source == str(path)
    assert str(path) in str(rej) and f":{line_no}" in str(rej)


def test_wrong_line_number_on_line_1_is_one_rejection(tmp_path, gps_lines):
    lines = list(gps_lines)
    lines[4] = "7" + lines[4][1:]  # entry 2, line 1
    with pytest.warns(RejectedElementsWarning):
        es = load_elements(_write(tmp_path, lines))
    assert len(es) == 4 and [r.line for r in es.rejected] == [5]
    assert "wrong line number '7': expected line 1" in es.rejected[0].reason
    assert es.rejected[0].name == "GPS BIIR-5  (PRN 22)"


def test_several_bad_entries_counted_with_line_numbers(tmp_path, gps_lines):
    lines = list(gps_lines)
    lines[1] = lines[1][:68] + str((int(lines[1][68]) + 1) % 10)  # bad checksum, line 2
    lines[10] = lines[10][:30]  # truncated line 1 of entry 4, line 11
    with pytest.warns(RejectedElementsWarning, match=r"rejected 2 of 5 entries \(lines 2, 11\)"):
        es = load_elements(_write(tmp_path, lines))
    assert len(es) == 3 and [r.line for r in es.rejected] == [2, 11]
    assert es.names == [gps_lines[3].strip(), gps_lines[6].strip(), gps_lines[12].strip()]


def test_line_1_without_line_2_and_orphan_line_2(tmp_path, gps_lines):
    lines = list(gps_lines)
    del lines[5]  # entry 2 loses its line 2
    del lines[6]  # entry 3 loses its line 1 (was index 7)
    with pytest.warns(RejectedElementsWarning):
        es = load_elements(_write(tmp_path, lines))
    assert len(es) == 3
    reasons = [r.reason for r in es.rejected]
    assert len(reasons) == 2
    assert "line 1 is not followed by line 2" in reasons[0] and "line 2 without a line 1" in reasons[1]


def test_empty_and_all_bad_files_raise_naming_the_file(tmp_path, gps_lines):
    empty = _write(tmp_path, [""], "empty.txt")
    with pytest.raises(UserInputError, match=r"empty\.txt: empty element file"):
        load_elements(empty)
    garbage = _write(tmp_path, ["<html>", "<body>Service unavailable</body>", "</html>"], "page.txt")
    with pytest.raises(UserInputError, match=r"page\.txt: no valid TLE/3LE element set"):
        load_elements(garbage)
    all_bad = _write(tmp_path, [l[:60] if l.startswith("1 ") else l for l in gps_lines], "cut.txt")
    with pytest.raises(UserInputError, match=r"cut\.txt: no valid .*:2 .*truncated line 1.*and 2 more"):
        load_elements(all_bad)
    with pytest.raises(UserInputError, match="not found"):
        load_elements(tmp_path / "missing.txt")


# ---------------------------------------------------------------- Vallado's set, OMM


def test_vallado_verification_file_loads_with_its_edited_checksums_reported():
    path = shared_file("sgp4/SGP4-VER.TLE")
    with pytest.warns(RejectedElementsWarning, match=r"rejected 3 of 33 entries \(lines 100, 103, 106\)"):
        strict = load_elements(path)
    assert len(strict) == 30 and all("bad checksum" in r.reason for r in strict.rejected)
    with pytest.warns(RejectedElementsWarning, match="3 entries loaded despite a bad checksum"):
        relaxed = load_elements(path, strict_checksum=False)
    assert len(relaxed) == 33 and relaxed.rejected == []
    assert relaxed.norad_ids[:3].tolist() == [5, 4632, 6251]


def _omm_row(path) -> dict[str, str]:
    header, row = path.read_text().splitlines()[:2]
    return dict(zip(header.split(","), row.split(",")))


def test_omm_csv_matches_the_same_elements_written_as_tle(tmp_path):
    path = shared_file("sgp4/sample_omm.csv")
    omm = load_elements(path)
    assert len(omm) == 1 and omm.names == ["VANGUARD 1"] and omm.norad_ids[0] == 5
    assert omm.epochs_utc[0] == dt.datetime(2020, 10, 13, 4, 52, 48, 472320, tzinfo=UTC)
    f = _omm_row(path)
    line1, line2 = format_tle(
        norad_id=5, epoch_utc=omm.epochs_utc[0], inclination_deg=float(f["INCLINATION"]),
        raan_deg=float(f["RA_OF_ASC_NODE"]), eccentricity=float(f["ECCENTRICITY"]),
        arg_perigee_deg=float(f["ARG_OF_PERICENTER"]), mean_anomaly_deg=float(f["MEAN_ANOMALY"]),
        mean_motion_revday=float(f["MEAN_MOTION"]), bstar_per_earth_radius=float(f["BSTAR"]),
        ndot_revday2=float(f["MEAN_MOTION_DOT"]), nddot_revday3=float(f["MEAN_MOTION_DDOT"]),
        intl_designator="58002B", element_number=999, rev_number=21814,
    )
    tle = parse_elements_text(f"VANGUARD 1\n{line1}\n{line2}\n", "vanguard.tle")
    assert "-22483-4" in line1 and "-.00000016" in line1
    t_s = np.linspace(0.0, 2 * 86400.0, 9)
    _, r_omm, v_omm = propagate_teme(omm, omm.epochs_utc[0], t_s)
    _, r_tle, v_tle = propagate_teme(tle, omm.epochs_utc[0], t_s)
    assert np.max(np.linalg.norm(r_omm - r_tle, axis=-1)) * 1e3 < 0.1  # m
    assert np.max(np.linalg.norm(v_omm - v_tle, axis=-1)) * 1e3 < 1e-4  # m/s


def test_omm_json_and_xml_like_celestrak(tmp_path):
    fields = _omm_row(shared_file("sgp4/sample_omm.csv"))
    text_keys = ("OBJECT_NAME", "OBJECT_ID", "EPOCH", "CLASSIFICATION_TYPE")
    int_keys = ("NORAD_CAT_ID", "ELEMENT_SET_NO", "REV_AT_EPOCH", "EPHEMERIS_TYPE")
    numeric = {k: v if k in text_keys else int(v) if k in int_keys else float(v) for k, v in fields.items()}
    broken = dict(numeric, MEAN_MOTION="fast", OBJECT_NAME="BROKEN")
    (tmp_path / "gp.json").write_text(json.dumps([numeric, broken]))
    with pytest.warns(RejectedElementsWarning):
        js = load_elements(tmp_path / "gp.json")
    assert len(js) == 1 and js.rejected[0].line == 2
    assert "record 2: non-numeric field MEAN_MOTION" in js.rejected[0].reason
    items = "".join(f"<{k}>{v}</{k}>" for k, v in fields.items())
    xml = ('<?xml version="1.0" encoding="UTF-8"?><ndm><omm id="CCSDS_OMM_VERS" version="2.0"><header/>'
           f'<body><segment><metadata/><data>{items}</data></segment></body></omm></ndm>')
    (tmp_path / "gp.xml").write_text(xml)
    xm = load_elements(tmp_path / "gp.xml")
    csv = load_elements(shared_file("sgp4/sample_omm.csv"))
    for other in (js, xm):
        _, r1, _ = propagate_teme(other, csv.epochs_utc[0], [0.0, 3600.0])
        _, r2, _ = propagate_teme(csv, csv.epochs_utc[0], [0.0, 3600.0])
        np.testing.assert_allclose(r1, r2, atol=1e-9)
    missing = dict(numeric)
    del missing["INCLINATION"]
    (tmp_path / "gp2.json").write_text(json.dumps([missing]))
    with pytest.raises(UserInputError, match=r"gp2\.json: no valid OMM JSON.*missing field INCLINATION"):
        load_elements(tmp_path / "gp2.json")


def test_warnings_can_be_silenced_but_rejections_stay_counted(tmp_path, gps_lines):
    lines = list(gps_lines)
    lines[2] = lines[2][:68] + str((int(lines[2][68]) + 3) % 10)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(RejectedElementsWarning):
            load_elements(_write(tmp_path, lines))
        warnings.simplefilter("ignore")
        assert len(load_elements(_write(tmp_path, lines)).rejected) == 1


def test_the_constellation_is_what_at_least_90_percent_of_the_names_say():
    from leonav_runtime.orbits.element_checks import guess_constellation

    starlink = [f"STARLINK-{k}" for k in range(9)]
    assert guess_constellation(starlink + ["ONEWEB-0012"]) == "starlink"         # 9 of 10
    assert guess_constellation(starlink[:8] + ["ONEWEB-1", "X"]) == "unknown"   # 8 of 10
    assert guess_constellation(["starlink-1007 [dtc]"]) == "starlink"            # any case, anywhere
    assert guess_constellation(["GPS BIIR-2  (PRN 13)", "NAVSTAR 43 (USA 132)"]) == "gps"
    assert guess_constellation(["GPS+BIIR"] * 9 + ["NAV"]) == "gps"
    assert guess_constellation(["GLONASS"]) == "unknown" and guess_constellation([]) == "unknown"
