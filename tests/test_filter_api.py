"""EKF object contract: argument checks, gate specs, per-step attributes, and the default gate
against scipy's chi-square quantile."""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.core import compiled, records
from leonav_runtime.core import filter as lf
from leonav_runtime.core.params import build_params
from tests.test_runtime_filter import P0, gps_aux, static_stream, x_rest

LAT, LON, H = math.radians(40.0), math.radians(-83.0), 200.0


@pytest.fixture(scope="module")
def lib():
    return compiled.load()


@pytest.fixture(scope="module")
def params():
    return np.array(build_params(LAT, LON, H))


def test_default_gate_is_the_999_permille_chi_square_quantile(lib, params):
    stats = pytest.importorskip("scipy.stats")
    assert lf.CHI2_1DOF_999 == pytest.approx(stats.chi2.ppf(0.999, 1), rel=1e-12)
    ekf = lf.EKF(x_rest(), P0(), params, library=lib)
    assert np.all(ekf.gate == lf.CHI2_1DOF_999) and ekf.gate.size == len(lib.meas_ids)


def test_gate_specs(lib, params):
    ekf = lf.EKF(x_rest(), P0(), params, gate=None, library=lib)
    assert np.all(ekf.gate == 0.0)
    g = ekf.gate_vector({"pseudorange": 5.0, lib.kind_id("pos_e"): 7.0})
    expected = np.zeros(len(lib.meas_ids))
    expected[lib.kind_id("pseudorange")], expected[lib.kind_id("pos_e")] = 5.0, 7.0
    np.testing.assert_array_equal(g, expected)
    assert np.all(ekf.gate_vector(3.0) == 3.0)


def test_argument_shapes_are_checked(lib, params):
    nx, ndx = lib.layout.NX, lib.layout.NDX
    with pytest.raises(ValueError, match=f"x0: expected {nx} values, got {nx - 1}"):
        lf.EKF(x_rest()[:-1], P0(), params, library=lib)
    with pytest.raises(ValueError, match=rf"P0: expected shape \({ndx}, {ndx}\)"):
        lf.EKF(x_rest(), np.eye(ndx - 1), params, library=lib)
    with pytest.raises(ValueError, match="params: expected"):
        lf.EKF(x_rest(), P0(), params[:-1], library=lib)
    ekf = lf.EKF(x_rest(), P0(), params, library=lib)
    with pytest.raises(ValueError, match="u: expected 6 values"):
        ekf.predict(np.zeros(5), 0.01)


def test_step_attributes_and_return_values(lib, params):
    ekf = lf.EKF(x_rest(), P0(), params, library=lib)
    u = lf.stationary_imu(x_rest(), 0.01, params, lib)
    assert ekf.predict(u, 0.01) == lf.STATUS_IMU
    np.testing.assert_array_equal(ekf.x_prior, ekf.x)          # after a predict: the predicted state
    np.testing.assert_array_equal(ekf.P_prior, ekf.P)
    aux = gps_aux()[0]
    h, H = ekf.h("pseudorange", aux)
    assert ekf.update("pseudorange", h + 1.0, 9.0, aux) is True   # aux is used: y is the 1 m offset
    assert ekf.y == pytest.approx(1.0, abs=1e-6) and ekf.S == pytest.approx(H @ ekf.P_prior @ H + 9.0)
    assert ekf.nis == pytest.approx(ekf.y**2 / ekf.S)
    h, _ = ekf.h("pseudorange", aux)
    assert ekf.update("pseudorange", h + 1e4, 9.0, aux) is False   # gated
    assert ekf.status == lf.STATUS_GATED and ekf.nis > lf.CHI2_1DOF_999
    np.testing.assert_array_equal(ekf.x_post, ekf.x_prior)
    # h at a given state, not the filter's
    x2 = x_rest()
    x2[0] = 12.5
    assert ekf.h("pos_e", x=x2)[0] == pytest.approx(12.5) and ekf.h("pos_e")[0] != pytest.approx(12.5)


def test_run_gate_override_and_P_rows_checks(lib, params):
    rng = np.random.default_rng(5)
    recs = static_stream(lib, params, 1.0, rng, pr_sigma=3.0)
    pr = np.flatnonzero(recs["kind"] == lib.kind_id("pseudorange"))
    recs["z"][pr[5]] += 1000.0
    ekf = lf.EKF(x_rest(), P0(), params, library=lib)
    assert ekf.run(recs, gate=None).n_gated == 0                    # per-call gate: off
    assert lf.EKF(x_rest(), P0(), params, library=lib).run(recs).n_gated == 1
    n = recs.size
    for bad in ([3, 3], [n], [-1, 2]):
        with pytest.raises(ValueError, match="increasing record indices"):
            lf.EKF(x_rest(), P0(), params, library=lib).run(recs, P_rows=bad)


