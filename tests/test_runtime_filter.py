"""EKF object vs C loop, gating, numerical-failure statuses, truth consistency, PCRB."""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.core import compiled, records
from leonav_runtime.core import filter as lf
from leonav_runtime.gen import state_layout as L
from tests.registry_reference import prior_sd
from leonav_runtime.gen import constants as K
from leonav_runtime.core.params import build_params

LAT, LON, H = math.radians(40.0), math.radians(-83.0), 200.0
IMU_DT = 0.01
POS, VEL = L.X_P_ENU_SLICE, L.X_V_ENU_SLICE
PV = slice(L.X_P_ENU, L.X_V_ENU + L.X_V_ENU_SIZE)  # position and velocity (same rows in x and dx)
assert PV == slice(L.DX_DP, L.DX_DV + L.DX_DV_SIZE)


@pytest.fixture(scope="module")
def lib():
    return compiled.load()


@pytest.fixture(scope="module")
def params():
    return np.array(build_params(LAT, LON, H))


def x_rest() -> np.ndarray:
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0  # body axes aligned with ENU
    return x


def P0() -> np.ndarray:
    # prior standard deviation per error-state block (SI); any other block: its registry prior
    sd = {"dp": 10.0, "dv": 0.5, "dtheta": 0.01, "db_a": 0.05, "db_g": 1e-4, "dc_dt": 100.0, "dc_ddt": 1.0,
          "db_lo": 10.0, "disb": 10.0}
    return np.diag(prior_sd(sd) ** 2)


def ecef_and_enu_axes():
    """Origin ECEF (m) and the ENU->ECEF rotation (columns e, n, u), WGS84."""
    n = K.WGS84_A_M / math.sqrt(1 - K.WGS84_E2 * math.sin(LAT) ** 2)
    r0 = np.array([(n + H) * math.cos(LAT) * math.cos(LON), (n + H) * math.cos(LAT) * math.sin(LON),
                   (n * (1 - K.WGS84_E2) + H) * math.sin(LAT)])
    e = np.array([-math.sin(LON), math.cos(LON), 0.0])
    nn = np.array([-math.sin(LAT) * math.cos(LON), -math.sin(LAT) * math.sin(LON), math.cos(LAT)])
    u = np.array([math.cos(LAT) * math.cos(LON), math.cos(LAT) * math.sin(LON), math.sin(LAT)])
    return r0, np.column_stack([e, nn, u])


def gps_aux(n_sat: int = 8) -> np.ndarray:
    """aux rows of n_sat GPS satellites 22000 km away, spread in azimuth and elevation."""
    r0, C = ecef_and_enu_axes()
    rows = []
    for i in range(n_sat):
        az, el = 2 * math.pi * i / n_sat, math.radians(15 + 60 * (i % 3) / 2)
        los = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
        a = np.zeros(records.NAUX)
        a[L.AUX_R_S_ECEF_SLICE] = r0 + C @ los * 2.2e7
        rows.append(a)
    return np.array(rows)


def static_stream(lib, params, seconds, rng, fix_sigma=None, gps_rate_hz=10.0, pr_sigma=None):
    """Records of a receiver at rest at the origin: noisy IMU, optional fixes and pseudoranges."""
    x = x_rest()
    n = int(round(seconds / IMU_DT))
    t = np.arange(1, n + 1) * IMU_DT
    u0 = lf.stationary_imu(x, IMU_DT, params, lib)
    vrw, arw = params[L.P_VRW], params[L.P_ARW]
    dtheta = u0[L.U_DTHETA_B_SLICE] + rng.normal(0, arw * math.sqrt(IMU_DT), (n, L.U_DTHETA_B_SIZE))
    dvel = u0[L.U_DVEL_B_SLICE] + rng.normal(0, vrw * math.sqrt(IMU_DT), (n, L.U_DVEL_B_SIZE))
    parts = [records.imu_records(t, dtheta, dvel)]
    t_gps = np.arange(1, int(seconds * gps_rate_hz) + 1) / gps_rate_hz
    if fix_sigma is not None:
        for axis, name in enumerate(("pos_e", "pos_n", "pos_u")):
            z = x[L.X_P_ENU + axis] + rng.normal(0, fix_sigma, t_gps.size)
            parts.append(records.measurement_records(t_gps, lib.kind_id(name), z, fix_sigma**2))
    if pr_sigma is not None:
        ekf = lf.EKF(x, P0(), params, library=lib)
        for sat, aux in enumerate(gps_aux()):
            h, _ = ekf.h("pseudorange", aux, x=x)
            z = h + rng.normal(0, pr_sigma, t_gps.size)
            parts.append(records.measurement_records(t_gps, lib.kind_id("pseudorange"), z, pr_sigma**2,
                                                     aux=aux, sat_id=sat))
    return records.merge_records(*parts)


