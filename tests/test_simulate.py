"""Simulator: truth through the generated mechanization, measurement generation, satellite rules."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from leonav_runtime.orbits import geometry
from leonav_runtime.simulation import simulate
from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core.filter import EKF
from leonav_runtime.scenarios.load import MODES, load_scenario, scenario_from_dict
from leonav_runtime.simulation.trajectory import motion

C = 299_792_458.0
W_E = 7.2921151467e-5  # rad/s, Earth rotation rate (WGS84)


def _scenario(name="paper", **changes):
    raw = copy.deepcopy(load_scenario(name).raw)
    for dotted, value in changes.items():
        section, key = dotted.split("__")
        raw.setdefault(section, {})[key] = value
    return scenario_from_dict(raw, source=f"<{name} test>")


@pytest.fixture(scope="module")
def paper_setup():
    scn = _scenario(time__duration_s=6.0, starlink__counts=[5, 45])
    setup, nav = mc.setup_for(scn)
    return scn, setup, nav


def test_static_truth_stays_put_and_vessel_truth_follows_its_manoeuvres(paper_setup):
    scn, setup, nav = paper_setup
    assert np.max(np.abs(setup.x_true[:, 0:6])) < 1e-9
    sea = _scenario("maritime-outage", time__duration_s=40.0, gps__outages_s=[[10.0, 20.0]],
                    trajectory__maneuvers=[[20.0, 0.0, 0.0], [20.0, 0.1, 3.0]])
    sea_setup, sea_nav = mc.setup_for(sea)
    m = motion(sea, sea_setup.t_imu)
    x = sea_setup.x_true
    assert np.max(np.abs(x[:, 3:6] - m.v_enu_mps)) < 1e-9
    rpy = sea_nav.euler_from_quat(x[:, 6:10])
    assert np.max(np.abs(np.angle(np.exp(1j * (rpy - m.rpy_rad))))) < 1e-9
    assert np.max(np.abs(x[:, 0:3] - m.p_enu_m)) < 5e-3  # mechanization's trapezoid vs fine integral


def test_pseudoranges_match_an_independent_range_with_light_time_and_sagnac(paper_setup):
    scn, setup, nav = paper_setup
    s = setup.series["pseudorange"]
    L = nav.layout
    r_rx = geometry.geodetic_to_ecef(scn.lat_rad, scn.lon_rad, scn.alt_m)
    r_tx = s.aux[:, L.AUX_R_S_ECEF:L.AUX_R_S_ECEF + 3]
    rho = np.linalg.norm(r_tx - r_rx, axis=1)
    sagnac = W_E / C * (r_tx[:, 0] * r_rx[1] - r_tx[:, 1] * r_rx[0])
    assert np.max(np.abs(s.z_true - (rho + sagnac))) < 1e-3
    assert np.all(s.H[:, L.DX_DC_DT] == pytest.approx(1.0))
    # the transmit time itself is checked against skyfield in test_pseudorange_is_the_light_time_range_of_skyfield
    per_epoch = np.unique(s.t_s, return_counts=True)[1]
    assert np.all(per_epoch == scn.gps["max_satellites"])


def test_starlink_selection_takes_the_highest_satellites_and_ofdm_uses_rank0_as_reference(paper_setup):
    scn, setup, nav = paper_setup
    a, o = setup.series["doppler_rate"], setup.series["ofdm_range_diff"]
    L = nav.layout
    r_rx = geometry.geodetic_to_ecef(scn.lat_rad, scn.lon_rad, scn.alt_m)
    for t in np.unique(a.t_s):  # at every epoch: ranks 0..44 by decreasing elevation, all above the mask
        at = a.t_s == t
        assert sorted(a.rank[at]) == list(range(45))
        _, el, _ = geometry.az_el_range(a.aux[at, L.AUX_R_S_ECEF:L.AUX_R_S_ECEF + 3], r_rx, scn.lat_rad, scn.lon_rad)
        el_by_rank = el[np.argsort(a.rank[at])]
        assert np.all(np.diff(el_by_rank) <= 0) and el_by_rank[-1] >= scn.starlink["elevation_mask_rad"]
    assert not np.any(o.rank == 0)
    rows5 = simulate.selected_rows(setup, "doppler_rate", 5)
    assert np.all(a.rank[rows5] < 5) and rows5.size == 5 * np.unique(a.t_s).size


@pytest.mark.parametrize("mode", MODES)
def test_noise_free_trial_keeps_the_filter_on_the_truth(paper_setup, mode):
    """Measurements, time tags and aux agree with the filter's model: with no noise and no
    biases, a filter started at the truth stays on it."""
    scn, setup, nav = paper_setup
    trial = simulate.trial_records(setup, mode, 45, np.random.default_rng(1), nav, noise_free=True)
    ekf = EKF(trial.x0, setup.P0, setup.params, gate=None, library=nav.library)
    res = ekf.run(trial.records)
    rows, k = mc.eval_rows(trial.records, setup.t_imu, mc.EVAL_RATE_HZ, scn.imu_rate_hz)
    err = nav.boxminus(res.x[rows], trial.x_true[k])
    assert np.max(np.abs(err[:, 0:3])) < 1e-4   # m
    assert np.max(np.abs(err[:, 6:9])) < 1e-8   # rad
    meas = res.status >= 0
    assert np.all(res.status[meas] == 0) and np.max(np.abs(res.y[meas])) < 1e-3


def test_more_satellites_than_visible_is_an_error_naming_the_count():
    scn = _scenario(time__duration_s=2.0, starlink__counts=[5, 500])
    with pytest.raises(UserInputError, match=r"up to 500 satellites but only \d+ are above the 28 deg mask"):
        simulate.prepare(scn)


def test_trials_share_random_numbers_across_modes_and_executors(paper_setup):
    scn, setup, nav = paper_setup
    a = simulate.trial_records(setup, "gps+imu", 5, mc.trial_rng(1, 3), nav)
    b = simulate.trial_records(setup, "leo-alpha+imu", 45, mc.trial_rng(1, 3), nav)
    imu_a, imu_b = a.records[a.records["kind"] < 0], b.records[b.records["kind"] < 0]
    assert np.array_equal(imu_a["u"], imu_b["u"]) and np.array_equal(a.x0, b.x0)
    c = simulate.trial_records(setup, "gps+imu", 5, mc.trial_rng(1, 4), nav)
    assert not np.array_equal(a.x0, c.x0)


# ---- measurement geometry against skyfield (independent SGP4 frames, time scales, light time) -----


F_C = 11.325e9
sf_api = itrs = None   # skyfield.api and its ITRS frame, imported by the `sky` fixture (skip without skyfield)


@pytest.fixture(scope="module")
def sky(paper_setup):
    """Skyfield objects of the scenario: time scale with the simulator's Earth orientation (UT1-UTC
    and polar motion from the same IERS table), the site, and every satellite of the built-in
    element sets by NORAD id."""
    global sf_api, itrs
    sf_api = pytest.importorskip("skyfield.api", reason="skyfield (independent reference) is in the test extra")
    itrs = pytest.importorskip("skyfield.framelib").itrs
    scn, _, _ = paper_setup
    from tests.eop_reference import skyfield_timescale_same_eop

    ts = skyfield_timescale_same_eop()
    site = sf_api.wgs84.latlon(math.degrees(scn.lat_rad), math.degrees(scn.lon_rad), scn.alt_m)
    sats, groups = {}, {}
    for name, es in simulate.scenario_elements(scn).items():
        for norad, rec in zip(es.norad_ids, es.satrecs):
            sats[int(norad)] = rec
            groups.setdefault(name, []).append(int(norad))
    return ts, site, sats, groups


def _times(ts, scn, t_s, shift_s=0.0):
    t = ts.from_datetime(scn.epoch_utc)   # two-part Julian date: a 1 ms step must not be rounded
    return ts.tt_jd(t.whole, t.tt_fraction + (np.asarray(t_s, float) - shift_s) / 86400.0)


def _sat(sky, norad):
    ts, _, sats, _ = sky
    return sf_api.EarthSatellite.from_satrec(sats[norad], ts)


def test_pseudorange_is_the_light_time_range_of_skyfield(paper_setup, sky):
    """Noise-free pseudorange (clock at zero) = c * tau, tau the signal's flight time between the
    satellite at transmit time t - tau and the receiver at t, both in skyfield's inertial GCRS;
    aux carries the satellite's ECEF position and velocity at the transmit time."""
    scn, setup, nav = paper_setup
    ts, site, _, _ = sky
    s, L = setup.series["pseudorange"], nav.layout
    rows = np.flatnonzero(s.t_s <= np.unique(s.t_s)[2])      # three epochs, every satellite
    assert rows.size == 3 * scn.gps["max_satellites"]
    for i in rows:
        sat = _sat(sky, int(s.sat_id[i]))
        t_rx = _times(ts, scn, s.t_s[i])
        r_rx = site.at(t_rx).position.m
        tau = 0.07
        for _ in range(4):
            tau = np.linalg.norm(sat.at(_times(ts, scn, s.t_s[i], tau)).position.m - r_rx) / C
        assert s.z_true[i] == pytest.approx(C * tau, abs=0.02)               # m
        r_e, v_e = sat.at(_times(ts, scn, s.t_s[i], tau)).frame_xyz_and_velocity(itrs)
        assert np.linalg.norm(s.aux[i, L.AUX_R_S_ECEF:L.AUX_R_S_ECEF + 3] - r_e.m) < 0.2
        assert np.linalg.norm(s.aux[i, L.AUX_V_S_ECEF:L.AUX_V_S_ECEF + 3] - v_e.m_per_s) < 5e-3


