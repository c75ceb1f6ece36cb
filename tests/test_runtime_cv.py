"""Constant-velocity predict records (kind LEONAV_KIND_CV): generated step, driver loop, EKF API."""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.core import compiled, records
from leonav_runtime.core import filter as lf
from leonav_runtime.gen import state_layout as L
from tests.registry_reference import block_dynamics
from leonav_runtime.gen.profiles import ClockProfile, ImuProfile
from leonav_runtime.core.navfuncs import GeneratedFunction
from leonav_runtime.core.params import params_array

Q_ACC, Q_CDT, Q_CDDT = 0.04, 2.0, 0.3
PARAMS = params_array(0.6, 2.4, 50.0, imu=ImuProfile("cv", math.sqrt(Q_ACC), 0.0, 0.0, 0.0, 0.0, 0.0, "test"),
                      clock=ClockProfile("c", Q_CDT, Q_CDDT, "test"))


def x0():
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0
    x[L.X_P_ENU_SLICE], x[L.X_V_ENU_SLICE] = [1.0, 2.0, 3.0], [0.5, -1.0, 0.2]
    x[L.X_C_DT], x[L.X_C_DDT], x[L.X_ISB_SLICE] = 100.0, 3.0, [4.0, 5.0]
    return x


def test_generated_cv_step_is_the_constant_velocity_model():
    lib = compiled.load()
    f = GeneratedFunction(lib.lib, "leonav_predict_cv")
    dt = 2.5
    P = np.diag(np.arange(1.0, L.NDX + 1))
    x_next, P_next, F, Qd = f(x0(), P, dt, PARAMS)
    x_next = x_next[:, 0]
    np.testing.assert_allclose(x_next[L.X_P_ENU_SLICE], [1.0 + 0.5 * dt, 2.0 - dt, 3.0 + 0.2 * dt])
    assert x_next[L.X_C_DT] == pytest.approx(100.0 + 3.0 * dt)
    np.testing.assert_array_equal(np.delete(x_next, np.r_[L.X_P_ENU_SLICE, L.X_C_DT]),
                                  np.delete(x0(), np.r_[L.X_P_ENU_SLICE, L.X_C_DT]))
    # every other block by its registry dynamics (the clock, the LO, the biases' walks): NumPy reference
    F_ref, Q_ref = block_dynamics(dt, PARAMS)
    F_ref[:9, :9] = np.eye(9)
    for k in range(3):
        F_ref[L.DX_DP + k, L.DX_DV + k] = dt
    assert F_ref[L.DX_DC_DT, L.DX_DC_DDT] == dt
    np.testing.assert_allclose(F, F_ref, atol=1e-15)
    for k in range(3):
        i, j = L.DX_DP + k, L.DX_DV + k
        Q_ref[i, i], Q_ref[i, j], Q_ref[j, i], Q_ref[j, j] = Q_ACC * dt**3 / 3, Q_ACC * dt**2 / 2, Q_ACC * dt**2 / 2, Q_ACC * dt
    c, d = L.DX_DC_DT, L.DX_DC_DDT
    assert Q_ref[c, c] == Q_CDT * dt + Q_CDDT * dt**3 / 3 and Q_ref[c, d] == Q_CDDT * dt**2 / 2
    assert Q_ref[L.DX_DB_LO, L.DX_DB_LO] == PARAMS[L.P_Q_BLO] * dt
    np.testing.assert_allclose(Qd, Q_ref, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(P_next, F_ref @ P @ F_ref.T + Q_ref, rtol=1e-13)


def test_cv_records_in_the_c_loop_equal_the_step_by_step_api():
    lib = compiled.load()
    t = np.array([1.0, 2.0, 3.5])
    cv = records.cv_records(t, [1.0, 1.0, 1.5])
    aux = np.zeros(L.NAUX)
    meas = records.measurement_records(t, lib.kind_id("pos_e"), [1.4, 1.9, 2.6], 0.25, aux)
    recs = records.merge_records(meas, cv)
    assert list(recs["kind"]) == [L.KIND_CV, lib.kind_id("pos_e")] * 3  # predict before the measurement
    P0 = np.eye(L.NDX)
    res = lf.EKF(x0(), P0, PARAMS, library=lib).run(recs)
    assert res.n_cv == 3 and res.n_applied == 3 and res.n_imu == 0
    assert list(res.status) == [lf.STATUS_IMU, lf.STATUS_APPLIED] * 3
    ekf = lf.EKF(x0(), P0, PARAMS, library=lib)
    for r in recs:
        if r["kind"] == L.KIND_CV:
            assert ekf.predict_cv(r["dt"]) == lf.STATUS_IMU
        else:
            assert ekf.update("pos_e", r["z"], r["R"], r["aux"])
    np.testing.assert_allclose(ekf.x, res.x[-1], rtol=1e-14)
    np.testing.assert_allclose(np.diag(ekf.P), res.P_diag[-1], rtol=1e-13)


def test_bad_cv_interval_fails_and_leaves_the_state():
    lib = compiled.load()
    ekf = lf.EKF(x0(), np.eye(L.NDX), PARAMS, library=lib)
    for dt in (-1.0, float("nan")):
        assert ekf.predict_cv(dt) == lf.STATUS_FAILED
        np.testing.assert_array_equal(ekf.x, x0())
    recs = records.cv_records([1.0, 2.0], [-1.0, 1.0])
    res = lf.EKF(x0(), np.eye(L.NDX), PARAMS, library=lib).run(recs)
    assert list(res.status) == [lf.STATUS_FAILED, lf.STATUS_IMU] and res.n_failed == 1 and res.n_cv == 1


def test_pcrb_runs_over_cv_records():
    lib = compiled.load()
    t = np.arange(1.0, 6.0)
    recs = records.merge_records(records.cv_records(t, 1.0),
                                 records.measurement_records(t, lib.kind_id("pos_n"), 0.0, 4.0, np.zeros(L.NAUX)))
    B0 = np.eye(L.NDX) * 100.0
    B0[L.DX_DDT_FIX, L.DX_DDT_FIX] = 0.0  # the fix latency held known, as runs do unless they estimate it
    pc = lf.pcrb(recs, np.tile(x0(), (recs.size, 1)), B0, PARAMS, library=lib)
    assert np.all(np.isfinite(pc.B_diag))
    assert pc.B_diag[-1, L.DX_DP + 1] < 4.0 < pc.B_diag[-1, L.DX_DP]  # north observed, east only predicted
