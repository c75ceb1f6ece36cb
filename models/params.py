"""Build the parameter vector `p` (layout in models.state.P_BLOCKS). Pure Python."""
from __future__ import annotations

from models.clock import TCXO, ClockProfile
from models.imu import TACTICAL, ImuProfile
from models.state import NP, P

STARLINK_BEACON_HZ = 11.325e9  # Starlink Ku-band beacon carrier used in the paper, Hz


def build_params(
    lat0_rad: float,
    lon0_rad: float,
    h0_m: float,
    imu: ImuProfile = TACTICAL,
    clock: ClockProfile = TCXO,
    q_blo: float = 1e-2,
    f_c_hz: float = STARLINK_BEACON_HZ,
) -> list[float]:
    """Parameter vector: ENU origin (WGS84 rad, rad, m), IMU and clock noise, LO PSD (Hz^2/s), carrier (Hz)."""
    values = {
        "lat0_rad": lat0_rad, "lon0_rad": lon0_rad, "h0_m": h0_m,
        "vrw": imu.vrw, "arw": imu.arw, "acc_bias_rw": imu.acc_bias_rw, "gyro_bias_rw": imu.gyro_bias_rw,
        "q_cdt": clock.q_cdt, "q_cddt": clock.q_cddt, "q_blo": q_blo, "f_c_hz": f_c_hz,
    }
    p = [0.0] * NP
    for name, value in values.items():
        p[P[name].offset] = float(value)
    return p
