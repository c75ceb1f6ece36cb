"""GNSS-only EKF and the tightly coupled inputs: outputs test_spp.py does not check, on GEONET
0759 (real pseudoranges, shared data), with what real receivers do added where the file has
none: a receiver clock jump of 1 ms (all pseudoranges of an epoch on +299.79 km, as u-blox
receivers without clock steering do), epochs before the first solution, a faulty satellite.

* covariance: after the first epoch's pseudoranges the EKF's position covariance is the
  information sum P = (P0^-1 + sum h h^T / R)^-1, computed here from the lines of sight;
* a clock jump changes no position; epochs without a single-point solution give none;
* RAIM-excluded rows reach the filter and its NIS gate rejects them;
* start fixes of the coupled filter: sigmas against RTKLIB's sdn/sde/sdu, clock continuous.
"""
from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gnss import coupled, gnss_ekf, solution_io, spp
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.rinex_obs import read_rinex_obs
from leonav_runtime.gnss.signals import gnss_rows, klobuchar_coefficients
from tests.conftest import shared_file

FIXTURES = Path(__file__).parent / "data" / "rtklib"
MS_M = K.C_LIGHT_MPS * 1e-3


@pytest.fixture(scope="module")
def data():
    obs = read_rinex_obs(shared_file("gnss_rinex/07590920.05o"))
    nf = read_rinex_nav(shared_file("gnss_rinex/07590920.05n"))
    return obs, nf


def _rows(obs, nf):
    return gnss_rows(obs, nf.ephemerides, klobuchar=klobuchar_coefficients(nf.iono), systems="G")


def _spp(obs, nf, *, jump_from: int | None = None, offsets: dict | None = None):
    """Single-point result of `obs`; jump_from: epoch index from which the receiver clock is
    1 ms ahead; offsets: {(epoch index, satellite): metres} added to one code.

    A 1 ms step of the receiver clock moves the true reception instant of a time tag 1 ms
    earlier, so a code grows by c x 1 ms less its range rate x 1 ms (up to 0.8 m): both added
    (range rates from the broadcast velocity and the header position), as a receiver sees it."""
    obs = obs.take(np.arange(len(obs)))
    obs.pseudorange_m = obs.pseudorange_m.copy()
    epochs = np.unique(obs.t_gps_s)
    if jump_from is not None:
        rows = _rows(obs, nf)
        los = rows.aux[:, L.AUX_R_S_ECEF_SLICE] - obs.approx_position_ecef_m
        rate = np.einsum("ij,ij->i", los / np.linalg.norm(los, axis=1)[:, None], rows.aux[:, L.AUX_V_S_ECEF_SLICE])
        after = rows.t_gps_s >= epochs[jump_from]
        obs.pseudorange_m[rows.obs_row[after]] += MS_M - 1e-3 * rate[after]
    for (e, sat), d in (offsets or {}).items():
        k = (obs.t_gps_s == epochs[e]) & (obs.system == sat[0]) & (obs.prn == int(sat[1:])) & (obs.signal == "1C")
        obs.pseudorange_m[k] += d
    return spp.solve(_rows(obs, nf), approx_ecef_m=obs.approx_position_ecef_m)


def test_first_epoch_position_covariance_is_the_information_sum(data):
    res = _spp(*data)
    sol = gnss_ekf.run(res)
    e0 = 0
    idx = gnss_ekf.filter_rows(res)
    idx = idx[res.epoch_index[idx] == e0]
    assert sol.ns[e0] == idx.size >= 6 and sol.gated[e0] == 0
    el, az = res.el_rad[idx], res.az_rad[idx]
    u = np.c_[np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)]     # receiver -> satellite, ENU
    H = np.c_[-u, np.ones(idx.size)]                                            # [p_enu (3), c dt]
    R = gnss_ekf.filter_sigma_m(res, idx) ** 2
    P0 = np.diag([gnss_ekf.P0_POSITION_M**2] * 3 + [gnss_ekf.P0_CLOCK_M**2])
    P = np.linalg.inv(np.linalg.inv(P0) + H.T @ (H / R[:, None]))
    # 0.2 % apart in the up axis: the generated Jacobian also has the height derivative of the
    # troposphere delay, the lines of sight here have not
    np.testing.assert_allclose(np.diag(sol.cov_enu_m2[e0]), np.diag(P)[:3], rtol=5e-3)
    assert 0.05 < np.sqrt(np.diag(P)[:3]).min() and np.sqrt(np.diag(P)[:3]).max() < 5.0   # metres, not m^2 of m/s


