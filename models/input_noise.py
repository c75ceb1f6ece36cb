"""Measurement noise added by model inputs that are themselves measured.

The Doppler-rate model uses the receiver's acceleration, which the filter forms from the
latest accelerometer sample (aux `f_b`). That sample carries the accelerometer's white
noise, vrw / sqrt(dt) per axis (m/s^2) for increments over dt, and the model maps it to the
Doppler-rate through -(f_c/c) u . C_b_n delta_f (a unit line of sight), so the filter's
measurement variance is the beacon's own plus (f_c/c)^2 vrw^2 / dt. Pure Python.
"""
from __future__ import annotations

from leonav.models.constants import C_LIGHT_MPS


def doppler_rate_variance(sigma_hz_s: float, f_c_hz: float, vrw: float, imu_dt_s: float) -> float:
    """Variance (Hz^2/s^2) of a Doppler-rate measurement whose model uses a measured specific force.

    sigma_hz_s: beacon Doppler-rate noise (Hz/s); f_c_hz: carrier (Hz); vrw: accelerometer
    velocity random walk (m/s/sqrt(s)); imu_dt_s: IMU sample interval (s).
    """
    return sigma_hz_s**2 + (f_c_hz / C_LIGHT_MPS) ** 2 * vrw**2 / imu_dt_s
