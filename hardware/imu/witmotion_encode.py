"""WitMotion output packets from physical values (the inverse of `witmotion.decode_packet`).

For simulators and tests: specific force, angular rate and Euler angles are scaled to
the protocol's int16 words (acc +/-16 g, rate +/-2000 deg/s, angles +/-180 deg over
32768 counts), rounded to the nearest count and saturated at the int16 limits, as the
sensor's own firmware does. One count is 16*9.80665/32768 = 4.79e-3 m/s^2,
2000/32768 = 0.061 deg/s (1.07e-3 rad/s) and 180/32768 = 0.0055 deg.
"""
from __future__ import annotations

import math
from typing import Sequence

from leonav.hardware.imu.witmotion import ACC, ANGLE, G_MPS2, GYRO, build_packet

ACC_LSB_MPS2 = 16.0 * G_MPS2 / 32768.0
GYRO_LSB_RADPS = 2000.0 / 32768.0 * math.pi / 180.0
ANGLE_LSB_RAD = 180.0 / 32768.0 * math.pi / 180.0


def _word(value: float) -> int:
    """Nearest int16, saturated (what the sensor outputs beyond its range)."""
    return int(min(32767, max(-32768, round(value))))


def acc_packet(f_b_mps2: Sequence[float], temperature_c: float = 25.0) -> bytes:
    """0x51: specific force (m/s^2, body FLU) and temperature (deg C)."""
    return build_packet(ACC, tuple(_word(v / ACC_LSB_MPS2) for v in f_b_mps2) + (_word(temperature_c * 100),))


def gyro_packet(w_b_radps: Sequence[float], voltage_v: float = 3.3) -> bytes:
    """0x52: angular rate (rad/s, body FLU) and supply voltage (V)."""
    return build_packet(GYRO, tuple(_word(v / GYRO_LSB_RADPS) for v in w_b_radps) + (_word(voltage_v * 100),))


def angle_packet(rpy_rad: Sequence[float], version: int = 0x3012) -> bytes:
    """0x53: roll, pitch, yaw (rad, Z-Y-X), each wrapped to [-pi, pi), and a firmware version word."""
    words = []
    for a in rpy_rad:
        wrapped = (a + math.pi) % (2 * math.pi) - math.pi
        words.append(_word(wrapped / ANGLE_LSB_RAD))
    v = version & 0xFFFF
    return build_packet(ANGLE, tuple(words) + (v - 0x10000 if v >= 0x8000 else v,))
