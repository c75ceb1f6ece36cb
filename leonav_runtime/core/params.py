"""The parameter vector `p` of the generated functions, built from named values.

Every parameter is a registry entry (`gen/registry.py` PARAMS: name, unit, default); the IMU and
clock noise figures come from the emitted profiles (`gen/profiles.py`), the carrier default
from `gen/constants.py`. A parameter a sensor module declares takes its registry default
unless the caller names it (`values`). No casadi, no `models/` import.
"""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.gen import registry as REG
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
from leonav_runtime.gen.profiles import CLOCK_PROFILES, IMU_PROFILES, TACTICAL, TCXO, ClockProfile, ImuProfile

__all__ = ["build_params", "imu_params", "ImuProfile", "ClockProfile", "IMU_PROFILES", "CLOCK_PROFILES",
           "DEFAULT_Q_BLO_HZ2_S"]

DEFAULT_Q_BLO_HZ2_S = 1e-2
"""Hz^2/s: default random-walk PSD of the beacon front-end frequency offset b_lo."""


def imu_params(imu: ImuProfile) -> dict[str, float]:
    """The IMU profile's parameters: white noise, bias driving densities and the gyro bias's
    Gauss-Markov rate (0 for a random walk; with a correlation time tau the density is
    gyro_bias_sigma sqrt(2 / tau), so the process's steady-state sigma is the profile's)."""
    tau = imu.gyro_bias_tau_s
    gauss_markov = math.isfinite(tau)
    return {"vrw": imu.vrw, "arw": imu.arw, "acc_bias_rw": imu.acc_bias_rw,
            "gyro_bias_rw": imu.gyro_bias_sigma * math.sqrt(2.0 / tau) if gauss_markov else imu.gyro_bias_rw,
            "gyro_bias_beta": 1.0 / tau if gauss_markov else 0.0}


def build_params(
    lat0_rad: float,
    lon0_rad: float,
    h0_m: float,
    imu: ImuProfile = TACTICAL,
    clock: ClockProfile = TCXO,
    q_blo: float = DEFAULT_Q_BLO_HZ2_S,
    f_c_hz: float = STARLINK_BEACON_HZ,
    lever_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    values: dict[str, float] | None = None,
) -> list[float]:
    """Parameter vector (NP,): ENU origin (WGS84 rad, rad, m), IMU and clock noise (SI),
    LO random-walk PSD (Hz^2/s), beacon carrier (Hz), the GNSS antenna lever arm (m, body FLU,
    from the IMU to the antenna), and `values` by parameter name (a sensor's own: e.g. a
    magnetometer's declination); any other parameter takes its registry default."""
    named = {
        "lat0_rad": lat0_rad, "lon0_rad": lon0_rad, "h0_m": h0_m, **imu_params(imu),
        "q_cdt": clock.q_cdt, "q_cddt": clock.q_cddt, "q_blo": q_blo, "f_c_hz": f_c_hz,
        "lever_x_m": lever_b_m[0], "lever_y_m": lever_b_m[1], "lever_z_m": lever_b_m[2],
    }
    known = {q.name: q for q in REG.PARAMS}
    for name, value in (values or {}).items():
        if name not in known:
            raise ValueError(f"parameter {name!r}: not in the generated layout (expected one of {', '.join(known)})")
        named[name] = value
    p = [0.0] * L.NP
    for q in REG.PARAMS:
        value = named.get(q.name, q.default)
        if value is None:
            raise ValueError(f"parameter {q.name!r} ({q.unit}): no value and no registry default")
        p[q.offset] = float(value)
    return p


def params_array(*args, **kwargs) -> np.ndarray:
    """`build_params` as a float64 array."""
    return np.asarray(build_params(*args, **kwargs), dtype=np.float64)