def test_gps_selection_is_the_highest_satellites_seen_by_skyfield(paper_setup, sky):
    scn, setup, _ = paper_setup
    ts, site, sats, groups = sky
    s = setup.series["pseudorange"]
    epochs = np.unique(s.t_s)
    assert epochs == pytest.approx(np.arange(1, epochs.size + 1) / scn.gps["rate_hz"])   # first epoch after 0
    gps = {n: sats[n] for n in groups["gps"]}
    for t in epochs[::20]:
        tt = _times(ts, scn, t)
        el = {n: (sf_api.EarthSatellite.from_satrec(rec, ts) - site).at(tt).altaz()[0].degrees
              for n, rec in gps.items()}
        top = sorted((n for n in el if el[n] >= 10.0), key=lambda n: -el[n])[: scn.gps["max_satellites"]]
        at = s.t_s == t
        assert list(s.sat_id[at][np.argsort(s.rank[at])]) == top


def test_doppler_and_ofdm_match_skyfield_ranges(paper_setup, sky):
    """Doppler = -(f/c) d(rho)/dt (LO at zero; range rate from skyfield's Earth-fixed satellite
    velocity) and OFDM = rho_i - rho_ref with the reference the highest satellite of the epoch."""
    scn, setup, nav = paper_setup
    ts, site, _, _ = sky
    d, o = setup.series["doppler"], setup.series["ofdm_range_diff"]
    r_rx = site.itrs_xyz.m
    t0 = np.unique(d.t_s)[1]

    # skyfield's ITRS velocity removes the Earth-rotation term w x r about the ITRS z axis only;
    # the rotation pole sits at (x_p, -y_p, 1) in ITRS (polar motion), so the rest of w x r,
    # w_E (x_p, -y_p, 0) x r, is removed here (about 1 mm/s, 0.04 Hz at 11.3 GHz for Starlink)
    from leonav_runtime.gen.constants import OMEGA_EARTH_TEME_RADPS
    from leonav_runtime.orbits.eop import default_table

    pm = default_table().at(scn.epoch_utc, t0)
    w_tilt = OMEGA_EARTH_TEME_RADPS * np.array([pm.xp_rad[0], -pm.yp_rad[0], 0.0])

    def itrs_state(norad):
        r, v = _sat(sky, norad).at(_times(ts, scn, t0)).frame_xyz_and_velocity(itrs)
        return r.m - r_rx, v.m_per_s - np.cross(w_tilt, r.m)

    at = np.flatnonzero(d.t_s == t0)
    el = np.array([(_sat(sky, int(n)) - site).at(_times(ts, scn, t0)).altaz()[0].degrees for n in d.sat_id[at]])
    ref = int(d.sat_id[at][np.argmax(el)])
    rho_ref = np.linalg.norm(itrs_state(ref)[0])
    for i in at[:15]:
        los, v = itrs_state(int(d.sat_id[i]))
        assert d.z_true[i] == pytest.approx(-F_C / C * (los @ v) / np.linalg.norm(los), abs=0.01)   # Hz
    for i in np.flatnonzero(o.t_s == t0)[:15]:
        rho = np.linalg.norm(itrs_state(int(o.sat_id[i]))[0])
        assert o.z_true[i] == pytest.approx(rho - rho_ref, abs=0.01)    # m


