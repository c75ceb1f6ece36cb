"""Simulator: truth through the generated mechanization, measurement generation, satellite rules."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from leonav_runtime import geometry, montecarlo as mc, simulate
from leonav_runtime.errors import UserInputError
from leonav_runtime.filter import EKF
from leonav_runtime.scenario import MODES, load_scenario, scenario_from_dict
from leonav_runtime.trajectory import motion

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
    assert np.max(np.abs(np.angle(np.exp(1j * (rpy - m.euler_rad))))) < 1e-9
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
    # transmit time: the satellite at t - rho/c, not at t (a 70 ms shift is ~270 m for GPS)
    v = s.aux[:, L.AUX_V_S_ECEF:L.AUX_V_S_ECEF + 3]
    r_rx_time = r_tx + v * rho[:, None] / C
    assert np.all(np.linalg.norm(r_rx_time - r_tx, axis=1) > 100.0)
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