def step_through(ekf: lf.EKF, recs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    xs, pd, st = [], [], []
    for r in recs:
        if r["kind"] == records.KIND_IMU:
            st.append(ekf.predict(r["u"], r["dt"]))
        else:
            ekf.update(int(r["kind"]), r["z"], r["R"], r["aux"])
            st.append(ekf.status)
        xs.append(ekf.x.copy())
        pd.append(np.diag(ekf.P).copy())
    return np.array(xs), np.array(pd), np.array(st)


def test_step_by_step_equals_c_loop(lib, params):
    rng = np.random.default_rng(3)
    recs = static_stream(lib, params, 2.0, rng, fix_sigma=2.0, pr_sigma=3.0)
    recs["z"][np.flatnonzero(recs["kind"] == L.MEAS_PSEUDORANGE)[5]] += 1000.0  # one gated record on both paths
    x0 = x_rest()
    x0[POS] += [3.0, -2.0, 1.0]
    a, b = lf.EKF(x0, P0(), params, library=lib), lf.EKF(x0, P0(), params, library=lib)
    res = a.run(recs, full_P=True)
    xs, pd, st = step_through(b, recs)
    np.testing.assert_array_equal(res.P[-1], a.P)
    np.testing.assert_array_equal(np.diagonal(res.P, axis1=1, axis2=2), res.P_diag)
    assert res.n_gated == 1 and np.count_nonzero(st == lf.STATUS_GATED) == 1
    np.testing.assert_array_equal(res.status, st)
    assert np.max(np.abs(res.x - xs)) <= 1e-12
    assert np.max(np.abs(res.P_diag - pd) / pd) <= 1e-12
    assert np.max(np.abs(a.P - b.P)) <= 1e-12 * np.max(np.abs(a.P))


def test_predict_F_is_column_major_and_consistent(lib, params):
    rng = np.random.default_rng(0)
    x = x_rest()
    x[VEL] = [20.0, -5.0, 1.0]
    u = lf.stationary_imu(x_rest(), IMU_DT, params, lib) + rng.normal(0, 1e-3, L.NU)
    A = rng.normal(size=(L.NDX, L.NDX))
    P = A @ A.T + L.NDX * np.eye(L.NDX)
    ekf = lf.EKF(x, P, params, library=lib)
    ekf.predict(u, IMU_DT)
    np.testing.assert_allclose(ekf.P, ekf.F @ P @ ekf.F.T + ekf.Q, rtol=1e-10, atol=1e-10)
    # position/velocity columns of F against finite differences of the mechanization
    work = lib.new_workspace()

    def mech(xx):
        xx = xx.copy()
        assert lib.lib.leonav_mech_step(lf._ptr(xx), lf._ptr(u), IMU_DT, lf._ptr(params), work.ctypes.data) == 0
        return xx

    base, eps = mech(x), 1e-3
    for j in range(PV.start, PV.stop):
        xp = x.copy()
        xp[j] += eps
        col = (mech(xp)[PV] - base[PV]) / eps
        np.testing.assert_allclose(ekf.F[PV, j], col, atol=1e-7)
    assert ekf.F[L.DX_DP, L.DX_DV] == pytest.approx(IMU_DT) and abs(ekf.F[L.DX_DV, L.DX_DP]) < 1e-5


def test_outlier_is_gated_and_counted(lib, params):
    rng = np.random.default_rng(5)
    recs = static_stream(lib, params, 3.0, rng, pr_sigma=3.0)
    pr_idx = np.flatnonzero(recs["kind"] == lib.kind_id("pseudorange"))
    bad = pr_idx[len(pr_idx) // 2]
    recs["z"][bad] += 1000.0
    ekf = lf.EKF(x_rest(), P0(), params, library=lib)
    res = ekf.run(recs)
    assert res.status[bad] == lf.STATUS_GATED and res.nis[bad] > 1e3
    assert res.n_gated == 1 and res.n_failed == 0 and res.n_applied == len(pr_idx) - 1
    assert np.all(res.status[pr_idx[pr_idx != bad]] == lf.STATUS_APPLIED)
    np.testing.assert_array_equal(res.x[bad], res.x[bad - 1])  # gated: state untouched
    # without gating the same outlier is applied and pulls the clock/position
    ekf2 = lf.EKF(x_rest(), P0(), params, gate=None, library=lib)
    res2 = ekf2.run(recs)
    assert res2.n_gated == 0 and res2.status[bad] == lf.STATUS_APPLIED
    assert np.linalg.norm(res2.x[bad, POS] - res2.x[bad - 1, POS]) > 1.0


def test_numerical_failures_return_status_2_and_loop_continues(lib, params):
    rng = np.random.default_rng(9)
    good = static_stream(lib, params, 1.0, rng, fix_sigma=2.0)
    fix = records.measurement_records([0.305, 0.505], lib.kind_id("pos_e"), [0.0, np.nan], [-1e9, 4.0])
    imu_nan = records.imu_records([0.705], np.full((1, 3), np.nan), np.zeros((1, 3)), dt_s=IMU_DT)
    neg_dt = records.imu_records([0.805], np.zeros((1, 3)), np.zeros((1, 3)), dt_s=-0.01)
    recs = records.merge_records(good, fix, imu_nan, neg_dt)
    bad = np.flatnonzero(np.isin(recs["t"], [0.305, 0.505, 0.705, 0.805]))
    res = lf.EKF(x_rest(), P0(), params, library=lib).run(recs)
    np.testing.assert_array_equal(res.status[bad], [lf.STATUS_FAILED] * 4)
    assert res.n_failed == 4 and np.isnan(res.nis[bad[1]])
    assert res.S[bad[0]] < 0  # R = -1e9 gives S <= 0: reported, not applied
    # failures leave the state untouched, so the run equals the run without those records
    ref = lf.EKF(x_rest(), P0(), params, library=lib).run(good)
    assert np.all(res.status[-5:] != lf.STATUS_FAILED) and res.n_applied == ref.n_applied
    np.testing.assert_array_equal(res.x[-1], ref.x[-1])


def test_static_receiver_with_fixes_is_consistent_with_P(lib, params):
    rng = np.random.default_rng(11)
    sigma = 2.0
    recs = static_stream(lib, params, 20.0, rng, fix_sigma=sigma, gps_rate_hz=1.0)
    x0 = x_rest()
    x0[PV] = [5.0, -4.0, 3.0, 0.3, -0.2, 0.1]  # initial error 5 m / 0.3 m/s vs sigma 10 m / 0.5 m/s
    res = lf.EKF(x0, P0(), params, library=lib).run(recs)
    assert res.n_applied == 60 and res.n_gated == 0 and res.n_failed == 0
    err = res.x[:, PV] - x_rest()[PV]  # truth is at rest at the origin
    sd = np.sqrt(res.P_diag[:, PV])
    after_first_fix = res.t >= 1.0
    assert np.all(np.abs(err[after_first_fix]) < 4 * sd[after_first_fix])
    assert np.all(sd[-1, POS] < 0.15 * sd[0, POS])  # converged from 10 m to ~1 m
    assert np.linalg.norm(err[-1, POS]) < 0.5 * np.linalg.norm(x0[POS])
    nis = res.nis[res.status == lf.STATUS_APPLIED]
    assert 0.5 < nis[10:].mean() < 1.6  # after convergence, innovations match their S


def test_pcrb_equals_ekf_covariance_linearised_at_truth(lib, params):
    rng = np.random.default_rng(2)
    recs = static_stream(lib, params, 1.0, rng, fix_sigma=2.0, pr_sigma=3.0)
    x_true = x_rest()
    pc = lf.pcrb(recs, np.tile(x_true, (recs.size, 1)), P0(), params, library=lib)
    # EKF steps with the state reset to truth before each record and z = h(truth):
    # its P follows F P F^T + Qd and the Joseph update, the same recursion as B
    ekf = lf.EKF(x_true, P0(), params, gate=None, library=lib)
    for i, r in enumerate(recs):
        ekf.x = x_true.copy()
        if r["kind"] == records.KIND_IMU:
            ekf.predict(r["u"], r["dt"])
        else:
            h, _ = ekf.h(int(r["kind"]), r["aux"])
            assert ekf.update(int(r["kind"]), h, r["R"], r["aux"])
        if i in (5, recs.size // 2):
            np.testing.assert_allclose(pc.B_diag[i], np.diag(ekf.P), rtol=1e-8)
    np.testing.assert_allclose(pc.B, ekf.P, rtol=1e-7, atol=1e-12)
    nav = L.DX_NAV9_SLICE
    np.testing.assert_allclose(pc.B_nav[-1], ekf.P[nav, nav], rtol=1e-7, atol=1e-12)


def test_stationary_imu_keeps_the_mechanization_at_rest(lib, params):
    x = x_rest()
    x[L.X_Q_NB_SLICE] = [math.cos(0.3), 0.0, 0.0, math.sin(0.3)]  # yawed 0.6 rad
    u = lf.stationary_imu(x, IMU_DT, params, lib)
    assert np.linalg.norm(u[L.U_DVEL_B_SLICE]) / IMU_DT == pytest.approx(9.80, abs=0.01)  # gravity at 40 deg N
    assert np.linalg.norm(u[L.U_DTHETA_B_SLICE]) / IMU_DT == pytest.approx(K.OMEGA_IE_RADPS, rel=1e-6)  # Earth rate
    work, xx = lib.new_workspace(), x.copy()
    for _ in range(1000):  # 10 s
        assert lib.lib.leonav_mech_step(lf._ptr(xx), lf._ptr(u), IMU_DT, lf._ptr(params), work.ctypes.data) == 0
    q = L.X_Q_NB_SLICE
    assert np.max(np.abs(xx[PV])) < 1e-6 and np.max(np.abs(xx[q] - x[q])) < 1e-9


def test_P_rows_returns_the_same_blocks_as_full_P(lib, params):
    rng = np.random.default_rng(5)
    recs = static_stream(lib, params, 1.0, rng, fix_sigma=2.0)
    full = lf.EKF(x_rest(), P0(), params, library=lib).run(recs, full_P=True)
    rows = np.array([0, 7, 50, recs.size - 1])
    some = lf.EKF(x_rest(), P0(), params, library=lib).run(recs, P_rows=rows)
    assert some.P.shape == (rows.size, P0().shape[0], P0().shape[0])
    np.testing.assert_array_equal(some.P, full.P[rows])
    np.testing.assert_array_equal(some.x, full.x)
    with pytest.raises(ValueError, match="increasing record indices"):
        lf.EKF(x_rest(), P0(), params, library=lib).run(recs, P_rows=[5, 3])


def test_step_return_codes_are_distinct(lib, params):
    """One success code for every step; gated/failed positive; errors negative (no -1 for success)."""
    L = lib.layout
    x, P, u = x_rest(), np.asfortranarray(P0()), lf.stationary_imu(x_rest(), IMU_DT, params, lib)
    good, bad = lib.new_workspace(), np.zeros_like(lib.new_workspace())  # bad: never initialised
    p_, w = lf._ptr(params), good.ctypes.data
    predict = lib.lib.leonav_predict_step
    assert predict(lf._ptr(x), lf._ptr(P), lf._ptr(u), IMU_DT, p_, None, None, bad.ctypes.data) == L.ERR_WORK
    assert predict(lf._ptr(x), lf._ptr(P), lf._ptr(u), IMU_DT, p_, None, None, w) == L.OK
    u_nan = np.full(L.NU, np.nan)
    assert predict(lf._ptr(x), lf._ptr(P), lf._ptr(u_nan), IMU_DT, p_, None, None, w) == L.FAILED
    assert lib.lib.leonav_mech_step(lf._ptr(x), lf._ptr(u), IMU_DT, p_, w) == L.OK
    update, aux, ysn = lib.lib.leonav_update_step, np.zeros(L.NAUX), np.zeros(3)
    args = lambda kind, z, R: (lf._ptr(x), lf._ptr(P), kind, z, R, lf._ptr(aux), p_, 10.0, lf._ptr(ysn), w)  # noqa: E731
    assert update(*args(L.MEAS_POS_E, 0.5, 4.0)) == L.OK
    assert update(*args(L.MEAS_POS_E, 1e4, 4.0)) == L.GATED
    assert update(*args(L.MEAS_POS_E, float("nan"), 4.0)) == L.FAILED
    assert update(*args(L.NMEAS, 0.0, 4.0)) == L.ERR_KIND
    assert update(*args(L.MEAS_IMU, 0.0, 4.0)) == L.ERR_KIND
    h, H = np.zeros(1), np.zeros(L.NDX)
    assert lib.lib.leonav_h_step(L.MEAS_POS_E, lf._ptr(x), lf._ptr(aux), p_, lf._ptr(h), lf._ptr(H), w) == L.OK
    assert len({L.OK, L.GATED, L.FAILED, L.ERR_WORK, L.ERR_KIND, L.ERR_LAYOUT, L.ERR_ARG, L.ERR_NUMERIC}) == 8
    # the PCRB rejects a non-positive R with an error code (named in the exception)
    rec = records.measurement_records([0.0], L.MEAS_POS_E, [0.0], [0.0])
    with pytest.raises(RuntimeError, match="LEONAV_ERR_NUMERIC at record 0"):
        lf.pcrb(rec, x_rest()[None, :], P0(), params, library=lib)


def test_a_non_symmetric_P0_runs_as_its_symmetric_part_and_P_stays_exactly_symmetric(lib, params):
    """The generated steps read P's upper triangle only; EKF symmetrizes P0 where it enters, and
    the PCRB loop its B0, so a caller's non-symmetric P0 gives the run of (P0 + P0^T) / 2 bit for
    bit, and every P written (predicts and updates) is exactly symmetric."""
    rng = np.random.default_rng(5)
    recs = static_stream(lib, params, 1.0, rng, fix_sigma=2.0, pr_sigma=3.0)
    A = rng.normal(size=(L.NDX, L.NDX)) * np.sqrt(np.outer(np.diag(P0()), np.diag(P0()))) * 1e-3
    skewed = P0() + A                     # not symmetric: A's two triangles differ
    assert not np.array_equal(skewed, skewed.T)
    a, b = lf.EKF(x_rest(), skewed, params, library=lib), lf.EKF(x_rest(), (skewed + skewed.T) / 2, params, library=lib)
    ra, rb = a.run(recs, full_P=True), b.run(recs, full_P=True)
    np.testing.assert_array_equal(ra.x, rb.x)
    np.testing.assert_array_equal(ra.P, rb.P)
    assert all(np.array_equal(P, P.T) for P in ra.P)
    # the C loops symmetrize what they are given themselves (leonav_symmetrize): the PCRB's B0
    x_lin = np.tile(x_rest(), (recs.size, 1))
    ba, bb = (lf.pcrb(recs, x_lin, B0, params, library=lib) for B0 in (skewed, (skewed + skewed.T) / 2))
    np.testing.assert_array_equal(ba.B_diag, bb.B_diag)
    np.testing.assert_array_equal(ba.B_nav, bb.B_nav)