@pytest.fixture(scope="module")
def long_setup():
    """Ten minutes at 1/20 Hz: GPS and Starlink satellites rise and set during the run."""
    scn = _scenario(time__duration_s=600.0, imu__rate_hz=1.0, gps__rate_hz=0.05, starlink__rate_hz=0.05,
                    starlink__counts=[5], monte_carlo__modes=["gps+imu", "leo-alpha+imu"])
    return scn, simulate.prepare(scn)


def _visible_counts(scn, es, t_s, mask_deg):
    from leonav_runtime.orbits import propagate_ecef

    st = propagate_ecef(es, scn.epoch_utc, t_s, acceleration=False)
    r_rx = geometry.geodetic_to_ecef(scn.lat_rad, scn.lon_rad, scn.alt_m)
    up = np.array([math.cos(scn.lat_rad) * math.cos(scn.lon_rad), math.cos(scn.lat_rad) * math.sin(scn.lon_rad),
                   math.sin(scn.lat_rad)])
    los = st.r_ecef_m - r_rx
    sin_el = (los @ up) / np.linalg.norm(los, axis=-1)
    return np.sum(sin_el >= math.sin(math.radians(mask_deg)), axis=0)


def test_fewest_visible_satellites_is_the_worst_epoch(long_setup):
    scn, setup = long_setup
    es = simulate.scenario_elements(scn)
    t = np.arange(1, 31) * 20.0
    gps = _visible_counts(scn, es["gps"], t, 10.0)
    star = _visible_counts(scn, es["starlink"], t, 28.0)
    assert gps.min() < gps.max() and star.min() < star.max()   # the counts do change over the run
    assert setup.visible_min == {"gps": gps.min(), "starlink": star.min()}
    per_epoch = np.unique(setup.series["pseudorange"].t_s, return_counts=True)[1]
    assert np.all(per_epoch == 8)


