"""Hostile element files: deep nesting, huge fields and ids, NaN elements, huge files.

Each case used to end in a traceback, a hang or gigabytes of memory; now it is a counted
rejection naming file/line/field, or one UserInputError line. Every case is small and
bounded in time (`bounded` fails the test instead of hanging).
"""
from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest

from leonav_runtime.cli import main as leonav_main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import load_elements, parse_elements_text
from leonav_runtime.orbits import tle as tle_mod
MAX_ELEMENT_MB_ENV = "LEONAV_MAX_ELEMENT_MB"  # documented in orbits/elements.py and `leonav --help`
from tests.conftest import shared_file
from tests.timebox import bounded



def _omm_csv() -> tuple[str, list[str], list[str]]:
    lines = shared_file("sgp4/sample_omm.csv").read_text().splitlines()
    return lines[0], lines[0].split(","), lines[1].split(",")


def _gps_lines() -> list[str]:
    return shared_file("tle/gps-ops_2026-03-09.txt").read_text().splitlines()


def _with_checksum(line: str) -> str:
    return line[:68] + str(tle_mod.checksum(line))


def _quiet_parse(text: str, source: str = "<hostile>"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parse_elements_text(text, source)


def test_json_nested_100000_deep_is_one_clear_error():
    text = "[" * 100_000 + "]" * 100_000
    with bounded(10), pytest.raises(UserInputError, match=r"deep\.json: no valid OMM JSON.*nested too deeply"):
        _quiet_parse(text, "deep.json")


def test_json_value_nested_inside_a_record_is_a_counted_rejection():
    header, keys, row = _omm_csv()
    good = dict(zip(keys, row))
    bad = dict(good, MEAN_MOTION=[[[1.0]]], OBJECT_NAME="NESTED")
    es = _quiet_parse(json.dumps([good, bad, good]), "n.json")
    assert len(es) == 2 and len(es.rejected) == 1
    assert es.rejected[0].line == 2 and "field MEAN_MOTION is an array" in es.rejected[0].reason


def test_xml_nested_100000_deep_is_one_clear_error():
    text = "<ndm><omm>" + "<a>" * 100_000 + "</a>" * 100_000 + "</omm></ndm>"
    with bounded(10), pytest.raises(UserInputError, match=r"deep\.xml: no valid OMM XML.*nested deeper than 64"):
        _quiet_parse(text, "deep.xml")


def test_xml_nested_segments_are_not_quadratic():
    # 8,000 nested <segment>s took 12.7 s (each record walked the whole subtree below it)
    n = 8000
    text = "<ndm>" + "<segment><x>1</x>" * n + "</segment>" * n + "</ndm>"
    with bounded(5), pytest.raises(UserInputError, match="nested deeper than 64"):
        _quiet_parse(text, "segments.xml")


def test_csv_field_over_128_kb_is_a_counted_rejection_naming_the_line():
    header, keys, row = _omm_csv()
    big = list(row)
    big[keys.index("OBJECT_NAME")] = "X" * 200_000
    text = "\n".join([header, ",".join(row), ",".join(big), ",".join(row)]) + "\n"
    es = _quiet_parse(text, "big.csv")
    assert len(es) == 2 and len(es.rejected) == 1
    rej = es.rejected[0]
    assert rej.source == "big.csv" and rej.line == 3 and "field larger than field limit" in rej.reason


def test_norad_id_of_10_to_the_30_is_a_counted_rejection():
    header, keys, row = _omm_csv()
    huge = list(row)
    huge[keys.index("NORAD_CAT_ID")] = "1" + "0" * 30
    es = _quiet_parse("\n".join([header, ",".join(row), ",".join(huge)]) + "\n", "ids.csv")
    assert len(es) == 1 and len(es.rejected) == 1
    assert es.rejected[0].line == 3 and "NORAD_CAT_ID" in es.rejected[0].reason
    assert "out of range" in es.rejected[0].reason
    # the same id as a JSON number
    good = dict(zip(keys, row))
    js = _quiet_parse(json.dumps([dict(good, NORAD_CAT_ID=10**30), good]), "ids.json")
    assert len(js) == 1 and "NORAD_CAT_ID" in js.rejected[0].reason and js.rejected[0].line == 1


def test_nan_mean_motion_in_a_tle_is_rejected_with_the_field_named():
    lines = _gps_lines()
    lines[5] = _with_checksum(lines[5][:52] + "        nan" + lines[5][63:])  # line 2 of the second entry
    es = _quiet_parse("\n".join(lines) + "\n", "nan.tle")
    assert len(es) == 31 and len(es.rejected) == 1
    rej = es.rejected[0]
    assert rej.line == 6 and "mean motion (line 2, columns 53-63) is nan" in rej.reason
    lines[5] = _with_checksum(lines[5][:53] + "inf".rjust(10) + lines[5][63:])
    assert "is inf" in _quiet_parse("\n".join(lines) + "\n").rejected[0].reason


def test_sky_never_reports_a_nan_satellite_as_fine(tmp_path, capsys):
    lines = _gps_lines()
    lines[2] = _with_checksum(lines[2][:52] + "        nan" + lines[2][63:])
    path = tmp_path / "nan.tle"
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "o"
    assert leonav_main(["sky", "--tle", str(path), "--duration", "20", "--step", "10", "--out", str(out)]) == 0
    summary = json.loads((out / "sky.json").read_text())
    assert summary["satellites"]["gps"]["loaded"] == 31
    assert summary["elements"][0]["rejected_entries"] == 1


def test_element_file_over_the_limit_is_refused_before_reading(tmp_path, monkeypatch, capsys):
    # a 200 MB file took 2.4 GB; now anything over 64 MB is refused unread (a sparse file: no disk)
    path = tmp_path / "huge.tle"
    with open(path, "wb") as fh:
        fh.truncate(200_000_000)
    with bounded(5), pytest.raises(UserInputError, match=rf"huge\.tle: 200\.0 MB is more than .* 64 MB.*{MAX_ELEMENT_MB_ENV}"):
        load_elements(path)
    assert leonav_main(["tle", "info", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("leonav tle info: error: ") and MAX_ELEMENT_MB_ENV in err[0]
    # the limit can be lowered or raised by the user
    small = tmp_path / "gps.tle"
    small.write_bytes(shared_file("tle/gps-ops_2026-03-09.txt").read_bytes())
    monkeypatch.setenv(MAX_ELEMENT_MB_ENV, "0.001")
    with pytest.raises(UserInputError, match="limit of 0.001 MB"):
        load_elements(small)
    with pytest.raises(UserInputError, match="limit of 0.001 MB"):
        parse_elements_text(small.read_text(), str(small))
    monkeypatch.setenv(MAX_ELEMENT_MB_ENV, "1")
    assert len(load_elements(small)) == 32
    monkeypatch.setenv(MAX_ELEMENT_MB_ENV, "lots")
    with pytest.raises(UserInputError, match=f"{MAX_ELEMENT_MB_ENV}='lots': expected a positive number"):
        load_elements(small)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_a_device_that_never_ends_is_read_only_up_to_the_limit(monkeypatch):
    monkeypatch.setenv(MAX_ELEMENT_MB_ENV, "1")
    with bounded(5), pytest.raises(UserInputError, match="more than the element-file limit of 1 MB"):
        load_elements("/dev/zero")


def test_cli_reports_hostile_element_files_in_one_line(tmp_path, capsys):
    cases = {
        "deep.json": "[" * 100_000 + "]" * 100_000,
        "deep.xml": "<ndm><omm>" + "<a>" * 100_000 + "</a>" * 100_000 + "</omm></ndm>",
        "bytes.tle": "\udcff",  # replaced below by raw non-UTF-8 bytes
    }
    for name, text in cases.items():
        path = tmp_path / name
        if name == "bytes.tle":
            path.write_bytes(b"\xff\xfe\x00garbage\n1 \x80\x81\n")
        else:
            path.write_text(text)
        with bounded(10):
            rc = leonav_main(["tle", "info", str(path), "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and err[0].startswith(f"leonav tle info: error: {path}"), err


def test_sky_counts_non_finite_positions_as_sgp4_failures():
    # defence behind the element checks: a propagator that returns NaN with no error code
    from leonav_runtime.sky import view as sky
    from tests.test_sky import EPOCH, SITE, T_S, FakeElements, fake_propagate, fixed

    def nan_propagate(elements, epoch_utc, t_s):
        states = fake_propagate(elements, epoch_utc, t_s)
        states.r_ecef_m[0, 3:] = np.nan  # satellite 0 goes NaN at epoch 3, "ok" all along
        return states

    starlink = FakeElements(["NAN-SAT", "FINE"], [fixed(0, 80), fixed(90, 60)])
    view = sky.sky_view({"starlink": starlink}, SITE, EPOCH, T_S, propagate=nan_propagate)
    s = sky.summarize(view)
    assert s["satellites"]["starlink"]["sgp4_failed"] == 1
    failure = s["left_out"]["starlink"]["sgp4_failures"][0]
    assert failure["name"] == "NAN-SAT" and "non-finite position" in failure["reason"] and "t = 30 s" in failure["reason"]
    assert list(view.constellations["starlink"].count) == [2, 2, 2, 1, 1, 1, 1]
