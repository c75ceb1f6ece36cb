"""PCRB recursion from the generated pieces equals the Kalman covariance on a linearized model.

On the true trajectory, with F, Qd from leonav_predict and H from the observables, the
information recursion J+ = (F J^-1 F^T + Qd)^-1 + sum H^T H / R (leonav_pcrb_info_<k>)
must equal the inverse of the covariance of a Kalman filter whose Jacobians are taken on
the same trajectory (leonav_predict's P_next + leonav_update_<k>'s Joseph P_post), and the
covariance-form recursion the C driver runs (leonav_predict on B, then the generated
Sherman-Morrison step leonav_pcrb_update with leonav_h_<k>'s H) must equal both.
"""
from __future__ import annotations

import math

import numpy as np

from tests import symbolic
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gen.profiles import WT901
from leonav_runtime.core.params import build_params
from leonav.models.state import NDX
from tests.registry_reference import prior_sd

FNS = symbolic.FNS  # built on first use, once per process


def test_information_recursion_equals_kalman_covariance():
    p = np.array(build_params(math.radians(43.08), math.radians(-77.68), 170.0, imu=WT901))
    rng = np.random.default_rng(3)
    x = np.zeros(L.NX)
    x[L.X_Q_NB_SLICE] = np.array(FNS["leonav_q_from_euler"](np.array([0.02, -0.01, 0.7]))).ravel()
    x[[L.X_C_DT, L.X_C_DDT, L.X_B_LO]] = [10.0, 1.0, 100.0]
    site = np.array(FNS["leonav_receiver_ecef"](x, p)[0]).ravel()
    sats = [site + 6e5 * (site / np.linalg.norm(site) + 0.6 * rng.normal(size=3)) for _ in range(4)]
    P = np.diag(prior_sd({"dp": 5.0, "dv": 1.0, "dtheta": 1e-3**0.5, "db_a": 0.1, "db_g": 1e-2, "dc_dt": 1e3,
                          "dc_ddt": 10.0, "db_lo": 100.0, "disb": 100.0}) ** 2)
    J = np.linalg.inv(P)
    B = P.copy()
    dt = 0.1
    for k in range(200):
        u = np.zeros(L.NU)
        u[L.U_DTHETA_B_SLICE] = rng.normal(size=3) * 1e-3
        u[L.U_DVEL_B_SLICE] = rng.normal(size=3) * 0.05 + [0, 0, 9.80 * dt]
        x_next, P, F, Qd = (np.array(v) for v in FNS["leonav_predict"](x, P, u, dt, p))
        J = np.linalg.inv(F @ np.linalg.inv(J) @ F.T + Qd)
        B = np.array(FNS["leonav_predict"](x, B, u, dt, p)[1])
        x = x_next.ravel()
        if k % 10 == 9:  # GNSS fix + Doppler-rate + OFDM at 1 Hz
            for i, sat in enumerate(sats):
                aux = np.zeros(L.NAUX)
                aux[L.AUX_R_S_ECEF_SLICE], aux[L.AUX_R_REF_ECEF_SLICE] = sat, sats[0]
                aux[L.AUX_V_S_ECEF_SLICE] = rng.normal(size=3) * 7e3
                aux[L.AUX_A_S_ECEF_SLICE] = rng.normal(size=3) * 8
                aux[L.AUX_F_B_SLICE] = [0.0, 0.0, 9.8]
                for suffix, R in (("doppler_rate", 0.5**2), ("ofdm_range_diff", 3.0**2) if i else ("pos_e", 4.0)):
                    P = np.array(FNS[f"leonav_update_{suffix}"](x, P, 0.0, R, aux, p)[1])
                    J = np.array(FNS[f"leonav_pcrb_info_{suffix}"](J, x, aux, p, R))
                    B_prior = B
                    H = FNS[f"leonav_h_{suffix}"](x, aux, p)[1]
                    B, S = (np.array(v) for v in FNS["leonav_pcrb_update"](B, H, R))
                    # one step from the same prior: Sherman-Morrison == Joseph with the optimal gain
                    P_joseph, _, S_joseph = (np.array(v) for v in FNS[f"leonav_update_{suffix}"](
                        x, B_prior, 0.0, R, aux, p)[1:4])
                    np.testing.assert_allclose(B, P_joseph, rtol=1e-9, atol=1e-12 * np.abs(B_prior).max())
                    assert abs(S.item() / S_joseph.item() - 1) < 1e-12
    np.testing.assert_array_equal(B, B.T)  # the step keeps B exactly symmetric (b_i b_j = b_j b_i)
    np.testing.assert_allclose(B, P, rtol=1e-6, atol=1e-8 * np.sqrt(np.outer(np.diag(P), np.diag(P))).max())
    B = np.linalg.inv(J)
    np.testing.assert_allclose(B, (B + B.T) / 2, atol=1e-9 * np.abs(B).max())
    np.testing.assert_allclose(np.diag(B), np.diag(P), rtol=1e-6)
    np.testing.assert_allclose(B, P, rtol=1e-5, atol=1e-8 * np.sqrt(np.outer(np.diag(P), np.diag(P))).max())
    # the aiding did its job: position information dominates the prior
    assert np.all(np.diag(P)[L.DX_DP_SLICE] < 25.0)
    assert P.shape == (NDX, NDX)
