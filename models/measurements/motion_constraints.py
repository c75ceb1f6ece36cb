"""Motion constraints of a ground vehicle as pseudo-measurements (z = 0, m/s).

- Non-holonomic constraint (NHC): a wheeled vehicle does not slide sideways nor leave the
  ground, so the body-frame velocity v_b = C_b_n^T v_enu has zero lateral (y, left) and
  vertical (z, up) components. Body FLU is the vehicle frame here (the importer rotates
  the IMU axes onto it); the IMU's offset from the axle and wheel slip in turns are left
  to the record's R.
- Zero-velocity update (ZUPT): at a detected standstill the ENU velocity is zero.
Both use the Earth-relative velocity of the state (v_enu), so they hold on a rotating Earth.
"""
from __future__ import annotations

from leonav.models import frames
from leonav.models.state import X


def velocity_body(x):
    """Earth-relative velocity in body FLU axes (m/s): C_b_n^T v_enu."""
    return frames.rot_from_quat(x[X["q_nb"].slice]).T @ x[X["v_enu"].slice]


def h_nhc_y(x, aux, p):
    """Lateral (body left) velocity (m/s); NHC: z = 0."""
    return velocity_body(x)[1]


def h_nhc_z(x, aux, p):
    """Vertical (body up) velocity (m/s); NHC: z = 0."""
    return velocity_body(x)[2]


def h_zupt_e(x, aux, p):
    """East velocity (m/s); ZUPT: z = 0."""
    return x[X["v_enu"].offset + 0]


def h_zupt_n(x, aux, p):
    """North velocity (m/s); ZUPT: z = 0."""
    return x[X["v_enu"].offset + 1]


def h_zupt_u(x, aux, p):
    """Up velocity (m/s); ZUPT: z = 0."""
    return x[X["v_enu"].offset + 2]
