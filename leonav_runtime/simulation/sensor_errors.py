"""Random sensor errors of the simulated trials: IMU bias random walks and measured increments.

Draw order is part of the contract (common random numbers across modes, counts and
executors): change it only together with the golden run.
"""
from __future__ import annotations

import math

import numpy as np


def _random_walk(rng, n, dt, x0, q):
    steps = rng.standard_normal((n,) + np.shape(x0)) * math.sqrt(q * dt)
    return np.concatenate([[x0], x0 + np.cumsum(steps, axis=0)])


def bias_walks(rng: np.random.Generator, profile, n: int, dt: float, scale: float = 1.0):
    """True accelerometer and gyro biases (n+1, 3) each at the IMU samples: an initial draw
    from the profile's bias sigma, then its random walk (m/s^2, rad/s; body frame).
    scale 0 gives zero biases (the draws are still made, to keep random streams aligned)."""
    b_a = _random_walk(rng, n, dt, scale * profile.acc_bias_sigma * rng.standard_normal(3),
                       scale * profile.acc_bias_rw**2)
    b_g = _random_walk(rng, n, dt, scale * profile.gyro_bias_sigma * rng.standard_normal(3),
                       scale * profile.gyro_bias_rw**2)
    return b_a, b_g


def measured_increments(rng: np.random.Generator, profile, u_true: np.ndarray, b_a: np.ndarray,
                        b_g: np.ndarray, dt: float, scale: float = 1.0) -> np.ndarray:
    """IMU increments as the sensor gives them: the ideal ones plus the bias at the start of
    each interval and the white noise of the profile (ARW, VRW). (n, 6): rad, m/s."""
    n = u_true.shape[0]
    u = u_true.copy()
    u[:, :3] += b_g[:-1] * dt + scale * profile.arw * math.sqrt(dt) * rng.standard_normal((n, 3))
    u[:, 3:] += b_a[:-1] * dt + scale * profile.vrw * math.sqrt(dt) * rng.standard_normal((n, 3))
    return u
