"""GNSS position fix and velocity components in the local ENU frame (m, m/s).

A receiver's geodetic fix is converted to ENU at the edge (runtime geometry); the antenna
is taken co-located with the IMU (no lever arm).
"""
from __future__ import annotations

from models.state import X

_P, _V = X["p_enu"].offset, X["v_enu"].offset


def h_pos_e(x, aux, p):
    """East position (m)."""
    return x[_P + 0]


def h_pos_n(x, aux, p):
    """North position (m)."""
    return x[_P + 1]


def h_pos_u(x, aux, p):
    """Up position (m)."""
    return x[_P + 2]


def h_vel_e(x, aux, p):
    """East velocity (m/s)."""
    return x[_V + 0]


def h_vel_n(x, aux, p):
    """North velocity (m/s)."""
    return x[_V + 1]


def h_vel_u(x, aux, p):
    """Up velocity (m/s)."""
    return x[_V + 2]
