"""Earth orientation against skyfield (an independent reader and interpolator of the same IERS
finals2000A table, `tests.eop_reference`), around the three leap seconds of the measured part
of the table (2012-06-30, 2015-06-30, 2016-12-31 23:59:60 UTC) and on ordinary days.

skyfield interpolates TT - UT1 (smooth across a leap second) in TT; leonav unwraps the 1 s
steps of UT1 - UTC and interpolates in UTC. Both are linear between the daily rows, so they
agree to the rounding of the time arguments (measured: 1.1e-8 s in UT1 - UTC, 1.5e-8 arcsec in
the pole coordinates) everywhere, on the leap-second day and at the midnight after it
included.
"""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.orbits import eop

pytest.importorskip("skyfield")
from tests.eop_reference import skyfield_timescale_same_eop  # noqa: E402

UTC = dt.timezone.utc
LEAP_MIDNIGHTS = (dt.datetime(2012, 7, 1, tzinfo=UTC), dt.datetime(2015, 7, 1, tzinfo=UTC),
                  dt.datetime(2017, 1, 1, tzinfo=UTC))


def _times() -> list[dt.datetime]:
    """Each leap-second day at 0 h, 6 h, 12 h, 18 h and 23:59:59, the midnight after it and
    1 ms later, and ordinary instants (not on the hour) over 2012-2018."""
    out = []
    for after in LEAP_MIDNIGHTS:
        day = after - dt.timedelta(days=1)
        out += [day + dt.timedelta(hours=h) for h in (0, 6, 12, 18)]
        out += [after - dt.timedelta(seconds=1), after, after + dt.timedelta(milliseconds=1)]
    start = dt.datetime(2012, 3, 1, 3, 17, 41, tzinfo=UTC)
    out += [start + dt.timedelta(days=37.3 * k) for k in range(60)]
    return out


def _skyfield(times):
    ts = skyfield_timescale_same_eop()
    t = ts.from_datetimes(times)
    _sprime, xp, yp = t.polar_motion_angles()
    return np.asarray(t.dut1, float), np.asarray(xp, float), np.asarray(yp, float)


def test_ut1_utc_and_polar_motion_match_skyfield_across_leap_seconds():
    times = _times()
    table = eop.default_table()
    with warnings.catch_warnings():
        warnings.simplefilter("error", eop.StaleEopWarning)   # all inside the measured table
        ours = [table.at(t) for t in times]
    ut1 = np.array([v.ut1_utc_s[0] for v in ours])
    xp = np.degrees([v.xp_rad[0] for v in ours]) * 3600.0   # rad -> arcsec here, not with eop's constant
    yp = np.degrees([v.yp_rad[0] for v in ours]) * 3600.0
    ref_ut1, ref_xp, ref_yp = _skyfield(times)
    assert np.abs(ut1 - ref_ut1).max() < 1e-7, np.abs(ut1 - ref_ut1).max()
    assert np.abs(xp - ref_xp).max() < 1e-7 and np.abs(yp - ref_yp).max() < 1e-7
    # the physical sizes, so that a unit error cannot hide in a common scale: the pole within
    # 0.6 arcsec, UT1 - UTC within 0.9 s, and +1 s across each leap second
    assert np.abs(xp).max() < 0.6 and np.abs(yp).max() < 0.6 and np.abs(ut1).max() < 0.9
    for after in LEAP_MIDNIGHTS:
        step = table.at(after).ut1_utc_s[0] - table.at(after - dt.timedelta(seconds=1)).ut1_utc_s[0]
        assert step == pytest.approx(1.0, abs=1e-4)


def test_the_midnight_after_a_leap_second_takes_the_new_days_row():
    table = eop.default_table()
    for after in LEAP_MIDNIGHTS:
        row = table.mjd == eop.mjd_utc(after)
        assert row.sum() == 1
        assert table.at(after).ut1_utc_s[0] == pytest.approx(float(table.ut1_utc_s[row][0]), abs=1e-9)


def test_a_time_before_the_table_warns_and_takes_the_first_row():
    table = eop.default_table()
    before = eop.mjd_to_utc(table.mjd[0]) - dt.timedelta(days=30)
    with pytest.warns(eop.StaleEopWarning, match="outside the table"):
        v = table.at(before)
    assert v.ut1_utc_s[0] == pytest.approx(float(table.ut1_utc_s[0]), abs=1e-9)


def test_a_table_with_a_day_twice_is_refused_naming_the_file(tmp_path):
    rows = [line for line in open(eop.default_path()) if line.startswith("26 2")][:4]
    own = tmp_path / "twice.all"
    own.write_text("".join(rows[:3] + [rows[2]] + rows[3:]))   # the third day repeated, as a bad merge writes it
    with pytest.raises(eop.UserInputError, match="twice.all: duplicated MJD"):
        eop.EopTable.load(own)
