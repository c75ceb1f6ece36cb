"""Realism switches term by term: each unmodelled error has the closed form it claims."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.simulation import orbit_truth, realism, simulate
from leonav_runtime.gen import state_layout as L
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

PAPER_MODES = load_scenario("paper").raw["monte_carlo"]["modes"]


def _scn(modes=("gps+imu", "leo-alpha+imu"), duration_s=3.0, **sections):
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = duration_s
    raw["starlink"]["counts"] = [10]
    raw["monte_carlo"]["modes"] = list(modes)
    raw.update(copy.deepcopy(sections))
    return scenario_from_dict(raw, source="<realism term test>")


def test_every_paper_mode_runs_with_the_ephemeris_error_on():
    on = _scn(modes=PAPER_MODES, duration_s=2.0, ephemeris_error={"enabled": True, "compensate": "inflate-r",
                                                                      "apply_to": ["starlink", "gps"]})
    off = _scn(modes=PAPER_MODES, duration_s=2.0)
    setup, nav = mc.setup_for(on)
    for mode in PAPER_MODES:
        a = simulate.trial_records(setup, mode, 10, mc.trial_rng(on.seed, 0), nav)
        b = simulate.trial_records(mc.setup_for(off)[0], mode, 10, mc.trial_rng(off.seed, 0), nav)
        sat = a.records["kind"] >= 0
        assert np.all(np.isfinite(a.records["z"][sat])), mode
        # every satellite observable of the mode moved (GPS by metres, Starlink ones by their orbit error)
        for kind in np.unique(a.records["kind"][sat]):
            k = a.records["kind"] == kind
            assert np.any(a.records["z"][k] != b.records["z"][k]), (mode, kind)
            assert np.all(a.records["R"][k] > b.records["R"][k]), (mode, kind)


def test_ofdm_reference_is_the_epochs_highest_satellite():
    setup, nav = mc.setup_for(_scn(modes=["leo-ofdm+imu"], duration_s=2.0))
    rows = simulate.selected_rows(setup, "ofdm_range_diff", 10)
    ids = orbit_truth.ref_ids(setup, "ofdm_range_diff", rows)
    s, dr = setup.series["ofdm_range_diff"], setup.series["doppler_rate"]
    for t, i, ref_state in zip(s.t_s[rows], ids, s.ref_ecef[rows]):
        top = (dr.t_s == t) & (dr.rank == 0)
        assert dr.sat_id[top] == [i] and np.array_equal(dr.sat_ecef[top][0], ref_state)


# ---- IMU errors: one term at a time, sizes from the TOML's human units --------------------

IMU_TOML = {"accel_scale_factor_ppm": 2000.0, "gyro_scale_factor_ppm": 3000.0, "misalignment_mrad": 4.0,
            "g_sensitivity_deg_s_per_g": 0.2, "accel_bias_tempco_mg_per_c": 0.5,
            "gyro_bias_tempco_deg_s_per_c": 0.01, "temperature_rate_c_per_s": 0.05}
G0 = 9.80665
SIGMA_SI = {"accel_scale_factor": 2000e-6, "gyro_scale_factor": 3000e-6, "misalignment_rad": 4e-3,
            "g_sensitivity_rad_s_per_mps2": np.radians(0.2) / G0, "accel_bias_tempco_mps2_per_c": 0.5e-3 * G0,
            "gyro_bias_tempco_rad_s_per_c": np.radians(0.01)}
N_DRAWS = 2000


def _only(*keys) -> dict:
    cfg = _scn(imu_errors=IMU_TOML).realism["imu"]
    return {**cfg, **{k: 0.0 for k in SIGMA_SI if k not in keys}}


def _draws(cfg, u, t_start, dt) -> np.ndarray:
    """(N_DRAWS, n, 6) increments of independent trials."""
    return np.stack([realism.imu_error_increments(np.random.default_rng(i), cfg, u, t_start, dt, L)
                     for i in range(N_DRAWS)])


def _spread_is(x: np.ndarray, sigma: float) -> None:
    """Zero-mean draws with the given 1-sigma (10 % on the spread)."""
    assert np.std(x) == pytest.approx(sigma, rel=0.1)
    assert abs(np.mean(x)) < 4 * sigma / np.sqrt(x.size)


def test_imu_cfg_is_in_si_units():
    cfg = _scn(imu_errors=IMU_TOML).realism["imu"]
    for k, v in SIGMA_SI.items():
        assert cfg[k] == pytest.approx(v, rel=1e-12), k


@pytest.mark.parametrize("key, sl, other", [("accel_scale_factor", L.U_DVEL_B_SLICE, L.U_DTHETA_B_SLICE),
                                            ("gyro_scale_factor", L.U_DTHETA_B_SLICE, L.U_DVEL_B_SLICE)])
def test_scale_factor_scales_each_axis_of_its_own_triad(key, sl, other):
    u = np.tile([0.01, -0.02, 0.005, 0.03, -0.04, 0.098], (3, 1))
    du = _draws(_only(key), u, np.arange(3) * 0.01, 0.01)
    s = du[:, :, sl] / u[:, sl]
    assert np.allclose(s, s[:, :1]) and np.all(du[:, :, other] == 0.0)   # one factor per axis and trial
    _spread_is(s[:, 0], SIGMA_SI[key])
    assert abs(np.corrcoef(s[:, 0, 0], s[:, 0, 1])[0, 1]) < 0.1            # axes independent


def test_misalignment_couples_other_axes_only_and_differs_between_triads():
    u = np.zeros((2, 6))
    u[:, 0], u[:, 3] = 0.01, 0.05                                          # x-axis motion only
    du = _draws(_only("misalignment_rad"), u, np.zeros(2), 0.01)
    g, a = du[:, 0, L.U_DTHETA_B_SLICE] / 0.01, du[:, 0, L.U_DVEL_B_SLICE] / 0.05
    assert np.all(g[:, 0] == 0.0) and np.all(a[:, 0] == 0.0)               # no diagonal: that is scale factor
    _spread_is(g[:, 1:], SIGMA_SI["misalignment_rad"])
    _spread_is(a[:, 1:], SIGMA_SI["misalignment_rad"])
    assert abs(np.corrcoef(g[:, 1], a[:, 1])[0, 1]) < 0.1                  # two triads, two matrices


def test_g_sensitivity_turns_specific_force_into_gyro_error():
    dt, f_b = 0.01, np.array([0.0, 0.0, G0])                               # 1 g along z, no rotation
    u = np.tile(np.concatenate([np.zeros(3), f_b * dt]), (2, 1))
    du = _draws(_only("g_sensitivity_rad_s_per_mps2"), u, np.zeros(2), dt)
    assert np.all(du[:, :, L.U_DVEL_B_SLICE] == 0.0)
    w_err = du[:, 0, L.U_DTHETA_B_SLICE] / dt                               # rad/s
    _spread_is(w_err / G0, SIGMA_SI["g_sensitivity_rad_s_per_mps2"])


@pytest.mark.parametrize("key, sl", [("accel_bias_tempco_mps2_per_c", L.U_DVEL_B_SLICE),
                                     ("gyro_bias_tempco_rad_s_per_c", L.U_DTHETA_B_SLICE)])
@pytest.mark.parametrize("dt", [0.01, 0.002])
def test_temperature_drift_is_a_bias_ramp_of_the_configured_size(key, sl, dt):
    t = np.array([0.0, 1.0, 4.0, 9.0])
    du = _draws(_only(key), np.zeros((4, 6)), t, dt)
    temp_c = 0.05 * (t + 0.5 * dt)                                          # degC at each interval's middle
    bias = du[:, :, sl] / dt / temp_c[None, :, None]                         # per degC, whatever dt is
    assert np.allclose(bias, bias[:, :1], rtol=1e-9)                         # linear in temperature
    _spread_is(bias[:, 0], SIGMA_SI[key])
    other = L.U_DTHETA_B_SLICE if sl == L.U_DVEL_B_SLICE else L.U_DVEL_B_SLICE
    assert np.all(du[:, :, other] == 0.0)


def test_process_noise_inflation_scales_the_four_noise_densities_only():
    params = np.arange(1.0, L.NP + 1.0)
    out = realism.filter_params(params, {"process_noise_inflation": 7.0}, L)
    four = [L.P_VRW, L.P_ARW, L.P_ACC_BIAS_RW, L.P_GYRO_BIAS_RW]
    assert np.array_equal(out[four], 7.0 * params[four])
    rest = np.setdiff1d(np.arange(params.size), four)
    assert np.array_equal(out[rest], params[rest]) and np.array_equal(params, np.arange(1.0, params.size + 1.0))


# ---- ephemeris error -------------------------------------------------------------------

MU = 3.986004418e14


def _circular(t: float, radius=6928e3, incl=0.93) -> np.ndarray:
    """Exact two-body circular orbit state [r v a] (inertial) at time t."""
    w = np.sqrt(MU / radius**3)
    e1, e2 = np.array([1.0, 0, 0]), np.array([0, np.cos(incl), np.sin(incl)])
    r = radius * (np.cos(w * t) * e1 + np.sin(w * t) * e2)
    v = radius * w * (-np.sin(w * t) * e1 + np.cos(w * t) * e2)
    return np.concatenate([r, v, -w**2 * r])


def test_along_track_offset_is_the_orbit_a_little_later():
    d_along = 960.0                                                         # m
    tau = d_along / np.linalg.norm(_circular(0.0)[3:6])                     # s
    moved = realism.perturb_states(_circular(0.0)[None], np.array([[0.0, d_along, 0.0]]))[0]
    exact = _circular(tau)
    assert moved[:3] == pytest.approx(exact[:3], abs=1e-3)                  # m
    assert moved[3:6] == pytest.approx(exact[3:6], abs=1e-3)                # m/s: v + a*dt, not v
    rc = realism.perturb_states(_circular(0.0)[None], np.array([[240.0, 0.0, -170.0]]))[0]
    axes = realism.rac_axes(_circular(0.0)[None])[0]
    assert (rc[:3] - _circular(0.0)[:3]) @ axes.T == pytest.approx([240.0, 0.0, -170.0], abs=1e-6)


def _ofdm_setup():
    setup, nav = mc.setup_for(_scn(modes=["leo-ofdm+imu"], duration_s=2.0))
    return setup, nav, simulate.selected_rows(setup, "ofdm_range_diff", 10)


def test_ofdm_moves_with_its_reference_satellite_too():
    setup, nav, rows = _ofdm_setup()
    s = setup.series["ofdm_range_diff"]
    refs = orbit_truth.ref_ids(setup, "ofdm_range_diff", rows)
    ids = np.unique(np.concatenate([setup.series["doppler_rate"].sat_id]))
    radial = np.array([1000.0, 0.0, 0.0])
    ref_only = {"starlink": {i: radial if i in set(refs.tolist()) else np.zeros(3) for i in ids.tolist()}}
    sat_only = {"starlink": {i: np.zeros(3) if i in set(refs.tolist()) else radial for i in ids.tolist()}}
    both = {"starlink": {i: radial for i in ids.tolist()}}
    d_ref, d_sat, d_both = (realism.ephemeris_delta(setup, nav, "ofdm_range_diff", rows, e)
                            for e in (ref_only, sat_only, both))
    # a 1 km radial move of a satellite above the 28 deg mask changes its range by 0.47..1 km
    assert np.all((np.abs(d_ref) > 400.0) & (np.abs(d_ref) < 1000.5))
    assert np.all(d_ref < 0) and np.all(d_sat > 0)                          # rho_i - rho_ref: opposite signs
    assert d_sat + d_ref == pytest.approx(d_both, abs=1e-3)
    for t in np.unique(s.t_s[rows]):                                        # one reference per epoch
        assert np.ptp(d_ref[s.t_s[rows] == t]) < 1e-6


@pytest.mark.parametrize("kind_name", ["doppler_rate", "ofdm_range_diff"])
def test_ephemeris_delta_spread_matches_its_sigma(kind_name):
    setup, nav = mc.setup_for(_scn(modes=["leo-alpha+ofdm+imu"], duration_s=1.0))
    rows = simulate.selected_rows(setup, kind_name, 10)
    sig = realism.ephemeris_sigma(setup, nav, kind_name, rows)
    deltas = np.array([realism.ephemeris_delta(setup, nav, kind_name, rows,
                                               realism.draw_orbit_errors(np.random.default_rng(i), setup))
                       for i in range(600)])
    rms = np.sqrt(np.mean(deltas**2, axis=0))
    assert np.all(sig > 0) and rms / sig == pytest.approx(np.ones(rows.size), abs=0.12)
    assert np.median(rms / sig) == pytest.approx(1.0, abs=0.06)


# ---- consistency: errors push NEES out of its band, compensation brings it back ------------

def _nees(scn, mode: str, trials: int = 20) -> tuple[float, tuple[float, float]]:
    from scipy.stats import chi2
    nees = np.stack([mc.run_trial(scn, mode, 10, i).nees for i in range(trials)]).mean(axis=0)
    dof = L.NNAV * trials
    return float(nees.mean()), (chi2.ppf(0.025, dof) / trials, chi2.ppf(0.975, dof) / trials)


@pytest.mark.parametrize("section, on, compensation", [
    ("ephemeris_error", {"enabled": True, "element_age_days": 7.0}, {"compensate": "inflate-r"}),
    ("imu_errors", {"enabled": True}, {"process_noise_inflation": 100.0}),
])
def test_unmodelled_errors_leave_the_nees_band_and_compensation_returns(section, on, compensation):
    pytest.importorskip("scipy")
    mode = "leo-alpha+imu"
    ideal, band = _nees(_scn(duration_s=3.0), mode)
    broken, _ = _nees(_scn(duration_s=3.0, **{section: on}), mode)
    fixed, _ = _nees(_scn(duration_s=3.0, **{section: {**on, **compensation}}), mode)
    assert band[0] <= ideal <= band[1]
    assert broken > 1.5 * band[1]
    assert fixed < 0.5 * broken and fixed < 1.3 * band[1]