def test_measurement_rate_must_divide_the_imu_rate_and_gps_needs_four():
    import warnings

    from tests.conftest import shared_file

    gps_only = dict(imu__rate_hz=10.0, time__duration_s=1.0, time__epoch="2026-03-09T12:00:00Z",
                    monte_carlo__modes=["gps+imu"], elements__source="files",
                    elements__files=[str(shared_file("tle/gps-ops_2026-03-09.txt"))])   # 32 real GPS sets: fast
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # two of the sets are 6 days old: irrelevant here
        with pytest.raises(UserInputError, match=r"\[gps\] rate_hz = 3: .* must divide the IMU rate 10 Hz"):
            simulate.prepare(_scenario(gps__rate_hz=3.0, **gps_only))
        # a scenario changed in code (not reloaded) meets the simulator's own check
        import dataclasses

        from leonav_runtime.simulation import satellites

        scn = _scenario(**gps_only)
        assert satellites.epochs(scn, 5.0, np.arange(11) / 10.0).tolist() == [2, 4, 6, 8, 10]
        with pytest.raises(UserInputError, match=r"measurement rate 3.0 Hz must divide the IMU rate 10.0 Hz"):
            satellites.epochs(dataclasses.replace(scn, gps=dict(scn.gps, rate_hz=3.0)), 3.0, np.arange(11) / 10.0)
        # two satellites above 60 deg at this epoch: a position needs four
        with pytest.raises(UserInputError, match=r"only 2 GPS satellites above the mask"):
            simulate.prepare(_scenario(gps__elevation_mask_deg=60.0, gps__max_satellites=4, **gps_only))
        assert simulate.prepare(_scenario(gps__rate_hz=5.0, **gps_only)).visible_min["gps"] >= 4


