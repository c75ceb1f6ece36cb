"""The parameter vector `p` of the generated functions, built from named values.

Layout (offsets, units) is `gen/state_layout.py` `P_*`; the IMU and clock noise figures
come from the emitted profiles (`gen/profiles.py`), the carrier default from
`gen/constants.py`. No casadi, no `models/` import.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.gen import state_layout as L
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
from leonav_runtime.gen.profiles import CLOCK_PROFILES, IMU_PROFILES, TACTICAL, TCXO, ClockProfile, ImuProfile

__all__ = ["build_params", "ImuProfile", "ClockProfile", "IMU_PROFILES", "CLOCK_PROFILES", "DEFAULT_Q_BLO_HZ2_S"]

DEFAULT_Q_BLO_HZ2_S = 1e-2
"""Hz^2/s: default random-walk PSD of the beacon front-end frequency offset b_lo."""


def build_params(
    lat0_rad: float,
    lon0_rad: float,
    h0_m: float,
    imu: ImuProfile = TACTICAL,
    clock: ClockProfile = TCXO,
    q_blo: float = DEFAULT_Q_BLO_HZ2_S,
    f_c_hz: float = STARLINK_BEACON_HZ,
    lever_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> list[float]:
    """Parameter vector (NP,): ENU origin (WGS84 rad, rad, m), IMU and clock noise (SI),
    LO random-walk PSD (Hz^2/s), beacon carrier (Hz) and the GNSS antenna lever arm
    (m, body FLU, from the IMU to the antenna)."""
    values = {
        "lat0_rad": lat0_rad, "lon0_rad": lon0_rad, "h0_m": h0_m,
        "vrw": imu.vrw, "arw": imu.arw, "acc_bias_rw": imu.acc_bias_rw, "gyro_bias_rw": imu.gyro_bias_rw,
        "q_cdt": clock.q_cdt, "q_cddt": clock.q_cddt, "q_blo": q_blo, "f_c_hz": f_c_hz,
        "lever_x_m": lever_b_m[0], "lever_y_m": lever_b_m[1], "lever_z_m": lever_b_m[2],
    }
    if set(values) != set(L.P_NAMES):
        raise RuntimeError(f"parameter names {sorted(values)} differ from the generated layout {L.P_NAMES}")
    p = [0.0] * L.NP
    for name, value in values.items():
        p[L.P_NAMES.index(name)] = float(value)
    return p


def params_array(*args, **kwargs) -> np.ndarray:
    """`build_params` as a float64 array."""
    return np.asarray(build_params(*args, **kwargs), dtype=np.float64)
