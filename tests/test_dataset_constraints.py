"""Motion constraints in the filter: standstill detection on the real CPET run, and what ZUPT
and NHC records do to the generated filter (a static receiver with a biased accelerometer)."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import navfuncs, records
from leonav_runtime.dataset import align, constraints, load, spec
from leonav_runtime.gen import state_layout as L
from leonav_runtime.inputs import prior_sigmas
from leonav_runtime.core.params import IMU_PROFILES, build_params
from tests.conftest import shared_file


def test_standstills_of_the_cpet_run_agree_with_the_gnss_speed():
    shared_file("gnss_ins/cpet_run3_navego/imu_planetary_200hz.csv")
    ds = load.load(spec.load_spec("cpet_run3"))
    imu = ds.imu_on_axis(0.36)
    still = align.standstill(imu, 0.5, 0.05, 0.02)
    rest = align.initial_rest(imu, still, 5.0)
    assert 0.8 < rest.seconds < 1.5 and rest.vrw < 0.003 and rest.arw < 0.001     # SOURCES: moves after ~1 s
    t_v, v = align.gnss_velocity(ds.fixes, 2.0)
    moving = t_v[np.hypot(v[:, 0], v[:, 1]) > 0.3]
    flagged = np.interp(moving, imu.t, still.astype(float)) > 0.5
    assert flagged.mean() < 0.01          # never at rest while the GNSS says it drives


@pytest.fixture(scope="module")
def static_run():
    """60 s at rest, 100 Hz, accelerometer biased by 0.05 m/s^2 (body x) that the prior does not know."""
    p = np.array(build_params(0.79, -1.28, 25.0, imu=IMU_PROFILES["wt901"]))
    nav = navfuncs.NavFunctions(params=p)
    x0 = np.zeros(L.NX)
    x0[L.X_Q_NB_SLICE] = nav.quat_from_euler(np.array([0.02, -0.01, 0.7]))[0]
    dt, n = 0.01, 6000
    u = lfilter.stationary_imu(x0, dt, p)
    u_b = np.tile(u, (n, 1))
    u_b[:, L.U_DVEL_B_SLICE.start] += 0.05 * dt
    t = dt * np.arange(1, n + 1)
    imu = records.imu_records(t, u_b[:, :3], u_b[:, 3:], dt)
    sig = prior_sigmas(L, IMU_PROFILES["wt901"], 1.0, 0.1, [0.01, 0.01, 0.05])
    samples = load.ImuSamples(np.r_[0.0, t], np.zeros((n + 1, 3)), np.zeros((n + 1, 3)))
    con = {"nhc_rate_hz": 10.0, "nhc_sigma_mps": [0.05, 0.05], "zupt_rate_hz": 10.0, "zupt_sigma_mps": 0.01}
    streams = constraints.records_for(samples, np.ones(n + 1, bool), 0.0, t[-1], con, nav)

    def run(*names):
        recs = records.merge_records(imu, *(streams[k] for k in names))
        return lfilter.EKF(x0, np.diag(sig**2), p, library=nav.library).run(recs)
    return run, streams


def test_zupt_holds_a_biased_static_receiver(static_run):
    run, streams = static_run
    assert streams["zupt"].size == 3 * 601 and set(streams["zupt"]["kind"]) == {L.MEAS_ZUPT_E, L.MEAS_ZUPT_N,
                                                                                L.MEAS_ZUPT_U}
    free, zupt = run(), run("zupt")
    drift = np.linalg.norm(free.x[-1, L.X_P_ENU_SLICE])
    assert drift > 50.0                                    # 0.05 m/s^2 for 60 s: ~90 m
    assert np.abs(zupt.x[-1, L.X_V_ENU_SLICE]).max() < 0.02
    assert np.linalg.norm(zupt.x[-1, L.X_P_ENU_SLICE]) < 0.5
    assert zupt.n_failed == 0 and zupt.n_gated < 0.01 * streams["zupt"].size


def test_nhc_bounds_only_lateral_and_vertical_drift(static_run):
    run, _ = static_run
    nhc = run("nhc")
    q = nhc.x[-1, L.X_Q_NB_SLICE]
    w, x, y, z = q
    C = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    v_body = C.T @ nhc.x[-1, L.X_V_ENU_SLICE]
    assert abs(v_body[1]) < 0.05 and abs(v_body[2]) < 0.05   # constrained
    assert abs(v_body[0]) > 1.0                              # forward is free: the bias drives it