def test_a_receiver_clock_jump_changes_no_position(data):
    """1 ms jumps between the first two solved epochs (where the start drift comes from) and in
    the middle of the run: the same EKF positions as without, to a millimetre."""
    base_spp = _spp(*data)
    base = gnss_ekf.run(base_spp)
    for k in (1, 60):
        res = _spp(*data, jump_from=k)
        step = np.diff(res.clock_m)[k - 1] - np.diff(base_spp.clock_m)[k - 1]
        assert abs(step - MS_M) < 1.0       # the single-point clock jumps (the receiver drifts 418 m/s)
        # one step of 1 ms at the jump, none elsewhere (before the fix, a jump between the first
        # two solutions read as 10 km/s of drift and became a -1 ms step at every epoch after)
        want = np.where(np.arange(res.t_gps_s.size) >= k, MS_M, 0.0)
        np.testing.assert_array_equal(gnss_ekf.clock_jumps_m(res), want)
        sol = gnss_ekf.run(res)
        assert np.abs(sol.r_ecef_m - base.r_ecef_m).max() < 1e-3, k
        assert sol.gated.sum() == base.gated.sum()


def test_epochs_before_the_first_solution_give_no_position_and_change_nothing(data):
    obs, nf = data
    epochs = np.unique(obs.t_gps_s)
    # the first 3 epochs with 3 satellites only (too few to solve), the rest as recorded
    first = obs.t_gps_s < epochs[3]
    keep = ~first | np.isin(obs.prn, np.unique(obs.prn[obs.t_gps_s == epochs[0]])[:3])
    res = _spp(obs.take(keep), nf)
    assert list(res.solved[:4]) == [False, False, False, True]
    sol = gnss_ekf.run(res)
    assert np.all(np.isnan(sol.r_ecef_m[:3])) and list(sol.ns[:3]) == [0, 0, 0]
    alone = gnss_ekf.run(_spp(obs.take(~first), nf))    # the file without those epochs
    assert np.abs(sol.r_ecef_m[3:] - alone.r_ecef_m).max() < 1e-6


def test_a_raim_excluded_row_reaches_the_filter_and_is_gated(data):
    base = gnss_ekf.run(_spp(*data))
    res = _spp(*data, offsets={(60, "G28"): 300.0})
    assert spp.EPOCH_STATUS[int(res.status[60])] == "ok_after_exclusion"
    sol = gnss_ekf.run(res)
    assert sol.gated[60] == base.gated[60] + 1 and sol.ns[60] == base.ns[60] - 1
    assert np.abs(sol.r_ecef_m[60] - base.r_ecef_m[60]).max() < 0.1    # one satellite fewer there


def test_start_fixes_carry_rtklibs_sigmas_per_axis(data):
    """The coupled filter's start fixes: 1-sigma E, N, U = sqrt of the single-point
    covariance's diagonal, which for the RTKLIB error model and atmosphere is RTKLIB's own
    sde, sdn, sdu (fixture 07590920.05.brdc_saas.pos) to 2 cm."""
    res = _spp(*data)
    epoch = dt.datetime(2005, 4, 2, tzinfo=dt.timezone.utc)
    fixes = coupled.spp_fixes(res, epoch, coupled.first_solution_origin(res))
    ref = {round(r.t_gps_s, 1): r for r in solution_io.read_pos(FIXTURES / "07590920.05.brdc_saas.pos")}
    t_gps = fixes.t + coupled.gps_epoch(epoch)
    n = 0
    for t, sig in zip(t_gps, fixes.sigma_enu_m):
        r = ref.get(round(float(t), 1))
        if r is None:
            continue
        sdn, sde, sdu = r.sd[:3]
        np.testing.assert_allclose(sig, np.maximum([sde, sdn, sdu], coupled.SPP_FIX_MIN_SIGMA_M), atol=0.02)
        n += 1
    assert n >= 100 and np.ptp(fixes.sigma_enu_m[:, 0] - fixes.sigma_enu_m[:, 1]) > 0.01


