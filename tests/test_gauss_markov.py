"""Gyro bias as a first-order Gauss-Markov process, selected per IMU profile by one field
(`gyro_bias_tau_s`): the filter's transition and noise, and the simulator's truth, follow it."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from leonav_runtime.core import navfuncs
from leonav_runtime.core.params import IMU_PROFILES, build_params, imu_params
from leonav_runtime.gen import state_layout as L
from leonav_runtime.simulation.sensor_errors import bias_walks

TAU_S = 120.0
GM = dataclasses.replace(IMU_PROFILES["wt901"], name="wt901-gm", gyro_bias_tau_s=TAU_S)
G = L.DX_DB_G_SLICE


def test_the_profile_field_sets_the_rate_and_the_driving_density():
    p = imu_params(GM)
    assert p["gyro_bias_beta"] == pytest.approx(1 / TAU_S)
    assert p["gyro_bias_rw"] == pytest.approx(GM.gyro_bias_sigma * math.sqrt(2 / TAU_S))
    assert imu_params(IMU_PROFILES["wt901"])["gyro_bias_beta"] == 0.0   # shipped profiles: random walk


def test_generated_transition_and_noise_are_the_gauss_markov_discretization():
    nav = navfuncs.NavFunctions(params=np.array(build_params(0.75, -1.35, 170.0, imu=GM)))
    dt = 0.5
    Phi, Qd = nav.sensor_error_step(dt)
    a = math.exp(-dt / TAU_S)
    np.testing.assert_allclose(np.diag(Phi[G, G]), a, rtol=1e-14)
    np.testing.assert_allclose(np.diag(Qd[G, G]), GM.gyro_bias_sigma**2 * (1 - a * a), rtol=1e-12)
    # the strapdown predict's F decays the bias the same way
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0
    predict = navfuncs.GeneratedFunction(nav.library.lib, "leonav_predict")
    u = np.r_[np.zeros(3), 0.0, 0.0, 9.8 * dt]
    _, _, F, Q = predict(x, np.eye(L.NDX), u, dt, nav.params)
    np.testing.assert_allclose(np.diag(F[G, G]), a, rtol=1e-14)
    np.testing.assert_allclose(np.diag(Q[G, G]), np.diag(Qd[G, G]), rtol=1e-14)


def test_the_simulated_truth_stays_at_the_steady_state_sigma():
    """Started from the prior (the steady state), the truth keeps sigma_b at every time and its
    autocorrelation over tau is exp(-1): a random walk would grow without bound."""
    nav = navfuncs.NavFunctions()
    dt, n = 0.5, 1200                        # 600 s = 5 tau
    rng = np.random.default_rng(4)
    draws = np.stack([bias_walks(rng, GM, n, dt, nav=nav)[1] for _ in range(400)])   # (400, n+1, 3)
    sd = draws.std(axis=0)
    assert np.all(np.abs(sd[[0, n // 2, n]] / GM.gyro_bias_sigma - 1) < 0.12)
    lag = int(TAU_S / dt)
    corr = np.mean(draws[:, 0] * draws[:, lag]) / np.mean(draws[:, 0] ** 2)
    assert corr == pytest.approx(math.exp(-1), abs=0.08)
    walk = np.stack([bias_walks(rng, IMU_PROFILES["wt901"], n, dt, nav=nav)[1] for _ in range(200)])
    assert walk.std(axis=0)[n].mean() > 2 * walk.std(axis=0)[0].mean()
