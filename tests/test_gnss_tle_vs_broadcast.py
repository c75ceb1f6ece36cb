"""GPS TLEs (SGP4) against the broadcast orbits of the same day (2012-10-31, IGS brdc).

Measured on 2026-11-30 (5-min grid over the GPS day, 30 healthy satellites, TLE epochs
0-1.75 days from the grid start): overall RMS radial 1.18 km, along-track 4.77 km,
cross-track 0.86 km, 3-D 4.99 km; largest 3-D error 15.2 km (G15). The test holds the
numbers to that order: km-level, dominated by along-track.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.gnss.tle_vs_broadcast import compare, format_table, gps_prn_from_name, main
from tests.conftest import shared_file


def test_tle_error_against_broadcast_is_km_level_along_track():
    tle = shared_file("tle/rtklib_gnss_20121031/TLE_GNSS_20121101.txt")
    nav = shared_file("tle/rtklib_gnss_20121031/brdc3050.12n")
    errors = compare(tle, nav, step_s=300.0)
    rows = {r["sat"]: r for r in errors.stats()}
    overall = rows["all"]
    assert len(rows) - 1 >= 28  # satellites with both orbits (G24, G27: unhealthy all day)
    assert overall["n"] >= 28 * 288
    assert 1000.0 < overall["rms_a_m"] < 8000.0
    assert 300.0 < overall["rms_r_m"] < 2000.0
    assert 300.0 < overall["rms_c_m"] < 2000.0
    assert overall["rms_a_m"] > overall["rms_r_m"] and overall["rms_a_m"] > overall["rms_c_m"]
    assert overall["max_3d_m"] < 20000.0
    # no satellite is hundreds of km off (a wrong PRN match or a GPST/UTC mix-up would be)
    assert max(r["max_3d_m"] for r in rows.values()) < 20000.0
    # UTC vs GPST matters: 16 s of along-track motion (62 km) would show up
    assert abs(np.nanmean(errors.rtn_m[..., 1])) < 3000.0
    assert "all" in format_table(errors.stats())


def test_prn_from_names():
    assert gps_prn_from_name("G05") == 5 and gps_prn_from_name("GPS BIIRM-8 (PRN 05)") == 5
    assert gps_prn_from_name("NAVSTAR 57 (USA 183)") is None and gps_prn_from_name("R08") is None


def test_main_prints_the_table(capsys):
    tle = shared_file("tle/rtklib_gnss_20121031/TLE_GNSS_20121101.txt")
    nav = shared_file("tle/rtklib_gnss_20121031/brdc3050.12n")
    assert main([str(tle), str(nav), "--step", "1800"]) == 0
    out = capsys.readouterr().out
    assert "rms A" in out and "\n all " in out and " G01 " in out