def test_pcrb_checks_the_linearisation_states(lib, params):
    rng = np.random.default_rng(1)
    recs = static_stream(lib, params, 0.2, rng, fix_sigma=2.0)
    with pytest.raises(ValueError, match="x_lin: expected shape"):
        lf.pcrb(recs, np.tile(x_rest(), (recs.size + 3, 1)), P0(), params, library=lib)
    with pytest.raises(ValueError, match="B0: expected shape"):
        lf.pcrb(recs, np.tile(x_rest(), (recs.size, 1)), np.eye(5), params, library=lib)
    assert records.KIND_IMU < 0


def test_clock_and_lo_process_noise_is_the_exact_discretization(lib, params):
    """Q of the clock (bias, drift) block equals Van Loan's matrix-exponential discretization of
    d(c_dt)/dt = c_ddt + w1, d(c_ddt)/dt = w2; the LO offset's is q_blo dt; the bias integrates the drift."""
    linalg = pytest.importorskip("scipy.linalg")
    lay = lib.layout
    x = x_rest()
    x[lay.X_C_DDT] = 3.0
    ekf = lf.EKF(x, P0(), params, library=lib)
    dt = 0.5
    ekf.predict(lf.stationary_imu(x, dt, params, lib), dt)
    assert ekf.x[lay.X_C_DT] == pytest.approx(3.0 * dt) and ekf.x[lay.X_C_DDT] == 3.0
    F = np.array([[0.0, 1.0], [0.0, 0.0]])
    Qc = np.diag([params[lay.P_Q_CDT], params[lay.P_Q_CDDT]])
    M = linalg.expm(np.block([[-F, Qc], [np.zeros((2, 2)), F.T]]) * dt)
    Qd = M[2:, 2:].T @ M[:2, 2:]
    i, j = lay.DX_DC_DT, lay.DX_DC_DDT
    np.testing.assert_allclose(ekf.Q[np.ix_([i, j], [i, j])], Qd, rtol=1e-12, atol=0)
    assert ekf.Q[lay.DX_DB_LO, lay.DX_DB_LO] == pytest.approx(params[lay.P_Q_BLO] * dt, rel=1e-12)


def test_update_covariance_is_the_kalman_one(lib, params):
    """For the optimal gain the Joseph form equals P - P H^T H P / S."""
    ekf = lf.EKF(x_rest(), P0(), params, gate=None, library=lib)
    aux = gps_aux()[2]
    h, H = ekf.h("pseudorange", aux)
    ekf.update("pseudorange", h + 2.0, 4.0, aux)
    b = ekf.P_prior @ H
    S = H @ b + 4.0
    np.testing.assert_allclose(ekf.P_post, ekf.P_prior - np.outer(b, b) / S, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ekf.x_post[:3] - ekf.x_prior[:3], (b / S * 2.0)[:3], rtol=1e-9, atol=1e-12)


def test_run_checks_the_record_stream(lib, params):
    rng = np.random.default_rng(1)
    recs = static_stream(lib, params, 0.1, rng, fix_sigma=2.0)
    ekf = lf.EKF(x_rest(), P0(), params, library=lib)
    bad = recs.copy()
    bad["kind"][3] = 99
    with pytest.raises(ValueError, match="record 3: kind 99"):
        ekf.run(bad)
    bad = recs.copy()
    bad["t"][4] = np.nan
    with pytest.raises(ValueError, match="record 4: t is not finite"):
        ekf.run(bad)
    with pytest.raises(ValueError, match="dtype"):
        ekf.run(np.zeros(3))


def test_fix_observables_read_their_own_component(lib, params):
    """pos_e/n/u and vel_e/n/u measure the matching state (H a unit row) and, besides, only the
    fix latency (position: -v; its covariance is zero unless a run estimates it)."""
    lay = lib.layout
    x = x_rest()
    x[lay.X_P_ENU:lay.X_P_ENU + 3] = [1.5, -2.5, 3.5]
    x[lay.X_V_ENU:lay.X_V_ENU + 3] = [0.25, -0.75, 1.25]
    ekf = lf.EKF(x, P0(), params, library=lib)
    for i, axis in enumerate("enu"):
        for name, off, dx in (("pos", lay.X_P_ENU, lay.DX_DP), ("vel", lay.X_V_ENU, lay.DX_DV)):
            h, H = ekf.h(f"{name}_{axis}")
            assert h == pytest.approx(x[off + i])
            expected = np.zeros(lay.NDX)
            expected[dx + i] = 1.0
            if name == "pos":
                expected[lay.DX_DDT_FIX] = -x[lay.X_V_ENU + i]
            else:       # -a: the acceleration the (zero) aux specific force implies
                expected[lay.DX_DDT_FIX] = H[lay.DX_DDT_FIX]
            np.testing.assert_allclose(H, expected, atol=1e-12)