def test_noise_free_trial_adds_the_clock_and_lo_offset_with_their_signs(paper_setup):
    scn, setup, nav = paper_setup
    L = nav.layout
    trial = simulate.trial_records(setup, "gps+leo-alpha+imu", 45, np.random.default_rng(2), nav, noise_free=True)
    assert trial.x_true[:, L.X_B_LO] == pytest.approx(scn.starlink["lo_offset_hz"])
    t = setup.t_imu
    assert trial.x_true[:, L.X_C_DT] == pytest.approx(scn.gps["clock_bias_m"] + scn.gps["clock_drift_mps"] * t)
    rec = trial.records
    pr = rec[rec["kind"] == setup.series["pseudorange"].kind]
    s = setup.series["pseudorange"]
    assert pr["z"] - s.z_true == pytest.approx(scn.gps["clock_bias_m"] + scn.gps["clock_drift_mps"] * s.t_s)
    assert np.all(pr["R"] == scn.gps["pseudorange_sigma_m"] ** 2)
    trial = simulate.trial_records(setup, "leo-doppler+alpha+imu", 45, np.random.default_rng(2), nav,
                                   noise_free=True)
    d = setup.series["doppler"]
    dop = trial.records[trial.records["kind"] == d.kind]
    assert dop["z"] - d.z_true == pytest.approx(scn.starlink["lo_offset_hz"])   # measured = predicted + b_lo


def test_noisy_trial_records_specific_force_noise_and_outages(paper_setup):
    import dataclasses

    from leonav.models.input_noise import doppler_rate_variance

    scn, setup, nav = paper_setup
    L = nav.layout
    trial = simulate.trial_records(setup, "gps+leo-alpha+imu", 45, np.random.default_rng(3), nav)
    rec = trial.records
    imu = rec[rec["kind"] < 0]
    a = rec[rec["kind"] == setup.series["doppler_rate"].kind]
    dt = 1.0 / scn.imu_rate_hz
    n_avg = int(round(simulate.F_B_AVERAGE_S / dt))
    sigma = scn.starlink["doppler_rate_sigma_hz_s"]
    R = doppler_rate_variance(sigma, setup.params[L.P_F_C_HZ], setup.imu_profile.vrw, n_avg * dt)
    assert R > sigma**2 and np.all(a["R"] == pytest.approx(R))
    for r in a[::37]:   # aux f_b: the measured velocity increments of the last 0.1 s, averaged
        k = int(round(r["t"] / dt))
        f = imu["u"][k - n_avg:k, 3:].sum(axis=0) / (n_avg * dt)
        assert r["aux"][L.AUX_F_B:L.AUX_F_B + 3] == pytest.approx(f, abs=1e-12)
    z = a["z"] - setup.series["doppler_rate"].z_true[setup.series["doppler_rate"].rank < 45]
    assert 0.5 * sigma < np.std(z) < 2.0 * sigma
    # a GPS outage removes exactly the epochs inside [start, end)
    out_scn = _scenario(time__duration_s=6.0, starlink__counts=[5, 45], gps__outages_s=[[2.0, 4.0]])
    out = dataclasses.replace(setup, scn=out_scn)
    rec = simulate.trial_records(out, "gps+imu", 5, np.random.default_rng(3), nav).records
    t = rec["t"][rec["kind"] == setup.series["pseudorange"].kind]
    assert not np.any((t >= 2.0 - 1e-9) & (t < 4.0 - 1e-9))
    assert np.unique(t).size == np.unique(setup.series["pseudorange"].t_s).size - 20
    # an outage reaching the run's end keeps GPS lost at t = duration too (no fix at the last epoch)
    end_scn = _scenario(time__duration_s=6.0, starlink__counts=[5, 45], gps__outages_s=[[4.0, 6.0]])
    rec = simulate.trial_records(dataclasses.replace(setup, scn=end_scn), "gps+imu", 5,
                                 np.random.default_rng(3), nav).records
    t = rec["t"][rec["kind"] == setup.series["pseudorange"].kind]
    assert t.max() < 4.0 - 1e-9 and np.unique(t).size == np.unique(setup.series["pseudorange"].t_s).size - 21


