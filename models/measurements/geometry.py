"""Receiver ECEF state from the navigation state, and line-of-sight range kinematics."""
from __future__ import annotations

import casadi as ca

from models import kinematics
from models.state import X


def receiver_ecef(x, p):
    """(r_U, v_U) receiver position (m) and Earth-relative velocity (m/s), ECEF axes."""
    _, _, _, r0, C = kinematics.origin(p)
    return r0 + C @ x[X["p_enu"].slice], C @ x[X["v_enu"].slice]


def range_rate_accel(r_S, v_S, a_S, r_U, v_U, a_U):
    """(rho, rho_dot, rho_ddot) of the range |r_S - r_U| (m, m/s, m/s^2), all inputs ECEF.

    rho_ddot = u.(a_S - a_U) + (|v_rel|^2 - (u.v_rel)^2)/rho, u = (r_S - r_U)/rho (paper eq. 3,
    with the receiver acceleration kept).
    """
    r = r_S - r_U
    rho = ca.norm_2(r)
    u = r / rho
    v_rel = v_S - v_U
    rho_dot = ca.dot(u, v_rel)
    rho_ddot = ca.dot(u, a_S - a_U) + (ca.dot(v_rel, v_rel) - rho_dot**2) / rho
    return rho, rho_dot, rho_ddot