def test_coupled_clock_start_and_pseudoranges_continue_across_a_jump(data):
    res = _spp(*data, jump_from=60)
    table = coupled.observation_table(res, dt.datetime(2005, 4, 2, tzinfo=dt.timezone.utc))
    base = coupled.observation_table(_spp(*data), dt.datetime(2005, 4, 2, tzinfo=dt.timezone.utc))
    np.testing.assert_allclose(table.pseudorange_m, base.pseudorange_m, atol=1e-6)
    np.testing.assert_allclose(table.clock_m, base.clock_m, atol=0.5)     # the 299.79 km step taken out


def test_first_epoch_velocity_covariance_with_range_rates(data):
    """GEONET has no Doppler: the receiver's D1 made here from the broadcast satellite velocity,
    clock drifts and the (static) header position, D = -(u . v_s + c dt_r' - c dt_s') / lambda_L1.
    After the first epoch's range rates the velocity covariance is the information sum of the
    prior and the range-rate rows, R = RANGE_RATE_SIGMA_MPS^2."""
    obs, nf = data
    base = _spp(obs, nf)
    drift_rx = float(np.median(np.diff(base.clock_m) / np.diff(base.t_gps_s)))     # 418.8 m/s
    rows = _rows(obs, nf)
    los = rows.aux[:, L.AUX_R_S_ECEF_SLICE] - obs.approx_position_ecef_m
    u = los / np.linalg.norm(los, axis=1)[:, None]
    rate = np.einsum("ij,ij->i", u, rows.aux[:, L.AUX_V_S_ECEF_SLICE]) + drift_rx - rows.aux[:, L.AUX_SAT_CLOCK + 1]
    with_doppler = obs.take(np.arange(len(obs)))
    with_doppler.doppler_hz = with_doppler.doppler_hz.copy()
    with_doppler.doppler_hz[rows.obs_row] = -rate * K.GPS_L1_HZ / K.C_LIGHT_MPS
    res = _spp(with_doppler, nf)
    sol = gnss_ekf.run(res)
    at0 = np.flatnonzero(sol.records["t"] == 0.0)
    rr = at0[sol.records["kind"][at0] == L.MEAS_GNSS_RANGE_RATE]
    assert rr.size == sol.ns[0] >= 6 and np.all(sol.run.status[rr] == 0)    # all applied
    idx = gnss_ekf.filter_rows(res)
    idx = idx[res.epoch_index[idx] == 0]
    el, az = res.el_rad[idx], res.az_rad[idx]
    u_enu = np.c_[np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)]
    H = np.c_[-u_enu, np.ones(idx.size)]                                        # [v_enu (3), c dt']
    P0 = np.diag([gnss_ekf.P0_VELOCITY_MPS**2] * 3 + [gnss_ekf.P0_DRIFT_MPS**2])
    P = np.linalg.inv(np.linalg.inv(P0) + H.T @ H / K.RANGE_RATE_SIGMA_MPS**2)
    np.testing.assert_allclose(sol.run.P_diag[at0[-1], L.DX_DV_SLICE], np.diag(P)[:3], rtol=1e-3)
    # the range rates inform it (2.5 % in east; with a variance of 0.1 for 0.01 m^2/s^2 it would be 0.25 %)
    assert np.diag(P)[:3].min() < 0.98 * gnss_ekf.P0_VELOCITY_MPS**2
