"""Broadcast orbit and clock: velocity and drift against differences of position and bias,
group delays per signal, ephemeris selection (fit interval, health, stale, missing) and the
per-observation states. (Positions and clocks against RTKLIB: test_gnss_rtklib.py.)"""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.gen.constants import GPS_L1_HZ, GPS_L2_HZ
from leonav_runtime.gnss.ephemeris import NO_EPHEMERIS, OK, STALE, UNHEALTHY
from leonav_runtime.gnss.observations import ObservationTable
from leonav_runtime.gnss.rinex_nav import parse_rinex_nav, read_rinex_nav
from leonav_runtime.gnss.rinex_obs import read_rinex_obs
from leonav_runtime.gnss.sat_states import states_for_observations
from leonav_runtime.orbits.broadcast import (eccentric_anomaly, group_delay_s, satellite_states,
                                             signal_frequency_hz)
from tests import gnss_rinex3_synth as synth
from tests.conftest import shared_file


def _all_rows():
    gps = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides
    other = parse_rinex_nav(synth.nav_text(), "t").ephemerides
    return gps.concat(other)


def test_velocity_and_drift_are_derivatives_of_position_and_bias():
    eph = _all_rows()
    rows = eph.data
    t = rows["toe"] + 1234.5
    h = 0.5
    mid = satellite_states(rows, t)
    plus, minus = satellite_states(rows, t + h), satellite_states(rows, t - h)
    v_num = (plus.r_ecef_m - minus.r_ecef_m) / (2 * h)
    assert np.max(np.abs(mid.v_ecef_mps - v_num)) < 2e-4  # m/s; GEO (C01) included
    d_num = (plus.clock_bias_s - minus.clock_bias_s) / (2 * h)
    assert np.max(np.abs(mid.clock_drift_sps - d_num)) < 1e-15
    radius = np.linalg.norm(mid.r_ecef_m, axis=1)
    a = rows["sqrt_a"] ** 2
    assert np.all(np.abs(radius - a) < a * rows["e"] + 2000.0)
    gps = rows["system"] == "G"
    assert np.all(np.abs(mid.relativistic_s[gps]) < 50e-9)
    geo = rows["geo"]
    assert geo.sum() == 1 and np.linalg.norm(mid.v_ecef_mps[geo]) < 300.0  # near-stationary in ECEF


def test_kepler_solver():
    m = np.linspace(-7, 7, 101)
    for e in (0.0, 0.01, 0.3):
        ecc = eccentric_anomaly(m, e)
        assert np.max(np.abs(ecc - e * np.sin(ecc) - m)) < 1e-13


def test_group_delays_per_signal():
    rows = _all_rows().data
    sys_prn = list(zip(rows["system"], rows["prn"]))
    g = rows[sys_prn.index(("G", 1))]
    e_inav = rows[sys_prn.index(("E", 11))]   # data sources 517: I/NAV, clock for E1,E5b
    e_fnav = rows[sys_prn.index(("E", 12))]   # data sources 258: F/NAV, clock for E1,E5a
    c = rows[sys_prn.index(("C", 11))]
    assert group_delay_s(g, "1C")[0] == g["tgd"]
    assert group_delay_s(g, "2W")[0] == pytest.approx((GPS_L1_HZ / GPS_L2_HZ) ** 2 * g["tgd"], rel=1e-15)
    assert group_delay_s(e_inav, "1C")[0] == e_inav["tgd2"]
    assert group_delay_s(e_fnav, "1C")[0] == e_fnav["tgd"]
    assert group_delay_s(c, "2I")[0] == c["tgd"] and group_delay_s(c, "7I")[0] == c["tgd2"]
    assert group_delay_s(c, "6I")[0] == 0.0
    f = signal_frequency_hz(["G", "C", "E", "R"], ["1C", "2I", "7Q", "1C"])
    assert f[0] == GPS_L1_HZ and f[1] == 1561.098e6 and f[2] == 1207.14e6 and np.isnan(f[3])


def test_selection_statuses():
    eph = read_rinex_nav(shared_file("tle/rtklib_gnss_20121031/brdc3050.12n")).ephemerides
    t0 = float(np.min(eph["toe"]))
    idx, st = eph.select(["G", "G", "G", "G", "E"], [1, 24, 1, 33, 1], [t0 + 3600, t0 + 3600, t0 + 10 * 86400,
                                                                      t0 + 3600, t0 + 3600])
    assert list(st) == [OK, UNHEALTHY, STALE, NO_EPHEMERIS, NO_EPHEMERIS]
    assert idx[0] >= 0 and np.all(idx[1:] == -1)
    row = eph.data[idx[0]]
    assert abs(row["toe"] - (t0 + 3600)) <= 3600  # nearest toe (2-hourly uploads)
    i2, s2 = eph.select("G", 24, t0 + 3600, allow_unhealthy=True)
    assert s2 == OK and eph.data[i2]["health"] == 63
    _i3, s3 = eph.select("G", 1, t0 + 3 * 3600, max_age_s=600.0)
    assert s3 == STALE
    # vectorized over a day of epochs for all satellites
    tt = t0 + np.arange(0, 86400, 30.0)
    prns = np.repeat(np.arange(1, 33), tt.size)
    i4, s4 = eph.select("G", prns, np.tile(tt, 32))
    assert (s4 == OK).mean() > 0.9


def test_states_for_observations_counts_missing_nav():
    obs = read_rinex_obs(shared_file("gnss_rinex/07590920.05o"))
    nav = read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).ephemerides
    keep = nav.take(nav["prn"] != 7)  # drop the navigation data of one satellite
    st = states_for_observations(obs, keep)
    g07 = obs.prn == 7
    assert np.all(st.status[g07] == NO_EPHEMERIS) and np.all(np.isnan(st.r_ecef_m[g07]))
    assert st.counts["no_ephemeris"] == g07.sum()
    assert st.counts["with_state"] == len(obs) - g07.sum()
    # transmit time is 65-90 ms before reception
    tau = obs.t_gps_s[st.ok] - st.t_tx_gps_s[st.ok]
    assert np.all((tau > 0.06) & (tau < 0.095))
    # L2 rows get gamma * TGD, L1 rows TGD
    l1 = st.ok & (obs.signal == "1C")
    rows = keep.data[st.index[l1]]
    full = satellite_states(rows, st.t_tx_gps_s[l1])
    assert np.allclose(full.clock_bias_s - rows["tgd"], st.clock_s[l1], rtol=0, atol=1e-18)
    nan_pr = ObservationTable(**{**obs.take(slice(0, 3)).column_dict(), "pseudorange_m": [np.nan, 0.0, 2e7]})
    s2 = states_for_observations(nan_pr, nav)
    assert s2.counts["no_pseudorange"] == 1
