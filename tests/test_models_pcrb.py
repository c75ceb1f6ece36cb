"""PCRB recursion from the generated pieces equals the Kalman covariance on a linearized model.

On the true trajectory, with F, Qd from leonav_predict and H from the observables, the
information recursion J+ = (F J^-1 F^T + Qd)^-1 + sum H^T H / R (leonav_pcrb_info_<k>)
must equal the inverse of the covariance of a Kalman filter whose Jacobians are taken on
the same trajectory (leonav_predict's P_next + leonav_update_<k>'s Joseph P_post).
"""
from __future__ import annotations

import math

import numpy as np

from codegen.functions import build_functions
from leonav_runtime.gen.profiles import WT901
from leonav_runtime.params import build_params
from models.state import NDX

FNS = {f.name(): f for f in build_functions()}


def test_information_recursion_equals_kalman_covariance():
    p = np.array(build_params(math.radians(43.08), math.radians(-77.68), 170.0, imu=WT901))
    rng = np.random.default_rng(3)
    x = np.zeros(19)
    x[6:10] = np.array(FNS["leonav_q_from_euler"](np.array([0.02, -0.01, 0.7]))).ravel()
    x[16:19] = [10.0, 1.0, 100.0]
    site = np.array(FNS["leonav_receiver_ecef"](x, p)[0]).ravel()
    sats = [site + 6e5 * (site / np.linalg.norm(site) + 0.6 * rng.normal(size=3)) for _ in range(4)]
    P = np.diag(np.r_[np.full(3, 25.0), np.full(3, 1.0), np.full(3, 1e-3), np.full(3, 1e-2), np.full(3, 1e-4),
                      1e6, 100.0, 1e4])
    J = np.linalg.inv(P)
    dt = 0.1
    for k in range(200):
        u = np.r_[rng.normal(size=3) * 1e-3, rng.normal(size=3) * 0.05 + [0, 0, 9.80 * dt]]
        x_next, P, F, Qd = (np.array(v) for v in FNS["leonav_predict"](x, P, u, dt, p))
        J = np.linalg.inv(F @ np.linalg.inv(J) @ F.T + Qd)
        x = x_next.ravel()
        if k % 10 == 9:  # GNSS fix + Doppler-rate + OFDM at 1 Hz
            for i, sat in enumerate(sats):
                aux = np.r_[sat, rng.normal(size=3) * 7e3, rng.normal(size=3) * 8, sats[0], np.zeros(6),
                            [0.0, 0.0, 9.8]]
                for suffix, R in (("doppler_rate", 0.5**2), ("ofdm_range_diff", 3.0**2) if i else ("pos_e", 4.0)):
                    P = np.array(FNS[f"leonav_update_{suffix}"](x, P, 0.0, R, aux, p)[1])
                    J = np.array(FNS[f"leonav_pcrb_info_{suffix}"](J, x, aux, p, R))
    B = np.linalg.inv(J)
    np.testing.assert_allclose(B, (B + B.T) / 2, atol=1e-9 * np.abs(B).max())
    np.testing.assert_allclose(np.diag(B), np.diag(P), rtol=1e-6)
    np.testing.assert_allclose(B, P, rtol=1e-5, atol=1e-8 * np.sqrt(np.outer(np.diag(P), np.diag(P))).max())
    # the aiding did its job: position information dominates the prior
    assert np.all(np.diag(P)[0:3] < 25.0)
    assert P.shape == (NDX, NDX)