def test_doppler_rate_of_a_moving_receiver_matches_the_second_difference_of_range():
    """A vessel at 20 m/s due East that starts to accelerate (3 m/s^2) at t = 2 s: the noise-free
    Doppler rate, whose receiver acceleration the model rebuilds from the specific force (gravity
    and Coriolis removed), equals -(f/c) times the second difference of the range between the truth
    trajectory and the satellite. At t = 2 s the measurement reflects the IMU interval that ends
    there (no acceleration yet): the receiver's next position is taken on its straight line."""
    scn = _scenario("maritime-outage", time__duration_s=3.0, trajectory__attitude_deg=[0.0, 0.0, 0.0],
                    trajectory__speed_mps=20.0, trajectory__maneuvers=[[2.0, 0.0, 0.0], [1.0, 3.0, 0.0]],
                    trajectory__roll_amplitude_deg=0.0, trajectory__pitch_amplitude_deg=0.0,
                    gps__outages_s=[], starlink__counts=[10], monte_carlo__modes=["leo-alpha+imu"])
    setup, nav = mc.setup_for(scn)
    L = nav.layout
    a = setup.series["doppler_rate"]
    dt = 1.0 / scn.imu_rate_hz
    r0 = geometry.geodetic_to_ecef(scn.lat_rad, scn.lon_rad, scn.alt_m)
    k2 = int(round(2.0 / dt))
    assert np.all(np.abs(setup.x_true[:k2 + 1, L.X_V_ENU] - 20.0) < 1e-6) and setup.x_true[-1, L.X_V_ENU] > 22.9
    checked = 0
    for i in range(a.t_s.size):
        k = int(round(a.t_s[i] / dt))
        if k + 1 >= setup.t_imu.size:
            continue
        checked += 1
        p = geometry.enu_to_ecef(setup.x_true[k - 1:k + 1, L.X_P_ENU:L.X_P_ENU + 3], r0, scn.lat_rad, scn.lon_rad)
        p = np.vstack([p, 2 * p[1] - p[0]])        # straight on over the next interval
        r, v, acc = (a.aux[i, off:off + 3] for off in (L.AUX_R_S_ECEF, L.AUX_V_S_ECEF, L.AUX_A_S_ECEF))
        s = np.array([r + v * d + 0.5 * acc * d * d for d in (-dt, 0.0, dt)])
        rho = np.linalg.norm(s - p, axis=1)
        rho_ddot = (rho[0] - 2 * rho[1] + rho[2]) / dt**2
        assert a.z_true[i] == pytest.approx(-F_C / C * rho_ddot, abs=0.01)    # Hz/s (Coriolis here: ~0.2)
    assert checked == 20


def test_filter_prior_is_the_documented_one(paper_setup):
    """P0: the scenario's navigation sigmas, the IMU profile's bias sigmas, clock 1 us (300 m) and
    1 m/s, LO 50 kHz."""
    scn, setup, nav = paper_setup
    L, prof = nav.layout, setup.imu_profile
    sd = np.sqrt(np.diag(setup.P0))
    f = scn.filter
    assert sd[L.DX_DP:L.DX_DP + 3] == pytest.approx([f["initial_position_sigma_m"]] * 3)
    assert sd[L.DX_DV:L.DX_DV + 3] == pytest.approx([f["initial_velocity_sigma_mps"]] * 3)
    assert sd[L.DX_DTHETA:L.DX_DTHETA + 3] == pytest.approx([math.radians(1.0)] * 3)
    assert sd[L.DX_DB_A:L.DX_DB_A + 3] == pytest.approx(np.broadcast_to(prof.acc_bias_sigma, 3))
    assert sd[L.DX_DB_G:L.DX_DB_G + 3] == pytest.approx(np.broadcast_to(prof.gyro_bias_sigma, 3))
    assert sd[L.DX_DC_DT] == pytest.approx(C * 1e-6, rel=1e-3) and sd[L.DX_DC_DDT] == 1.0
    assert sd[L.DX_DB_LO] == 50e3 and np.count_nonzero(setup.P0 - np.diag(np.diag(setup.P0))) == 0


