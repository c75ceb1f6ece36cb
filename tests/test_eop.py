"""Earth orientation: the IERS table, its interpolation, staleness, and what it does to SGP4.

The reference values are the raw rows of the IERS finals2000A table (read here by column
position, independently of the parser), and skyfield's timescale built from the same
file (`tests.eop_reference`).
"""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.cli import main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import eop, load_elements, propagate_ecef

UTC = dt.timezone.utc


def _raw_row(date: dt.date) -> dict:
    """The finals2000A row of `date` (columns per the IERS ReadMe, 1-based inclusive)."""
    key = f"{date.year % 100:2d}{date.month:2d}{date.day:2d}"
    for line in open(eop.default_path()):
        if line[:6] == key:
            return {"mjd": float(line[7:15]), "ut1": float(line[58:68]), "xp": float(line[18:27]),
                    "yp": float(line[37:46]), "flag": line[57]}
    raise AssertionError(f"no row for {date}")


def test_values_at_midnight_equal_the_table_rows_and_midday_is_their_mean():
    table = eop.default_table()
    day0, day1 = _raw_row(dt.date(2026, 2, 23)), _raw_row(dt.date(2026, 2, 24))
    v = table.at(dt.datetime(2026, 2, 23, tzinfo=UTC), np.array([0.0, 43200.0]))
    assert v.ut1_utc_s[0] == pytest.approx(day0["ut1"], abs=1e-12)
    assert v.xp_rad[0] == pytest.approx(day0["xp"] * eop.ARCSEC_RAD, abs=1e-15)
    assert v.yp_rad[0] == pytest.approx(day0["yp"] * eop.ARCSEC_RAD, abs=1e-15)
    assert v.ut1_utc_s[1] == pytest.approx((day0["ut1"] + day1["ut1"]) / 2, abs=1e-12)
    assert day0["flag"] == "I" and not v.predicted.any()
    # the value the issue measured for that day: UT1-UTC ~ 0.066 s (21 m at Rochester)
    assert 0.05 < v.ut1_utc_s[0] < 0.08


def test_leap_second_day_is_exact_on_both_sides():
    """2016-12-31 23:59:60: UT1-UTC steps from -0.41 to +0.59 s at 2017-01-01 0h."""
    table = eop.default_table()
    before, after = _raw_row(dt.date(2016, 12, 31)), _raw_row(dt.date(2017, 1, 1))
    assert after["ut1"] - before["ut1"] > 0.9  # the leap second is in the table
    v = table.at(dt.datetime(2016, 12, 31, 23, 0, tzinfo=UTC), np.array([0.0, 3599.0, 3600.001, 3601.0]))  # MJD floats resolve ~1 us
    assert np.all(v.ut1_utc_s[:2] < 0) and np.all(v.ut1_utc_s[2:] > 0)
    # continuous apart from the step: neighbours differ by microseconds, not by a second
    assert abs(v.ut1_utc_s[1] - before["ut1"]) < 2e-3 and abs(v.ut1_utc_s[2] - after["ut1"]) < 1e-9


def test_stale_and_out_of_table_requests_warn():
    table = eop.default_table()
    last_measured = eop.mjd_to_utc(table.last_measured_mjd)
    with warnings.catch_warnings():
        warnings.simplefilter("error", eop.StaleEopWarning)
        table.at(last_measured, np.array([0.0, 5 * 86400.0]))  # a few days of predictions: quiet
    with pytest.warns(eop.StaleEopWarning, match="predictions"):
        table.at(last_measured + dt.timedelta(days=eop.PREDICTION_STALE_DAYS + 5))
    with pytest.warns(eop.StaleEopWarning, match="outside the table"):
        v = table.at(eop.mjd_to_utc(table.mjd[-1]) + dt.timedelta(days=400))
    assert v.ut1_utc_s[0] == pytest.approx(table.ut1_utc_s[-1])


def test_bad_tables_are_named_and_rejected(tmp_path, monkeypatch):
    empty = tmp_path / "finals.txt"
    empty.write_text("not an EOP table\n")
    with pytest.raises(UserInputError, match="finals.txt: no EOP rows"):
        eop.EopTable.load(empty)
    with pytest.raises(UserInputError, match="cannot read"):
        eop.EopTable.load(tmp_path / "missing.all")
    # a user table through the environment, with one garbled row counted
    rows = [line for line in open(eop.default_path()) if line.startswith("26 2")][:5]
    rows[2] = rows[2][:60] + "x.xxxxxx" + rows[2][68:]
    own = tmp_path / "own.all"
    own.write_text("".join(rows))
    monkeypatch.setenv(eop.ENV_FILE, str(own))
    table = eop.EopTable.load()
    assert table.source == str(own) and table.mjd.size == 4 and table.rejected_lines == 1


def test_ignoring_earth_orientation_moves_satellites_by_tens_of_metres(shared_data):
    """What the table changes: Starlink ECEF positions at Rochester's epoch move by ~20 m
    (UT1-UTC 0.066 s of rotation at 7.5 km/s orbital speed ~ 30 m at most, plus a few m of
    polar motion); the skyfield agreement to mm is in test_orbits_propagate."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        es = load_elements(shared_data / "tle" / "starlink_2026-02-23.txt").select(np.arange(0, 400, 40))
        epoch = dt.datetime(2026, 2, 23, 12, tzinfo=UTC)
        iers = propagate_ecef(es, epoch, [0.0], acceleration=False)
        none = propagate_ecef(es, epoch, [0.0], ut1_utc_s=0.0, xp_rad=0.0, yp_rad=0.0, acceleration=False)
    d = np.linalg.norm(iers.r_ecef_m - none.r_ecef_m, axis=-1)
    assert 5.0 < d.min() and d.max() < 60.0


def test_eop_command_prints_the_values_in_use(capsys):
    assert main(["eop", "--date", "2026-02-23T00:00:00Z", "--days", "2"]) == 0
    out = capsys.readouterr().out
    row = _raw_row(dt.date(2026, 2, 23))
    assert f"{row['ut1']:.7f}" in out and "IERS measured" in out
    assert main(["eop", "--date", "2026-02-23T00:00:00Z", "--json"]) == 0
    import json
    report = json.loads(capsys.readouterr().out)
    assert report["values"][0]["ut1_utc_s"] == pytest.approx(row["ut1"])
    assert main(["eop", "--date", "yesterday"]) == 2


@pytest.mark.parametrize("argv", [[], ["--date", "2026-02-23T12:00:00.25Z"]])
def test_eop_command_prints_the_time_with_its_utc_offset(argv, capsys):
    """Without --date (now) and with fractional seconds the printed time keeps its +00:00, like --date."""
    assert main(["eop", *argv]) == 0
    lines = capsys.readouterr().out.splitlines()
    row = lines[lines.index(next(l for l in lines if l.startswith("UTC "))) + 1]
    stamp = row.split()[0]
    assert stamp.endswith("+00:00"), row
    assert dt.datetime.fromisoformat(stamp).utcoffset() == dt.timedelta(0)
    if not argv:
        assert abs((dt.datetime.now(UTC) - dt.datetime.fromisoformat(stamp)).total_seconds()) < 120


def test_eop_command_warns_on_stderr_for_a_date_past_the_table(capsys):
    """A date beyond the IERS measurements: one `leonav eop: warning:` line on stderr, the table on stdout."""
    assert main(["eop", "--date", "2030-06-01T00:00:00Z"]) == 0
    cap = capsys.readouterr()
    assert "warning" not in cap.out
    assert [ln for ln in cap.err.splitlines() if ln.startswith("leonav eop: warning: ")], cap.err
