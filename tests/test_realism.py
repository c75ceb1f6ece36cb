"""Realism switches: each changes the truth in the stated way; off leaves trials bit for bit."""
from __future__ import annotations


import numpy as np
import pytest

from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.simulation import realism, simulate
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen import state_layout as L
from tests.conftest import short_paper_scenario


def _scn(**sections):
    return short_paper_scenario(3.0, [10], "<realism test>", **sections)


def _records(scn, mode, index=0):
    setup, nav = mc.setup_for(scn)
    return simulate.trial_records(setup, mode, 10, mc.trial_rng(scn.seed, index), nav)


def test_switches_off_leave_the_trial_bit_for_bit():
    base = _scn()
    off = _scn(ephemeris_error={"enabled": False, "element_age_days": 3.0},
               imu_errors={"enabled": False, "accel_scale_factor_ppm": 5000.0})
    for mode in ("gps+imu", "leo-alpha+imu"):
        a, b = _records(base, mode), _records(off, mode)
        assert a.records.tobytes() == b.records.tobytes() and np.array_equal(a.x0, b.x0)


def test_perturbed_orbits_differ_by_the_configured_sigmas():
    rng = np.random.default_rng(5)
    # a Starlink-like state: 550 km circular, inclined, ECEF-ish numbers are enough for the geometry
    r = np.array([6928e3, 0.0, 0.0])
    v = np.array([0.0, 7590.0 * np.cos(0.93), 7590.0 * np.sin(0.93)])
    a = -3.986004418e14 * r / np.linalg.norm(r) ** 3
    state = np.tile(np.concatenate([r, v, a]), (20000, 1))
    sig = np.array([240.0, 960.0, 170.0])
    d = rng.standard_normal((20000, 3)) * sig
    moved = realism.perturb_states(state, d)
    axes = realism.rac_axes(state)[0]
    rac = (moved[:, :3] - state[:, :3]) @ axes.T
    assert np.std(rac, axis=0) == pytest.approx(sig, rel=0.03)
    assert np.abs(np.mean(rac, axis=0)).max() < 0.05 * sig.min() * 3
    # along-track is a time shift: the velocity turns with the position, the speed stays
    assert np.linalg.norm(moved[:, 3:6], axis=1) == pytest.approx(np.linalg.norm(v), rel=1e-6)


def test_starlink_sigma_grows_with_element_age_by_the_power_law():
    eph = _scn().realism["ephemeris"]
    s6h = realism.starlink_sigma_rac(eph)
    s7d = realism.starlink_sigma_rac({**eph, "element_age_days": 7.0})
    assert np.linalg.norm(s6h) == pytest.approx(1.0e3, rel=0.02)       # ~1 km 3D at 6 h
    assert np.linalg.norm(s7d) / np.linalg.norm(s6h) == pytest.approx(28.0 ** 1.09, rel=1e-9)


def test_ephemeris_error_moves_alpha_and_inflate_r_covers_it():
    on = _scn(ephemeris_error={"enabled": True})
    setup, nav = mc.setup_for(on)
    base = _records(_scn(), "leo-alpha+imu")
    pert = _records(on, "leo-alpha+imu")
    alpha = base.records["kind"] == nav.kind_id("doppler_rate")
    dz = pert.records["z"][alpha] - base.records["z"][alpha]
    assert np.all(np.isfinite(dz)) and np.std(dz) > 0.1              # Hz/s: km orbit errors show in alpha
    rows = simulate.selected_rows(setup, "doppler_rate", 10)
    sig = realism.ephemeris_sigma(setup, nav, "doppler_rate", rows)
    # over many draws the spread of the change matches the inflation computed from the model
    deltas = [realism.ephemeris_delta(setup, nav, "doppler_rate", rows,
                                      realism.draw_orbit_errors(np.random.default_rng(i), setup)) for i in range(200)]
    assert np.sqrt(np.mean(np.square(deltas), axis=0)) == pytest.approx(sig, rel=0.3)
    comp = _records(_scn(ephemeris_error={"compensate": "inflate-r"}), "leo-alpha+imu")
    assert np.all(comp.records["R"][alpha] > base.records["R"][alpha])
    assert np.array_equal(comp.records["z"], base.records["z"], equal_nan=True)  # the filter's R only


def test_imu_scale_factor_and_drift_show_in_the_measured_increments():
    cfg = dict(_scn().realism["imu"], misalignment_rad=0.0, g_sensitivity_rad_s_per_mps2=0.0,
               accel_bias_tempco_mps2_per_c=0.0, gyro_bias_tempco_rad_s_per_c=0.0)
    u_true = np.tile([0.001, -0.002, 0.0005, 0.01, 0.02, 0.0980665], (50, 1))   # 100 Hz, static-like
    t = np.arange(50) * 0.01
    du = realism.imu_error_increments(np.random.default_rng(3), cfg, u_true, t, 0.01, L)
    s = du / u_true                                                              # per-axis relative error
    assert np.allclose(s, s[0]) and np.all(np.abs(s[0]) < 5 * 0.01) and np.std(s[0]) > 1e-4
    warm = dict(cfg, accel_scale_factor=0.0, gyro_scale_factor=0.0, accel_bias_tempco_mps2_per_c=1e-3)
    du = realism.imu_error_increments(np.random.default_rng(3), warm, u_true, t, 0.01, L)
    dv = du[:, L.U_DVEL_B_SLICE]
    assert np.allclose(np.diff(dv, axis=0), dv[1] - dv[0]) and np.all(dv[0] != 0)  # a bias ramp
    on = _records(_scn(imu_errors={"enabled": True}), "gps+imu")
    base = _records(_scn(), "gps+imu")
    imu = base.records["kind"] < 0
    du = on.records["u"][imu] - base.records["u"][imu]
    f_b = base.records["u"][imu][:, L.U_DVEL_B_SLICE]
    # static: the accelerometer's errors scale the ~1 g it reads; about 1 % of it (x, y: cross terms)
    assert 1e-4 < np.abs(du[:, L.U_DVEL_B_SLICE]).max() / np.abs(f_b).max() < 0.1


def test_process_noise_inflation_reaches_the_filter():
    scn = _scn(imu_errors={"process_noise_inflation": 10.0})
    setup, nav = mc.setup_for(scn)
    trial = simulate.trial_records(setup, "gps+imu", 10, mc.trial_rng(scn.seed, 0), nav)
    assert trial.params[L.P_VRW] == pytest.approx(10 * setup.params[L.P_VRW])
    assert trial.params[L.P_GYRO_BIAS_RW] == pytest.approx(10 * setup.params[L.P_GYRO_BIAS_RW])


@pytest.mark.parametrize("section, value, fragment", [
    ("ephemeris_error", {"apply_to": ["galileo"]}, "apply_to"),
    ("ephemeris_error", {"starlink_sigma_rac_m": [1.0, 2.0]}, "starlink_sigma_rac_m"),
    ("ephemeris_error", {"enabled": 1}, "enabled = 1: expected a bool"),
    ("imu_errors", {"misalignment_mrad": -1.0}, "misalignment_mrad"),
])
def test_bad_switch_values_name_the_field(section, value, fragment):
    with pytest.raises(UserInputError, match=fragment):
        _scn(**{section: value})