# ---- a block of trials at once: the same records as one trial at a time -------------------------

def _assert_block_is_the_reference(setup, nav, mode, count, indices, seed):
    """trial_block's records, x0 and truth, and trial_records', equal the pre-block per-trial
    simulator's (tests/simulate_reference.py) byte for byte, trial by trial."""
    from leonav_runtime.simulation import trial_block
    from tests import simulate_reference

    block = trial_block.trial_block(setup, mode, count, [mc.trial_rng(seed, i) for i in indices], nav)
    buf = block.buffer()
    truth = block.truth()
    assert len(block) == len(indices)
    for j, i in enumerate(indices):
        ref = simulate_reference.trial_records(setup, mode, count, mc.trial_rng(seed, i), nav)
        one = simulate.trial_records(setup, mode, count, mc.trial_rng(seed, i), nav)
        for got in (one.records, block.records(j), block.fill(j, buf)):
            assert got.dtype == ref.records.dtype and got.size == ref.records.size, (mode, count, i)
            for name in ref.records.dtype.names:   # name the first field that differs
                assert got[name].tobytes() == ref.records[name].tobytes(), (mode, count, i, name)
        assert one.x0.tobytes() == block.x0[j].tobytes() == ref.x0.tobytes(), (mode, count, i)
        assert one.x_true.tobytes() == truth[j].tobytes() == ref.x_true.tobytes(), (mode, count, i)
        params = block.params if block.params.ndim == 1 else block.params[j]
        assert params.tobytes() == ref.params.tobytes()
    k = np.array([0, 7, truth.shape[1] - 1])
    assert block.truth(k).tobytes() == truth[:, k].tobytes()


@pytest.mark.parametrize("mode", MODES)
def test_a_block_of_trials_equals_the_per_trial_simulator_record_for_record(paper_setup, mode):
    scn, setup, nav = paper_setup
    for count in (5, 45):
        _assert_block_is_the_reference(setup, nav, mode, count, [0, 3, 11], scn.seed)
    ref = __import__("tests.simulate_reference", fromlist=["x"]).trial_records(
        setup, mode, 45, np.random.default_rng(4), nav, noise_free=True)
    one = simulate.trial_records(setup, mode, 45, np.random.default_rng(4), nav, noise_free=True)
    assert one.records.tobytes() == ref.records.tobytes() and one.x0.tobytes() == ref.x0.tobytes()


def test_a_block_with_local_sensors_and_an_outage_equals_the_per_trial_simulator():
    """Barometer and magnetometer (own streams, generated h at each trial's truth), a GPS outage."""
    scn = _scenario(time__duration_s=4.0, starlink__counts=[5], gps__outages_s=[[1.0, 2.5]],
                    monte_carlo__modes=["gps+imu+baro+mag", "leo-alpha+imu+baro"])
    setup, nav = mc.setup_for(scn)
    for mode in scn.modes:
        _assert_block_is_the_reference(setup, nav, mode, 5, [2, 5], scn.seed)


def test_a_block_with_realism_switches_takes_the_road_per_trial_and_equals_it():
    from tests.conftest import short_paper_scenario

    scn = short_paper_scenario(3.0, [10], "<block realism test>",
                               ephemeris_error={"enabled": True, "compensate": "inflate-r"},
                               imu_errors={"enabled": True, "process_noise_inflation": 2.0})
    setup, nav = mc.setup_for(scn)
    _assert_block_is_the_reference(setup, nav, "gps+leo-alpha+imu", 10, [0, 1], scn.seed)


def test_prior_draws_are_numpys_multivariate_normal_with_one_factorisation():
    A = np.random.default_rng(5).standard_normal((7, 7))
    cov = A @ A.T + np.eye(7)   # a full covariance: the factor's rotation matters
    got = simulate.prior_draws([mc.trial_rng(9, i) for i in range(6)], cov)
    ref = np.stack([mc.trial_rng(9, i).multivariate_normal(np.zeros(7), cov) for i in range(6)])
    assert got.shape == (6, 7) and got.tobytes() == ref.tobytes()
